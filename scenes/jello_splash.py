"""``jello_splash``: a finite-element jello dropped into a pool: it splashes, bobs and floats.

An elastic body two-way coupled with the DFSPH liquid (:class:`filters.coupling.Coupled`): the
jello's boundary particles ride in its tetrahedra, and the water's forces on them are spread
over its nodes, inside every step of its implicit (backward Euler) integration.  Outputs
``particles`` (the water; the jello's surface vertices in its field data), ``bodies`` (the
jello's surface) and ``surface``; the jello's tetrahedra are not written.
"""

from __future__ import annotations

import numpy as np

from filters.elastic.contact import Colliders
from filters.elastic.fem_simulation import FEMSimulation
from filters.elastic.topology import icosphere
from filters.geometry import Box
from filters.validation import check_range
from pipeline import Flow
from pipeline.scene import Scene

from .coupled_pool import check_pool, coupled_flow

SCENE_FPS = 30.0
SCENE_DURATION = 2.0  # s: the fall, the splash, bobbing, afloat


def build(*, spacing: float = 0.01, tank_length: float = 0.3, tank_width: float = 0.3,
          tank_height: float = 0.35, water_depth: float = 0.12, radius: float = 0.06,
          drop_height: float = 0.06, density: float = 600.0, youngs_modulus: float = 3e4,
          poisson_ratio: float = 0.45, damping: float = 0.002, lattice: float = 0.02,
          kinematic_viscosity: float = 1e-4, cfl: float = 0.4, max_dt: float = 0.005,
          surface: bool = True, smooth_iterations: int = 30, feature_smoothing: int = 25,
          anisotropic: bool = True) -> Flow:
    """Drop a jello ball into a pool (10,800 water particles with the defaults).

    Parameters
    ----------
    spacing : float
        Water particle spacing (m), > 0.
    tank_length : float
        Inner length of the closed tank along x (m), at least four spacings.
    tank_width : float
        Inner width of the tank along y (m), at least four spacings.
    tank_height : float
        Inner height of the tank (m), at least four spacings.
    water_depth : float
        Depth of the pool (m), at least two spacings.
    radius : float
        Radius of the jello ball (m), at least two spacings.
    drop_height : float
        Height of the ball's lowest point above the water (m), >= 0.
    density : float
        The jello's density (kg/m^3) in [100, 10000]; below the water's 1000 it floats.
    youngs_modulus : float
        Young's modulus E (Pa), > 0 (Neo-Hookean, Smith et al. 2018).
    poisson_ratio : float
        Poisson's ratio in [0, 0.5); 0.45 keeps the volume.
    damping : float
        Rayleigh stiffness damping (s), >= 0.
    lattice : float
        Edge of the lattice cells (m) cut into tetrahedra, > 0.
    kinematic_viscosity : float
        ``nu`` (m^2/s) in (0, 1] of the water and of its friction on walls and jello.
    cfl : float
        Courant number in (0, 1].
    max_dt : float
        Largest time step (s) of water and jello, in (0, 1].
    surface : bool
        Also write the water surface.
    smooth_iterations : int
        Windowed-sinc smoothing iterations of the water surface (0 to 1000).
    feature_smoothing : int
        Feature-weighted Laplacian smoothing sweeps of the water surface (0 to 10000).
    anisotropic : bool
        Anisotropic kernels for the water surface.
    """
    tank = (tank_length, tank_width, tank_height)
    spacing = check_pool(tank, water_depth, spacing)
    radius = check_range("radius", radius, 2 * spacing, 0.5 * min(tank_length, tank_width))
    drop = check_range("drop_height", drop_height, 0.0, tank_height)
    density = check_range("density", density, 100.0, 1e4)
    lattice = check_range("lattice", lattice, 0.0, radius, low_inclusive=False)
    check_range("kinematic_viscosity", kinematic_viscosity, 0.0, 1.0, low_inclusive=False)
    if water_depth + drop + 2 * radius >= tank_height - spacing:
        raise ValueError("the jello does not fit under the lid: lower drop_height or radius")
    points, triangles = icosphere(radius, 3)
    points = points + np.array([0.5 * tank_length, 0.5 * tank_width,
                                water_depth + drop + radius])
    walls = Colliders(friction=0.3).add(~Box((0.0, 0.0, 0.0), tank))
    jello = FEMSimulation.from_mesh(points, triangles, spacing=lattice, density=density,
                                    youngs_modulus=youngs_modulus, poisson_ratio=poisson_ratio,
                                    stiffness_damping=damping, colliders=walls, max_dt=max_dt)
    return coupled_flow([jello], tank=tank, depth=water_depth, spacing=spacing, fps=SCENE_FPS,
                        duration=SCENE_DURATION, kinematic_viscosity=kinematic_viscosity,
                        cfl=cfl, max_dt=max_dt, surface=surface,
                        smooth_iterations=smooth_iterations,
                        feature_smoothing=feature_smoothing, anisotropic=anisotropic)


SCENE = Scene("jello_splash", build, "a finite-element jello dropped into a pool: it splashes, "
              "bobs and floats (elastic body coupled with the DFSPH liquid)",
              fps=SCENE_FPS, duration=SCENE_DURATION, still=1.0)
