"""
Bodies in the water
===================

:class:`filters.coupling.Coupled` joins a DFSPH liquid (:class:`filters.sph.SPHLiquid`) and
rigid bodies (:class:`filters.rigid.RigidBodies`) into one simulation.  The bodies are part of
the liquid's boundary, sampled in layers like the tank's walls
(:func:`filters.coupling.coupled_boundary`); the liquid's pressure and viscosity push them, the
rigid ones inside its density solve, and they push back.  Buoyancy is not a force of its own: a
body lighter than water floats at its Archimedes draft, a heavier one sinks.

Here a wooden ball (600 kg/m^3) and a brick (2,000 kg/m^3) drop into a pool.  The run is written
as series that ParaView opens: the water's particles (the bodies' positions and orientations
in their field data) and the bodies' meshes (:class:`pipeline.bodies.BodyMeshes`).
"""

# %%
import os
from pathlib import Path

import numpy as np
import pyvista as pv

from filters.coupling import Coupled, coupled_boundary
from filters.elastic.contact import Colliders
from filters.elastic.topology import icosphere
from filters.geometry import Box
from filters.rigid import RigidBodies, RigidBody
from filters.rigid.meshes import box_mesh
from filters.sph import SPHLiquid
from filters.sph.boundary import box_boundary
from filters.sph.settle import hydrostatic_pressure
from pipeline import Flow, SimulationSource, read_series
from pipeline.bodies import BodyMeshes

pv.OFF_SCREEN = True  # draw without a display

SMALL = os.environ.get("BLOBFLOW_EXAMPLE_SMALL") == "1"  # the tests run every example small
OUT = Path(os.environ.get("BLOBFLOW_EXAMPLES_OUT", "outputs/examples")) / "bodies_in_water"

# %%
# The bodies
# ----------
# Any closed triangle mesh and a density: mass, centre of mass and inertia come from the mesh.
# Both start 2 cm above the water of a closed tank 30 x 20 x 25 cm, whose walls are their
# colliders (a body resting on the floor is held by contact, not by the liquid).

spacing = 0.02 if SMALL else 0.01  # m, the liquid's particle spacing
tank, depth = (0.3, 0.2, 0.25), 0.1
ball = RigidBody(*icosphere(0.04, 2, center=(0.09, 0.1, depth + 0.06)), density=600.0)
brick = RigidBody(*box_mesh((0.08, 0.06, 0.04), (0.21, 0.1, depth + 0.04)), density=2000.0)
bodies = RigidBodies([ball, brick], colliders=Colliders(friction=0.3).add(~Box((0, 0, 0), tank)))

# %%
# The liquid and the coupled simulation
# -------------------------------------
# The pool on a lattice of the spacing, with its hydrostatic pressure to start from; its
# boundary is the tank's walls followed by the bodies' particles, in the order ``Coupled`` is
# given the bodies.

n = [int(round(tank[0] / spacing)), int(round(tank[1] / spacing)), int(round(depth / spacing))]
axes = [(np.arange(k) + 0.5) * spacing for k in n]
water = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
boundary = coupled_boundary(box_boundary((0, 0, 0), tank, spacing), bodies, spacing)
liquid = SPHLiquid(water, spacing=spacing, boundary=boundary, solver="dfsph",
                   kinematic_viscosity=1e-4, initial_pressure=hydrostatic_pressure(water, spacing),
                   container=((0, 0, 0), tank))
sim = Coupled(liquid, bodies)
print(f"{water.shape[0]} water particles, {bodies.n_bodies} bodies")

# %%
# The series
# ----------
# One ``Simulation`` for :class:`pipeline.SimulationSource`; the bodies' meshes are a filter of
# the particle frames.

flow = Flow(SimulationSource(sim, fps=30, duration=0.8 if SMALL else 1.5))
flow.add("bodies", BodyMeshes(sim.body_mesh_layout()))
flow.add_collider("tank", ~Box((0, 0, 0), tank), role="container")
paths = flow.run(OUT, progress=False)
times, frames = read_series(paths["particles"])
_, meshes = read_series(paths["bodies"])
z = np.asarray(frames[-1].field_data["body_position"]).reshape(-1, 3)[:, 2]
level = np.percentile(np.asarray(frames[-1].points)[:, 2], 99) + 0.5 * spacing
print(f"t = {times[-1]:.2f} s: water level {100 * level:.1f} cm; the ball's top "
      f"{100 * (z[0] + 0.04 - level):+.1f} cm above it, the brick's bottom "
      f"{100 * (z[1] - 0.02):.1f} cm above the floor")

# %%
# The picture
# -----------
# The last frame: the water's particles and the bodies' meshes from the series.

plotter = pv.Plotter(window_size=(800, 560))
plotter.add_mesh(frames[-1], color="#3b7dd8", point_size=6 if SMALL else 4,
                 render_points_as_spheres=True)
body = np.asarray(meshes[-1].point_data["body"])
plotter.add_mesh(meshes[-1].extract_points(body == 0, adjacent_cells=False), color="#c8924f",
                 smooth_shading=True)
plotter.add_mesh(meshes[-1].extract_points(body == 1, adjacent_cells=False), color="#b5523b")
plotter.add_mesh(pv.Box((0, tank[0], 0, tank[1], 0, tank[2])), style="wireframe", color="black")
plotter.camera_position = [(0.62, -0.42, 0.36), (0.15, 0.1, 0.08), (0.0, 0.0, 1.0)]
OUT.mkdir(parents=True, exist_ok=True)
plotter.show(screenshot=OUT / "bodies_in_water.png")
