"""
A series for ParaView, a USD stage for Blender and Houdini
==========================================================

A :class:`pipeline.Flow` writes each output as a time series that ParaView opens as one
animated dataset (*File > Open* the ``.pvd``, then *Play*): VTK XML frames in a folder, the
``.pvd`` collection and the same frames as a ``.series`` file, and, for a fixed topology with
``xdmf=True``, XDMF + HDF5 as well.  ``colliders.vtp`` beside them holds what the bodies touch.
:func:`pipeline.export_usd` writes series as one USD stage (Pixar's Universal Scene
Description, ``pip install -e ".[usd]"``) that Blender's and Houdini's importers read: particles
as ``Points``, surfaces as ``Mesh``, strands as linear ``BasisCurves``, one time sample per
frame, z-up in metres.  (``blobflow export SERIES.pvd --usd FILE.usd`` from the command line.)

Here hair grows from the vertices of a mesh (the upper half of a sphere, a head), falls and
drapes over it (:class:`filters.elastic.mass_spring.HairSimulation`, as the ``hair`` scene); the
run is written for ParaView, exported to USD, and the strands are read back from the USD stage
with Pixar's own ``pxr`` to draw them.
"""

# %%
import os
from pathlib import Path

import numpy as np
import pyvista as pv
from pxr import Usd, UsdGeom

from filters.elastic.contact import Colliders
from filters.elastic.mass_spring import HairSimulation
from filters.geometry import Sphere
from pipeline import Flow, SimulationSource, export_usd

pv.OFF_SCREEN = True  # draw without a display

SMALL = os.environ.get("BLOBFLOW_EXAMPLE_SMALL") == "1"  # the tests run every example small
OUT = Path(os.environ.get("BLOBFLOW_EXAMPLES_OUT", "outputs/examples")) / "paraview_and_usd"

# %%
# Hair from a mesh
# ----------------
# A root at every vertex of the mesh's upper part, growing outwards and combed down; 16 segments
# of 30 cm per strand, clamped at the root, with bending stiffness, air drag and friction on
# the head (a sphere collider).

head = Sphere((0.0, 0.0, 1.5), 0.1)
scalp = pv.Sphere(radius=0.1, center=(0.0, 0.0, 1.5), theta_resolution=12 if SMALL else 24,
                  phi_resolution=10 if SMALL else 20)
keep = scalp.point_normals[:, 2] > 0.2
roots, normals = np.asarray(scalp.points)[keep], scalp.point_normals[keep]
down = np.array([0.0, 0.0, -1.0]) + normals[:, 2:3] * normals  # downhill along the scalp
down[np.linalg.norm(down, axis=1) < 0.2] = (-1.0, 0.0, 0.0)  # the crown: combed backwards
grow = 0.4 * normals + down / np.linalg.norm(down, axis=1, keepdims=True)
hair = HairSimulation(roots, grow, segments=16, length=0.3, linear_density=1e-3, clamped=True,
                      stretch_stiffness=50.0, bend_stiffness=3e-6, damping=0.002,
                      bend_damping=2e-3, drag=4.0 * 1e-3 * 0.3 / 16,
                      colliders=Colliders(friction=0.3, thickness=0.002).add(head),
                      max_dt=1.0 / 60.0, newton_tol=1e-2)
print(f"{len(roots)} strands")

# %%
# The series, for ParaView
# ------------------------

flow = Flow(SimulationSource(hair, fps=30, duration=0.5 if SMALL else 1.5), name="hair",
            xdmf=True)
flow.add_collider("head", head)
paths = flow.run(OUT, progress=False)
for path in sorted(OUT.iterdir()):
    size = "folder of frames" if path.is_dir() else f"{path.stat().st_size:,} bytes"
    print(f"{path.name:<18} {size}")

# %%
# The USD stage
# -------------
# One prim per series under ``/blobflow``; a frame at time ``t`` is time code ``t * fps``.

usd = export_usd(paths["hair"], OUT / "hair.usd")
stage = Usd.Stage.Open(str(usd))
print(f"up axis {UsdGeom.GetStageUpAxis(stage)}, {stage.GetTimeCodesPerSecond():g} time codes "
      f"per second, {stage.GetStartTimeCode():g} to {stage.GetEndTimeCode():g}")
for prim in stage.Traverse():
    print(f"  {prim.GetPath()} ({prim.GetTypeName()})")

# %%
# Read back with ``pxr``
# ----------------------
# The strands at the last time code, as a PyVista mesh of poly-lines (what an importer sees).

curves = UsdGeom.BasisCurves(stage.GetPrimAtPath("/blobflow/hair"))
code = stage.GetEndTimeCode()
points = np.array(curves.GetPointsAttr().Get(code))
counts = np.array(curves.GetCurveVertexCountsAttr().Get(code))
starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
lines = np.concatenate([np.concatenate([[c], np.arange(s, s + c)])
                        for s, c in zip(starts, counts, strict=True)])
strands = pv.PolyData(points, lines=lines)
print(f"{len(counts)} strands, {len(points)} points at time code {code:g}")

# %%
# The picture
# -----------
# The strands from the USD stage as tubes, and the head from ``colliders.vtp``.

head = pv.read(OUT / "colliders.vtp")
plotter = pv.Plotter(window_size=(700, 700))
plotter.add_mesh(head, color="#d9c2a7", smooth_shading=True)
plotter.add_mesh(strands.tube(radius=0.0015), color="#7a4a26", smooth_shading=True)
plotter.camera_position = [(1.0, -1.4, 1.9), (0.0, 0.0, 1.43), (0.0, 0.0, 1.0)]
plotter.camera.zoom(1.6)
OUT.mkdir(parents=True, exist_ok=True)
plotter.show(screenshot=OUT / "paraview_and_usd.png")
