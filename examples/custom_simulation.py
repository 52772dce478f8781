"""
Your own simulation as a VTK source
===================================

Any simulation that follows the protocol of :mod:`filters.simulation` becomes a temporal VTK
source with :class:`pipeline.SimulationSource`, and a :class:`pipeline.Flow` writes it as a
time series that ParaView opens as one animated dataset.  The protocol asks for three things:

* a **model**: what is fixed after construction (here the Lorenz parameters);
* a **state** (:class:`filters.State`): positions, velocities, time and any extra arrays, which
  the pipeline copies, restores and checkpoints into every frame;
* ``_step(dt)``: advance the state's arrays by ``dt`` seconds, in place.

Here, particles follow the Lorenz (1963) system, started in a 1 mm cube: chaos spreads them over
the whole attractor within a few seconds.
"""

# %%
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyvista as pv

from filters import Frame, OutputSpec, Simulation, State
from pipeline import Flow, SimulationSource, read_series

pv.OFF_SCREEN = True  # draw without a display

SMALL = os.environ.get("BLOBFLOW_EXAMPLE_SMALL") == "1"  # the tests run every example small
OUT = Path(os.environ.get("BLOBFLOW_EXAMPLES_OUT", "outputs/examples")) / "custom_simulation"

# %%
# The model and the simulation
# ----------------------------
# The model is a frozen dataclass.  ``_step`` works on whole arrays (NumPy here; a Numba kernel
# for anything heavier): never a Python loop over particles.


@dataclass(frozen=True)
class LorenzModel:
    """Lorenz's parameters, his time scaled by ``speed``, lengths by ``scale`` (m)."""

    sigma: float = 10.0
    rho: float = 28.0
    beta: float = 8.0 / 3.0
    speed: float = 1.0
    scale: float = 0.01


class LorenzParticles(Simulation):
    """Particles moving with the Lorenz flow, integrated with the classical RK4 scheme."""

    max_dt = 1.0 / 600.0  # the largest step advance_to takes (s)

    def __init__(self, positions, model=LorenzModel()):
        self.model = model
        self.state = State(positions)
        self.state.velocities[:] = self.velocity(self.state.positions)

    def velocity(self, x):
        """dx/dt (m/s) at positions ``x`` (N, 3) (m)."""
        m = self.model
        u = x / m.scale
        du = np.column_stack([m.sigma * (u[:, 1] - u[:, 0]),
                              u[:, 0] * (m.rho - u[:, 2]) - u[:, 1],
                              u[:, 0] * u[:, 1] - m.beta * u[:, 2]])
        return du * (m.speed * m.scale)

    def _step(self, dt):
        x = self.state.positions
        k1 = self.velocity(x)
        k2 = self.velocity(x + 0.5 * dt * k1)
        k3 = self.velocity(x + 0.5 * dt * k2)
        k4 = self.velocity(x + dt * k3)
        x += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        self.state.velocities[:] = self.velocity(x)

    # What a frame carries: the default is velocity and id; add the speed.
    @property
    def output_spec(self):
        return OutputSpec(point_arrays=(("velocity", 3), ("id", 1), ("speed", 1)))

    def frame(self):
        s = self.state
        return Frame(time=s.time, points=s.positions.copy(),
                     point_data={"velocity": s.velocities.copy(),
                                 "id": np.arange(s.n_points, dtype=np.int64),
                                 "speed": np.linalg.norm(s.velocities, axis=1)})


# %%
# Run it through the pipeline
# ---------------------------
# 300 particles in a 1 mm cube near ``(0.01, 0.01, 0.2)`` m; 8 s at 30 frames per second.

rng = np.random.default_rng(1963)
n = 60 if SMALL else 300
start = np.array([0.01, 0.01, 0.2]) + rng.uniform(-5e-4, 5e-4, (n, 3))
simulation = LorenzParticles(start)
flow = Flow(SimulationSource(simulation, fps=30, duration=1.0 if SMALL else 8.0),
            name="particles")
paths = flow.run(OUT, progress=False)  # particles.pvd (+ particles.vtp.series) and frames
times, frames = read_series(paths["particles"])
print(f"{len(times)} frames of {n} particles in {paths['particles']}")

# %%
# The picture
# -----------
# Frames keep their particles in one order (by ``id``), so a particle's track is its row in
# every frame: the tracks of a few particles as tubes, the particles at the last frame as
# spheres coloured by speed.

tracks = np.stack([np.asarray(f.points) for f in frames], axis=1)  # (particles, frames, 3)
lines = pv.MultipleLines(tracks[0])
for track in tracks[1:4]:
    lines = lines.merge(pv.MultipleLines(track))
plotter = pv.Plotter(window_size=(800, 600))
plotter.add_mesh(lines.tube(radius=0.001), color="#8a9bb5", smooth_shading=True)
plotter.add_mesh(frames[-1], scalars="speed", cmap="plasma", render_points_as_spheres=True,
                 point_size=9, scalar_bar_args={"title": "speed (m/s)"})
plotter.view_xz()
plotter.camera.elevation = 15
plotter.camera.zoom(1.2)
OUT.mkdir(parents=True, exist_ok=True)
plotter.show(screenshot=OUT / "custom_simulation.png")
