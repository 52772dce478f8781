"""
Particles advected by curl noise
================================

Curl noise (Bridson, Hourihan & Nordenstam 2007) is the curl of a noise potential: a velocity
field with eddies everywhere and no divergence, so that particles advected by it neither bunch
up nor spread out.  :class:`filters.fields.CurlNoise` builds it from Perlin's improved noise
(:mod:`filters.noise`), adds a uniform flow through its potential, and ramps the potential near
colliders so that the flow goes around them.  :class:`filters.advect.NoiseAdvection` emits
particles in a box and advects them (``rk4`` here).

Everything here is arrays: the same field evaluates at any points (``field(points, t)``) and
gives its Jacobian, from which the divergence is read.
"""

# %%
import os
from pathlib import Path

import numpy as np
import pyvista as pv

from filters.advect import BoxEmitter, NoiseAdvection
from filters.fields import CurlNoise
from filters.geometry import Plane, Sphere

pv.OFF_SCREEN = True  # draw without a display

SMALL = os.environ.get("BLOBFLOW_EXAMPLE_SMALL") == "1"  # the tests run every example small
OUT = Path(os.environ.get("BLOBFLOW_EXAMPLES_OUT", "outputs/examples")) / "curl_noise_advection"

# %%
# The field
# ---------
# Eddies about 40 cm across (2.5 lattice cells per metre), 0.4 m/s, two octaves, on a rising
# flow of 0.5 m/s, going around a ball of radius 15 cm.

ball = Sphere((0.0, 0.0, 0.6), 0.15)
floor = Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
field = CurlNoise(amplitude=0.4, frequency=2.5, octaves=2, seed=3, time_scale=0.3,
                  colliders=(ball,), ramp_distance=0.1, base_velocity=(0.0, 0.0, 0.5))

probe = np.random.default_rng(0).uniform([-0.4, -0.4, 0.0], [0.4, 0.4, 1.4], (2000, 3))
probe = probe[ball(probe) > 0.0]  # shapes are signed distances (m), negative inside
velocity, jacobian = field.jacobian(probe, 0.0)  # (N, 3) m/s and (N, 3, 3) 1/s
divergence = np.trace(jacobian, axis1=1, axis2=2)
print(f"median speed {np.median(np.linalg.norm(velocity, axis=1)):.2f} m/s; "
      f"largest |divergence| {np.abs(divergence).max():.1e} 1/s "
      f"(median velocity gradient {np.median(np.abs(jacobian)):.1f} 1/s)")

# %%
# The particles
# -------------
# 2,000 particles a second from a thin box on the floor, living 2.5 s on average.

emitter = BoxEmitter(lower=(-0.12, -0.12, 0.0), upper=(0.12, 0.12, 0.04),
                     rate=800.0 if SMALL else 2000.0, lifetime=2.5, lifetime_jitter=0.25)
smoke = NoiseAdvection(field, emitter, integrator="rk4", colliders=(floor, ball),
                       max_dt=1.0 / 120.0, seed=3)
smoke.advance_to(1.0 if SMALL else 3.0)
frame = smoke.frame()  # plain arrays: points and point_data (velocity, id, age, size, color)
print(f"t = {frame.time} s: {len(frame.points)} particles alive")

# %%
# The picture
# -----------
# The particles coloured by age, the ball, and streamlines of the field at that time.

particles = pv.PolyData(frame.points)
particles.point_data["age"] = frame.point_data["age"]
grid = pv.ImageData(dimensions=(17, 17, 31), spacing=(0.05, 0.05, 0.05), origin=(-0.4, -0.4, 0.0))
grid.point_data["velocity"] = field(grid.points, frame.time)
seeds = pv.PolyData(np.column_stack([np.linspace(-0.3, 0.3, 7), np.full(7, 0.1), np.full(7, 0.3)]))
lines = grid.streamlines_from_source(seeds, vectors="velocity", max_length=3.0)

plotter = pv.Plotter(window_size=(600, 800))
plotter.add_mesh(pv.Sphere(center=ball.center, radius=ball.radius), color="#d0d0d0",
                 smooth_shading=True)
plotter.add_mesh(lines.tube(radius=0.004), color="#4a6fa5")
plotter.add_mesh(particles, scalars="age", cmap="inferno_r", clim=(0.0, 3.0), point_size=5,
                 render_points_as_spheres=True,
                 scalar_bar_args={"title": "age (s)", "fmt": "%.1f", "vertical": True,
                                  "position_x": 0.85, "position_y": 0.3})
plotter.add_mesh(pv.Plane(center=(0, 0, 0), i_size=1.2, j_size=1.2), color="#b8b8b8")
plotter.camera_position = [(3.0, -3.0, 1.6), (0.0, 0.0, 0.85), (0.0, 0.0, 1.0)]
OUT.mkdir(parents=True, exist_ok=True)
plotter.show(screenshot=OUT / "curl_noise_advection.png")
