"""Ready-made SPH set-ups: the dam break and a drop into a pool, as :class:`SPHLiquid` objects.

Both validate every parameter before sampling a single particle, so a bad value fails fast with a
``ValueError`` naming it.  Fluid particles sit at the cell centres of a lattice of step
``spacing`` aligned with the tank's inner walls, and the walls are
:func:`filters.sph.boundary.box_boundary` layers on the same lattice, so the fluid starts
exactly at rest density, corners included.  With DFSPH the dam break's column starts with its
hydrostatic pressure and the drop's pool starts settled (:mod:`filters.sph.settle`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..memory import check_memory
from ..validation import check_range
from .boundary import box_boundary
from .liquid import SPHLiquid, default_support_factor
from .settle import hydrostatic_pressure, settle

if TYPE_CHECKING:
    from collections.abc import Iterable
    from typing import Any

__all__ = ["dam_break_liquid", "drop_liquid", "MAX_PARTICLES", "SETTLE_TIME", "SETTLE_DAMPING"]

#: Largest particle count the set-ups accept (fluid plus boundary).
MAX_PARTICLES = 50_000_000
#: Peak bytes per fluid particle of a running liquid (state, neighbour lists, solver scratch;
#: measured 1.8 KiB per fluid particle, boundary included, on a 31k dam break).
BYTES_PER_PARTICLE = 2048


def _lattice(lo, hi, spacing):
    """Cell centres of the lattice of step ``spacing`` in the box [lo, hi] (whole cells only)."""
    axes = []
    for k in range(3):
        n = int(math.floor((hi[k] - lo[k]) / spacing + 1e-9))
        axes.append(lo[k] + (np.arange(n) + 0.5) * spacing)
    X, Y, Z = np.meshgrid(*axes, indexing="ij")
    return np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)


def _positive(name, value):
    value = check_range(name, value, 0.0, math.inf, low_inclusive=False)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite (m), got {value!r}")
    return value


def _check_count(fluid, tank, spacing, layers=2):
    inner = np.prod(np.array(tank) / spacing)
    outer = np.prod(np.array(tank) / spacing + 2 * layers)
    total = fluid + (outer - inner)
    check_memory(f"a liquid of {fluid:.3g} particles at spacing {spacing:g} m",
                 BYTES_PER_PARTICLE * fluid, hint="increase spacing")
    if total > MAX_PARTICLES:
        raise ValueError(
            f"spacing {spacing:g} m gives about {total:.3g} particles (limit {MAX_PARTICLES:g}); "
            f"increase spacing")


def dam_break_liquid(*, column_width: float = 0.2, column_height: float | None = None,
                     tank_length: float | None = None, depth: float = 0.1,
                     tank_height: float | None = None, spacing: float = 0.01,
                     free_slip: Iterable[str] = (), **sph_options: Any) -> SPHLiquid:
    """A water column collapsing in a closed tank (the dam break of Martin & Moyce 1952).

    The column of width ``a = column_width`` (x) and height ``column_height`` (z, default ``2 a``)
    stands against the left wall (x = 0) and spans the tank's depth (y).  The tank is the box
    ``[0, tank_length] x [0, depth] x [0, tank_height]``.

    Parameters
    ----------
    column_width : float
        ``a`` (m), > 0.
    column_height : float, optional
        (m); default ``2 a``.
    tank_length : float, optional
        (m), >= ``column_width``; default ``4 a``.
    depth : float
        Tank and column depth (m), > 0.
    tank_height : float, optional
        (m), >= ``column_height``; default ``1.5 * column_height``.
    spacing : float
        Particle spacing (m), > 0, at most half of the column's smallest side.
    free_slip : iterable of str
        Tank faces without friction (:data:`filters.sph.boundary.BOX_FACES`; ``"y"`` for both
        side walls: a column a few particles deep between them is the quasi-2D experiment).
    **sph_options
        Passed to :class:`filters.sph.SPHLiquid` (``container`` defaults to the tank's inner
        box, a DFSPH column starts with its hydrostatic pressure; ``viscosity``, ``xsph``,
        ``surface_tension``, ``cfl``, ``threads`` ...).

    Returns
    -------
    SPHLiquid

    Raises
    ------
    ValueError, TypeError
        For a bad parameter, before any particle is sampled.
    """
    spacing = _positive("spacing", spacing)
    a = _positive("column_width", column_width)
    hcol = _positive("column_height", 2.0 * a if column_height is None else column_height)
    length = _positive("tank_length", 4.0 * a if tank_length is None else tank_length)
    depth = _positive("depth", depth)
    height = _positive("tank_height", 1.5 * hcol if tank_height is None else tank_height)
    if a > length:
        raise ValueError(f"column_width {a:g} m must not exceed tank_length {length:g} m")
    if hcol > height:
        raise ValueError(f"column_height {hcol:g} m must not exceed tank_height {height:g} m")
    smallest = min(a, hcol, depth)
    if spacing > 0.5 * smallest:
        raise ValueError(
            f"spacing must be in (0, {0.5 * smallest:g}] m (half the column's smallest side), "
            f"got {spacing:g}")
    fluid = (a / spacing) * (hcol / spacing) * (depth / spacing)
    _check_count(fluid, (length, depth, height), spacing)
    x = _lattice((0.0, 0.0, 0.0), (a, depth, hcol), spacing)
    kernel = sph_options.get("kernel", "cubic")
    support_factor = sph_options.get("support_factor") or default_support_factor(kernel)
    walls = box_boundary((0.0, 0.0, 0.0), (length, depth, height), spacing,
                         support_factor=support_factor, kernel=kernel, free_slip=free_slip)
    sph_options.setdefault("container", ((0.0, 0.0, 0.0), (length, depth, height)))
    if sph_options.get("solver", "wcsph") == "dfsph":
        sph_options.setdefault("initial_pressure", hydrostatic_pressure(
            x, spacing, sph_options.get("gravity", (0.0, 0.0, -9.81)),
            sph_options.get("rest_density", 1000.0)))
    return SPHLiquid(x, spacing=spacing, boundary=walls, **sph_options)


def drop_liquid(*, tank_length: float = 0.4, tank_width: float = 0.4, tank_height: float = 0.4,
                pool_depth: float = 0.1, drop_radius: float = 0.06, drop_height: float = 0.25,
                drop_speed: float = 0.0, spacing: float = 0.01, **sph_options: Any) -> SPHLiquid:
    """A sphere of liquid falling into a resting pool in a closed tank.

    Parameters
    ----------
    tank_length, tank_width, tank_height : float
        Inner size of the tank (m) along x, y, z.
    pool_depth : float
        Depth of the pool (m), >= 0 (0: no pool), below ``drop_height - drop_radius``.
    drop_radius : float
        Radius of the drop (m), at least one spacing.
    drop_height : float
        Height of the drop's centre above the floor (m).
    drop_speed : float
        Initial downward speed of the drop (m/s), >= 0.
    spacing : float
        Particle spacing (m), > 0.
    **sph_options
        Passed to :class:`filters.sph.SPHLiquid`.  With ``solver="dfsph"`` the pool starts
        settled (:func:`filters.sph.settle.settle` for 1 s of simulated time, once per process
        for the same pool and settings) with its pressure: its surface stays within 0.01
        spacings over the first half second when nothing falls in (tested).

    Returns
    -------
    SPHLiquid
        Fluid ids: the pool first, then the drop.

    Raises
    ------
    ValueError, TypeError
        For a bad parameter, before any particle is sampled.
    """
    spacing = _positive("spacing", spacing)
    length = _positive("tank_length", tank_length)
    width = _positive("tank_width", tank_width)
    height = _positive("tank_height", tank_height)
    pool = check_range("pool_depth", pool_depth, 0.0, height)
    radius = _positive("drop_radius", drop_radius)
    zc = _positive("drop_height", drop_height)
    speed = check_range("drop_speed", drop_speed, 0.0, 100.0)
    if radius < spacing:
        raise ValueError(f"drop_radius must be >= spacing ({spacing:g} m), got {radius:g}")
    if 2.0 * radius > min(length, width):
        raise ValueError(f"drop_radius {radius:g} m does not fit in the tank "
                         f"({length:g} x {width:g} m)")
    if zc + radius > height:
        raise ValueError(f"drop_height + drop_radius must be <= tank_height {height:g} m")
    if zc - radius < pool + spacing:
        raise ValueError(f"the drop (bottom at {zc - radius:g} m) must start at least one spacing "
                         f"above the pool surface ({pool:g} m)")
    if 0.0 < pool < 2.0 * spacing:
        raise ValueError(f"pool_depth must be 0 or >= 2 spacings ({2 * spacing:g} m), got {pool:g}")
    fluid = length * width * pool / spacing ** 3 + 4.19 * radius ** 3 / spacing ** 3
    _check_count(fluid, (length, width, height), spacing)
    parts = []
    if pool > 0.0:
        parts.append(_lattice((0.0, 0.0, 0.0), (length, width, pool), spacing))
    center = np.array([0.5 * length, 0.5 * width, zc])
    cube = _lattice(center - radius, center + radius, spacing)
    sphere = cube[((cube - center) ** 2).sum(axis=1) <= radius * radius]
    parts.append(sphere)
    kernel = sph_options.get("kernel", "cubic")
    support_factor = sph_options.get("support_factor") or default_support_factor(kernel)
    walls = box_boundary((0.0, 0.0, 0.0), (length, width, height), spacing,
                         support_factor=support_factor, kernel=kernel)
    sph_options.setdefault("container", ((0.0, 0.0, 0.0), (length, width, height)))
    pressure = None
    if pool > 0.0 and sph_options.get("solver", "wcsph") == "dfsph":
        parts[0], pool_pressure = _settled_pool(parts[0], walls, spacing, sph_options)
        pressure = np.concatenate([pool_pressure, np.zeros(sphere.shape[0])])
        sph_options.setdefault("initial_pressure", pressure)
    x = np.concatenate(parts)
    v = np.zeros_like(x)
    v[x.shape[0] - sphere.shape[0]:, 2] = -speed
    return SPHLiquid(x, v, spacing=spacing, boundary=walls, **sph_options)


#: Settled pools of this process, by the pool's particles, walls and liquid settings.
_SETTLED: dict = {}
#: Simulated time (s) a pool settles for, and the velocity damping per step while it does.
SETTLE_TIME = 1.0
SETTLE_DAMPING = 0.05


def _settled_pool(x, walls, spacing, sph_options):
    """The pool's particles after :func:`filters.sph.settle.settle` (DFSPH), and their
    pressure (Pa), in the lattice's order; computed once per process for the same pool."""
    try:
        key = (x.tobytes(), walls.points.tobytes(), spacing,
               repr(sorted((k, v) for k, v in sph_options.items() if k != "initial_pressure")))
        hash(key)
    except TypeError:  # e.g. an external field object: settle afresh
        key = None
    if key is not None and key in _SETTLED:
        settled, pressure = _SETTLED[key]
        return settled.copy(), pressure.copy()
    options = {k: v for k, v in sph_options.items() if k not in ("initial_pressure", "external")}
    options["initial_pressure"] = hydrostatic_pressure(
        x, spacing, options.get("gravity", (0.0, 0.0, -9.81)), options.get("rest_density", 1000.0))
    pool = SPHLiquid(x, spacing=spacing, boundary=walls, **options)
    settle(pool, max_time=SETTLE_TIME, damping=SETTLE_DAMPING)
    order = np.argsort(pool.state.extra["id"])
    settled = np.ascontiguousarray(pool.state.positions[order])
    pressure = np.ascontiguousarray(pool.state.extra["pressure"][order])
    if key is not None:
        _SETTLED[key] = (settled, pressure)
    return settled.copy(), pressure.copy()
