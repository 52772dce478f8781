"""
Cloth from your own mesh
========================

:class:`filters.elastic.mass_spring.ClothSimulation` makes a cloth of any triangle mesh: a
stretch spring along every edge and a bending spring across every interior edge
(:func:`filters.elastic.topology.cloth_from_mesh`), each vertex carrying a third of its
triangles' mass.  Its contacts with colliders (planes, spheres, boxes) are solved inside the
step of every scheme, with friction (the barrier of Li et al. 2020, IPC).  The same goes for hair
(``HairSimulation`` from root points and directions) and jello
(``JelloSimulation`` from a closed mesh).

Here a round cloth, triangulated from points on rings (an irregular mesh, as one made in a
modeller would be), falls onto two balls.  The run is written as a time series with the
colliders, and blobflow's renderer draws the last frame.
"""

# %%
import os
from pathlib import Path

import numpy as np
import pyvista as pv

from filters.elastic.contact import Colliders
from filters.elastic.mass_spring import ClothSimulation
from filters.geometry import Plane, Sphere
from pipeline import Flow, SimulationSource
from pipeline.render import render_still

pv.OFF_SCREEN = True  # draw without a display

SMALL = os.environ.get("BLOBFLOW_EXAMPLE_SMALL") == "1"  # the tests run every example small
OUT = Path(os.environ.get("BLOBFLOW_EXAMPLES_OUT", "outputs/examples")) / "cloth_from_your_mesh"

# %%
# The mesh
# --------
# Points on rings 4 cm apart, a disc of radius 0.6 m triangulated by Delaunay: any mesh of
# points ``(N, 3)`` and triangles ``(T, 3)`` will do (``pv.read("cloth.obj")`` for a file).

spacing = 0.08 if SMALL else 0.04  # m
rings = np.arange(spacing, 0.6 + 1e-9, spacing)
angles = [np.linspace(0, 2 * np.pi, max(6, int(2 * np.pi * r / spacing)), endpoint=False)
          for r in rings]
xy = np.concatenate([[[0.0, 0.0]]] + [np.column_stack([r * np.cos(a + r), r * np.sin(a + r)])
                                        for r, a in zip(rings, angles, strict=True)])
disc = pv.PolyData(np.column_stack([xy, np.full(len(xy), 0.7)])).delaunay_2d()
points = np.asarray(disc.points)
triangles = disc.regular_faces  # (T, 3) vertex indices
print(f"cloth: {len(points)} vertices, {len(triangles)} triangles")

# %%
# The simulation
# --------------
# Two balls of radius 25 cm on the floor, friction 0.5, 5 mm of contact thickness.

floor = Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
balls = [Sphere((-0.27, 0.0, 0.25), 0.25), Sphere((0.27, 0.0, 0.25), 0.25)]
colliders = Colliders(friction=0.5, thickness=0.005).add(floor).add(balls[0]).add(balls[1])
cloth = ClothSimulation(points, triangles, areal_density=0.2, stretch_stiffness=200.0,
                        bend_stiffness=0.5, damping=0.02, colliders=colliders,
                        max_dt=1.0 / 60.0, newton_tol=1e-2)

# %%
# Run it through the pipeline
# ---------------------------
# ``xdmf=True`` also writes the fixed-topology series as XDMF + HDF5;
# :meth:`~pipeline.Flow.add_collider` declares what the renderer draws beside the cloth.

flow = Flow(SimulationSource(cloth, fps=30, duration=0.6 if SMALL else 1.5), name="cloth",
            xdmf=True)
flow.add_collider("floor", floor, role="floor", size=3.0)
flow.add_collider("left", balls[0])
flow.add_collider("right", balls[1])
paths = flow.run(OUT, progress=False)
energy = cloth.energies()
print(f"wrote {sorted(p.name for p in OUT.iterdir())}")
print(f"energy at t = {cloth.state.time} s: kinetic {energy.kinetic:.4f} J, "
      f"elastic {energy.elastic:.4f} J")

# %%
# The picture
# -----------
# :func:`pipeline.render.render_still` draws a series with its colliders as ``blobflow render``
# does (shadows, the balls in grey, the floor).

render_still(paths["cloth"], OUT / "cloth_from_your_mesh.png", time=float(flow.times[-1]),
             size=(800, 600))
