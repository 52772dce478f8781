"""
The time integrators compared
=============================

Every elastic simulation in blobflow is a system of particles (an
:class:`filters.linalg.ImplicitSystem`, here a :class:`filters.elastic.springs.SpringSystem`)
advanced by one of the schemes of :mod:`filters.integrators`.  Here the four schemes advance the
same chain of eight masses and springs, pinned at one end and released horizontally under
gravity, with the same step, and without any damping: the exact motion keeps its total energy.

* ``euler`` (forward) gains energy every step and blows up;
* ``symplectic_euler`` keeps the energy within a bounded error, while ``h`` is below its
  stability limit;
* ``linearized_backward_euler`` (Baraff & Witkin 1998) and ``backward_euler`` (Newton on the
  incremental potential, Gast et al. 2015) never gain energy: stable at any step, they damp the
  motion instead (numerical dissipation), which is why the scenes use them.
"""

# %%
import os
from pathlib import Path

import numpy as np
import pyvista as pv

from filters import State
from filters.elastic.springs import SpringSystem
from filters.integrators import integrate

pv.OFF_SCREEN = True  # draw without a display

SMALL = os.environ.get("BLOBFLOW_EXAMPLE_SMALL") == "1"  # the tests run every example small
OUT = Path(os.environ.get("BLOBFLOW_EXAMPLES_OUT", "outputs/examples")) / "integrators_compared"

# %%
# The chain
# ---------
# Eight 10 g masses 5 cm apart along x, joined by springs of seed-form stiffness 20 N
# (``f = -k (l / L - 1)``), the first one pinned.  Gravitational energy is zero at the pin's
# height, so the chain starts with a total energy of 0 J.

n = 8
rest = 0.05  # m
positions = np.column_stack([np.arange(n) * rest, np.zeros(n), np.zeros(n)])
springs = np.column_stack([np.arange(n - 1), np.arange(1, n)])
pinned = np.zeros(n, dtype=bool)
pinned[0] = True
chain = SpringSystem(springs, rest, 20.0, np.full(n, 0.01), pinned=pinned)

# %%
# One run per scheme
# ------------------
# 240 steps per second; forward Euler's run stops once it has gained 0.1 J.

h = 1.0 / 240.0
duration = 1.0 if SMALL else 3.0
schemes = ("euler", "symplectic_euler", "linearized_backward_euler", "backward_euler")
energies = {}
for scheme in schemes:
    state = State(positions)  # positions (m), velocities zero, time 0
    energy = [chain.energy(state.positions, state.velocities)]
    for _ in range(round(duration / h)):
        integrate(chain, state, h, scheme)
        energy.append(chain.energy(state.positions, state.velocities))
        if not energy[-1] < 0.1:  # blown up (or NaN)
            break
    energies[scheme] = np.array(energy)
    print(f"{scheme:>26}: {len(energy) - 1} steps, energy at the end {energy[-1]:+.4f} J")

# %%
# The picture
# -----------
# Total energy (J) over time, one line per scheme.

chart = pv.Chart2D(x_label="time (s)", y_label="total energy (J)")
colors = ("tab:red", "tab:blue", "tab:orange", "tab:green")
for scheme, color in zip(schemes, colors, strict=True):
    times = np.arange(len(energies[scheme])) * h
    chart.line(times, energies[scheme], color=color, width=3.0, label=scheme)
chart.x_range = [0.0, duration]
chart.y_range = [-0.15, 0.1]
chart.legend_visible = True
plotter = pv.Plotter(window_size=(800, 500))
plotter.add_chart(chart)
OUT.mkdir(parents=True, exist_ok=True)
plotter.show(screenshot=OUT / "integrators_compared.png")
