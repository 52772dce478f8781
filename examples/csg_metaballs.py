"""
Metaballs combined with shapes (CSG)
====================================

A particle field (negative inside, as every implicit in blobflow) combines with the shapes of
:mod:`filters.geometry` by Ricci's (1973) operators: ``union`` (min), ``intersection`` (max) and
``difference``; shapes combine among themselves with ``|``, ``&``, ``-`` and ``~``.  In the
pipeline the surface stages take the shape as ``implicit=`` and ``operation=``; on arrays,
:func:`filters.surface.csg.combine_dense` (and ``combine_sparse``) does the same to a splatted
field.

Forty metaballs (Wyvill, McPheeters & Wyvill 1986 "soft objects") along a loop, combined with
a ball, a box and a ball minus a slab.
"""

# %%
import os
from pathlib import Path

import numpy as np
import pyvista as pv

from filters.geometry import Box, Sphere
from filters.surface.csg import combine_dense
from filters.surface.splat import splat_dense
from pipeline.surface import reconstruct

pv.OFF_SCREEN = True  # draw without a display

SMALL = os.environ.get("BLOBFLOW_EXAMPLE_SMALL") == "1"  # the tests run every example small
OUT = Path(os.environ.get("BLOBFLOW_EXAMPLES_OUT", "outputs/examples")) / "csg_metaballs"

# %%
# The metaballs
# -------------
# Balls of radius 4 cm on a wavy loop of radius 15 cm: neighbours overlap and blend.

n = 40
angle = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
centres = np.column_stack([0.15 * np.cos(angle), 0.15 * np.sin(angle),
                           0.03 * np.sin(3.0 * angle)])
radius = 0.04  # m
cell = 0.008 if SMALL else 0.004  # voxel edge (m)
metaballs = dict(kernel="metaball", anisotropic=False, feature_smoothing=0, smooth_iterations=20,
                 volume_correction=False, attributes=(), cell_size=cell)

# %%
# Through the surface stages
# --------------------------
# ``reconstruct`` (or ``surface_stages`` in a :class:`pipeline.Flow`) with a shape: the loop
# united with a ball at its centre, intersected with a box, and with a ball cut out of it.

ball = Sphere((0.0, 0.0, 0.0), 0.07)
union = reconstruct(centres, radius, implicit=ball, operation="union", **metaballs)
boxed = reconstruct(centres, radius, implicit=Box((-0.2, -0.2, -0.02), (0.12, 0.2, 0.2)),
                    operation="intersection", **metaballs)
bitten = reconstruct(centres, radius, implicit=Sphere((0.15, 0.0, 0.05), 0.05),
                     operation="difference", **metaballs)

# %%
# On arrays
# ---------
# The same on a dense voxel field, with a combined shape: a ball split by a slot.
# ``splat_dense`` returns a :class:`~filters.surface.grid.DenseField` (values ``(nz, ny, nx)``,
# negative inside); wrapped as an image, VTK's contour gives the surface at 0.

field = splat_dense(centres, radius, cell, kernel="metaball")
shape = Sphere((0.0, 0.0, 0.0), 0.09) - Box((-0.2, -0.015, -0.2), (0.2, 0.015, 0.2))
combined = combine_dense(field, shape, "union")
image = pv.ImageData(dimensions=combined.dimensions, spacing=(cell,) * 3,
                     origin=combined.origin)
image.point_data["implicit"] = combined.values.ravel()  # x fastest: VTK's point order
arrays = image.contour([0.0], scalars="implicit")
for name, surface in (("union", union), ("intersection", boxed), ("difference", bitten),
                      ("arrays", arrays)):
    print(f"{name}: {surface.n_cells} triangles, {surface.n_open_edges} open edges")

# %%
# The picture
# -----------

plotter = pv.Plotter(shape=(2, 2), window_size=(900, 700), border=False)
titles = ('operation="union", a Sphere', 'operation="intersection", a Box',
          'operation="difference", a Sphere', "combine_dense: Sphere - Box, union")
for k, (title, surface) in enumerate(zip(titles, (union, boxed, bitten, arrays), strict=True)):
    plotter.subplot(k // 2, k % 2)
    plotter.add_text(title, font_size=10)
    plotter.add_mesh(surface, color="#e0a95c", smooth_shading=True, split_sharp_edges=True,
                     specular=0.4)
    plotter.camera_position = [(0.42, -0.52, 0.42), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)]
OUT.mkdir(parents=True, exist_ok=True)
plotter.show(screenshot=OUT / "csg_metaballs.png")
