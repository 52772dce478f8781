"""Shared by the scenes with bodies in the water: the pool, the coupled simulation and its flow."""

from __future__ import annotations

import math

import numpy as np

from filters.coupling import Coupled, coupled_boundary
from filters.coupling.parts import count_inside, world_meshes
from filters.geometry import Box
from filters.sph import SPHLiquid
from filters.sph.boundary import box_boundary
from filters.sph.settle import hydrostatic_pressure
from filters.validation import check_range
from pipeline import Flow, SimulationSource
from pipeline.bodies import BodyMeshes

from .liquid_surface import add_liquid_surface


def pool_lattice(tank, depth: float, spacing: float, meshes=()) -> np.ndarray:
    """Cell centres ``(i + 1/2) spacing`` of the pool ``[0, tank_x] x [0, tank_y] x [0,
    depth]``, less those inside the closed meshes ``meshes`` (bodies that start in the water)."""
    n = [int(math.floor(tank[0] / spacing + 1e-9)), int(math.floor(tank[1] / spacing + 1e-9)),
         int(math.floor(depth / spacing + 1e-9))]
    axes = [(np.arange(k) + 0.5) * spacing for k in n]
    x = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    keep = np.ones(x.shape[0], dtype=bool)
    for v, f in meshes:
        keep &= ~count_inside(x, v, f)
    return np.ascontiguousarray(x[keep])


def check_pool(tank, depth, spacing):
    """Validate the tank (m), the water depth (m) and the spacing (m) before any work."""
    spacing = check_range("spacing", spacing, 0.0, math.inf, low_inclusive=False)
    for name, value in zip(("tank_length", "tank_width", "tank_height"), tank, strict=True):
        check_range(name, value, 4 * spacing, 100.0)
    check_range("water_depth", depth, 2 * spacing, tank[2])
    count = tank[0] * tank[1] * depth / spacing ** 3
    if count > 2e6:
        raise ValueError(f"spacing {spacing:g} m gives {count:.3g} particles (at most 2e6); "
                         f"increase spacing")
    return spacing


def coupled_flow(bodies, *, tank, depth, spacing, fps, duration, kinematic_viscosity, cfl,
                 max_dt, surface, smooth_iterations=30, feature_smoothing=25,
                 anisotropic=True) -> Flow:
    """The flow of a pool of water in a closed tank ``[0, tank]`` with ``bodies`` in it.

    Outputs ``particles`` (the liquid, the bodies in its field data), ``bodies`` (their meshes,
    :class:`pipeline.bodies.BodyMeshes`) and, with ``surface``, the water ``surface``.
    """
    sim = coupled_simulation(bodies, tank=tank, depth=depth, spacing=spacing,
                             kinematic_viscosity=kinematic_viscosity, cfl=cfl, max_dt=max_dt)
    flow = Flow(SimulationSource(sim, fps=fps, duration=duration))
    flow.add("bodies", BodyMeshes(sim.body_mesh_layout()))
    box = Box((0.0, 0.0, 0.0), tuple(tank))
    flow.add_collider("tank", ~box, role="container")
    if surface:
        add_liquid_surface(flow, spacing=spacing, tank_lo=box.lower, tank_hi=box.upper,
                           smooth_iterations=smooth_iterations,
                           feature_smoothing=feature_smoothing, anisotropic=anisotropic)
    return flow


def coupled_simulation(bodies, *, tank, depth, spacing, kinematic_viscosity, cfl,
                       max_dt) -> Coupled:
    """The pool (less what the bodies fill) and the bodies, two-way coupled."""
    meshes = []
    for b in bodies:
        meshes.extend(world_meshes(b))
    x = pool_lattice(tank, depth, spacing, meshes)
    walls = box_boundary((0.0, 0.0, 0.0), tuple(tank), spacing)
    boundary = coupled_boundary(walls, bodies, spacing)
    liquid = SPHLiquid(x, spacing=spacing, boundary=boundary, solver="dfsph",
                       initial_pressure=hydrostatic_pressure(x, spacing),
                       kinematic_viscosity=kinematic_viscosity, cfl=cfl, max_dt=max_dt,
                       container=((0.0, 0.0, 0.0), tuple(tank)))
    return Coupled(liquid, bodies)

