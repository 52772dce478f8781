"""``floating``: three boxes of different densities dropped into a tank of water.

Rigid bodies two-way coupled with the DFSPH liquid (:class:`filters.coupling.Coupled`): the
boxes' boundary particles move with them, and the force of the water on them (its pressure and
viscosity) moves them back.  Boxes lighter than water float near their Archimedes draft
(``density / 1000`` of their height under the water line; within 15 %: the liquid's force on
a body falls short of ``rho g V`` by 5-20 % here, so the 900 kg/m^3 box hovers just under the
surface at the default spacing), the heavy one sinks to the floor, where it rests on a film of
water a particle thick.
Outputs ``particles`` (the water; the boxes' poses in its field data), ``bodies`` (the boxes'
meshes, with ``body_orientation`` and ``body_translation`` as field data) and ``surface``.
"""

from __future__ import annotations

import numpy as np

from filters.elastic.contact import Colliders
from filters.geometry import Box
from filters.rigid import RigidBodies, RigidBody
from filters.rigid.meshes import box_mesh
from filters.validation import check_bool, check_range
from pipeline import Flow
from pipeline.scene import Scene

from .coupled_pool import check_pool, coupled_flow

SCENE_FPS = 30.0
SCENE_DURATION = 2.5  # s: the drop, the splash, the bobbing, at rest


def build(*, spacing: float = 0.01, tank_length: float = 0.45, tank_width: float = 0.2,
          tank_height: float = 0.25, water_depth: float = 0.12, box_size: float = 0.1,
          box_height: float = 0.05,
          densities: tuple = (500.0, 900.0, 1500.0), drop_height: float = 0.02,
          kinematic_viscosity: float = 1e-4, cfl: float = 0.4, max_dt: float = 0.005,
          surface: bool = True, smooth_iterations: int = 30, feature_smoothing: int = 25,
          anisotropic: bool = True) -> Flow:
    """Drop boxes of the given densities side by side into a pool (10,800 water particles
    with the defaults).

    Parameters
    ----------
    spacing : float
        Particle spacing (m), > 0; the boxes are sampled on the water's lattice.
    tank_length : float
        Inner length of the closed tank along x (m), at least four spacings.
    tank_width : float
        Inner width of the tank along y (m), at least four spacings.
    tank_height : float
        Inner height of the tank (m), at least four spacings.
    water_depth : float
        Depth of the pool (m), at least two spacings, at most ``tank_height``.
    box_size : float
        Length and width of the boxes (m), at least two spacings; best a whole number of
        spacings.
    box_height : float
        Height of the boxes (m), at least two spacings.  Flat boxes float upright: a cube of
        half the water's density would tip over (its metacentre lies below its centre of
        mass), a box twice as wide as high does not (``b^2 / (12 d) > (H - d) / 2``).
    densities : sequence of float
        One box per density (kg/m^3), each in [100, 10000], spread evenly along x.
    drop_height : float
        Height of the boxes' bottoms above the water (m), >= 0.
    kinematic_viscosity : float
        ``nu`` (m^2/s) in (0, 1] of the water and of its friction on walls and boxes.
    cfl : float
        Courant number in (0, 1].
    max_dt : float
        Largest time step (s) in (0, 1].
    surface : bool
        Also write the reconstructed water surface.
    smooth_iterations : int
        Windowed-sinc smoothing iterations of the water surface (0 to 1000).
    feature_smoothing : int
        Feature-weighted Laplacian smoothing sweeps of the water surface (0 to 10000).
    anisotropic : bool
        Anisotropic kernels for the water surface.
    """
    tank = (tank_length, tank_width, tank_height)
    spacing = check_pool(tank, water_depth, spacing)
    size = check_range("box_size", box_size, 2 * spacing, min(tank_length, tank_width))
    height = check_range("box_height", box_height, 2 * spacing, tank_height)
    drop = check_range("drop_height", drop_height, 0.0, tank_height)
    dens = np.atleast_1d(np.asarray(densities, dtype=np.float64))
    if dens.ndim != 1 or not 1 <= dens.size <= 8 or not np.all((dens >= 100) & (dens <= 1e4)):
        raise ValueError(f"densities must be 1 to 8 values in [100, 10000] kg/m^3, got "
                         f"{densities!r}")
    if dens.size * size > tank_length:
        raise ValueError(f"{dens.size} boxes of {size:g} m do not fit along tank_length "
                         f"{tank_length:g} m")
    if water_depth + drop + height >= tank_height - spacing:
        raise ValueError("the boxes do not fit under the lid: lower drop_height or box_size")
    check_range("kinematic_viscosity", kinematic_viscosity, 0.0, 1.0, low_inclusive=False)
    check_bool("surface", surface)
    pitch = tank_length / dens.size
    bodies = []
    for k, rho in enumerate(dens):
        # the box on the water's lattice: its corner on a lattice node (i spacing)
        x0 = round((pitch * (k + 0.5) - 0.5 * size) / spacing) * spacing
        y0 = round((0.5 * tank_width - 0.5 * size) / spacing) * spacing
        z0 = round((water_depth + drop) / spacing) * spacing
        v, f = box_mesh((size, size, height), (x0 + 0.5 * size, y0 + 0.5 * size,
                                               z0 + 0.5 * height))
        bodies.append(RigidBody(v, f, density=float(rho), friction=0.3))
    walls = Colliders(friction=0.3).add(~Box((0.0, 0.0, 0.0), tank))
    rigid = RigidBodies(bodies, colliders=walls, max_dt=max_dt)
    return coupled_flow([rigid], tank=tank, depth=water_depth, spacing=spacing, fps=SCENE_FPS,
                        duration=SCENE_DURATION, kinematic_viscosity=kinematic_viscosity,
                        cfl=cfl, max_dt=max_dt, surface=surface,
                        smooth_iterations=smooth_iterations,
                        feature_smoothing=feature_smoothing, anisotropic=anisotropic)


SCENE = Scene("floating", build, "three boxes (500, 900, 1500 kg/m^3) dropped into water: the "
              "lightest floats, the heaviest sinks (rigid bodies coupled with the DFSPH liquid)",
              fps=SCENE_FPS, duration=SCENE_DURATION, still=2.0)
