"""
The surface of your own particles
=================================

:func:`pipeline.surface.reconstruct` turns any point cloud into a watertight triangle surface:
splat a kernel per particle onto a sparse voxel grid, contour it with VTK's flying edges, smooth
it and compute normals.  Its defaults are the liquid scenes' surface (anisotropic ``sph``
kernels, feature smoothing, windowed-sinc smoothing, the volume correction).  Installed
blobflow also gives every PyVista dataset the same call as ``dataset.blobflow.surface(...)``.

The particles here are a pool and a drop sampled at spacing ``2 r`` (as a liquid simulation
would give them), with a velocity that the surface carries to its vertices.
"""

# %%
import os
from pathlib import Path

import numpy as np
import pyvista as pv

from pipeline.surface import reconstruct

pv.OFF_SCREEN = True  # draw without a display

SMALL = os.environ.get("BLOBFLOW_EXAMPLE_SMALL") == "1"  # the tests run every example small
OUT = Path(os.environ.get("BLOBFLOW_EXAMPLES_OUT", "outputs/examples")) / "surface_of_particles"

# %%
# Particles
# ---------
# A jittered lattice: a pool 20 cm wide and 4 cm deep, and a drop of radius 4 cm falling into it.

spacing = 0.02 if SMALL else 0.01  # m
radius = spacing / 2  # particle radius (m)
rng = np.random.default_rng(7)
axis = np.arange(-0.1, 0.1, spacing) + spacing / 2
pool = np.stack(np.meshgrid(axis, axis, np.arange(0.0, 0.04, spacing) + spacing / 2,
                            indexing="ij"), -1).reshape(-1, 3)
ball = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
drop = ball[np.linalg.norm(ball, axis=1) < 0.04] + [0.0, 0.0, 0.12]
points = np.concatenate([pool, drop]) + rng.normal(0.0, 0.05 * spacing, (len(pool) + len(drop), 3))
velocity = np.zeros_like(points)
velocity[len(pool):, 2] = -1.0  # the drop falls at 1 m/s

cloud = pv.PolyData(points)
cloud.point_data["velocity"] = velocity
print(f"{cloud.n_points} particles of radius {radius} m")

# %%
# Two surfaces
# ------------
# ``reconstruct`` with its defaults (the liquid scenes' surface), and the accessor with
# spherical kernels and no smoothing: the lattice's bumps show.

liquid = reconstruct(cloud, radius)
raw = cloud.blobflow.surface(radius=radius, anisotropic=False, feature_smoothing=0,
                             smooth_iterations=0, volume_correction=False)
for name, surface in (("default", liquid), ("isotropic, unsmoothed", raw)):
    print(f"{name}: {surface.n_cells} triangles, {surface.n_open_edges} open edges, "
          f"volume {surface.volume * 1e6:.1f} cm^3, arrays {list(surface.point_data.keys())}")
print(f"the particles' volume (2 r)^3 N: {cloud.n_points * spacing ** 3 * 1e6:.1f} cm^3")

# %%
# The picture
# -----------
# Side by side, coloured by the speed the surface carries from the particles.

plotter = pv.Plotter(shape=(1, 2), window_size=(1000, 450), border=False)
for column, (title, surface) in enumerate((("reconstruct(cloud, radius)", liquid),
                                           ("anisotropic=False, no smoothing", raw))):
    plotter.subplot(0, column)
    plotter.add_text(title, font_size=11)
    plotter.add_mesh(surface, scalars="velocity", cmap="Blues", clim=(0.0, 1.0),
                     smooth_shading=True, specular=0.5,
                     scalar_bar_args={"title": "speed (m/s)", "vertical": False})
    plotter.camera_position = [(0.33, -0.42, 0.27), (0.0, 0.0, 0.05), (0.0, 0.0, 1.0)]
OUT.mkdir(parents=True, exist_ok=True)
plotter.show(screenshot=OUT / "surface_of_particles.png")
