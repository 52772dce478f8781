"""The boundary particles of a running liquid: kept sorted for the neighbour search, moved by the
caller between steps, and the forces the fluid exerts on them.

Walls and bodies are one kind of thing here: :class:`filters.sph.boundary.BoundaryParticles`
with volumes, normals, velocities and friction factors.  A static tank never moves; a rigid body
or a deforming surface (cloth, the skin of an elastic body) is moved by its own simulation,
which hands the liquid the new positions and velocities before each step
(:meth:`BoundarySet.move`) and reads back the force of the fluid on each of its particles
(:func:`boundary_forces`) to sum into its own forces: two-way coupling in the manner of Akinci
et al. (2012), "Versatile rigid-fluid coupling for incompressible SPH" (ACM TOG 31(4)).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numba
import numpy as np
from numba import njit, prange

from ..binning import cell_keys, counting_sort
from ..kernels import kernel_dw
from ..neighbors import bounds
from .boundary import BoundaryParticles
from .neighbourhood import boundary_reach_mask, cell_range, mark_boundary_reach, wall_key, wall_of

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["BoundarySet", "boundary_forces"]


class BoundarySet:
    """Boundary particles of one liquid, in the caller's order and sorted by grid cell.

    Parameters
    ----------
    boundary : BoundaryParticles or None
        The walls and bodies (None: no boundary).
    rest_density : float
        ``rho0`` of the fluid (kg/m^3); a boundary particle weighs ``rho0 V_b`` in densities.
    cell : float
        Edge of the grid cells (m) the particles are sorted by (the fluid's search grid).

    Attributes
    ----------
    points, velocities, normals : (M, 3) float64
        In the caller's order (read-only views; :meth:`move` replaces them).
    volumes, friction : (M,) float64
        Likewise.
    moving : bool
        Whether any boundary particle has ever had a non-zero velocity (the solvers then carry
        the boundary velocity terms).
    """

    def __init__(self, boundary: BoundaryParticles | None, rest_density: float, cell: float):
        if boundary is None:
            boundary = BoundaryParticles(np.zeros((0, 3)), np.zeros(0))
        self.rest_density = float(rest_density)
        self.cell = float(cell)
        self.points = boundary.points
        self.velocities = boundary.velocities
        self.volumes = boundary.volumes
        self.normals = boundary.normals
        self.friction = boundary.friction
        self.moving = bool(np.any(self.velocities != 0.0))
        # the particles moved since the start (a body's; the tank's never move): the grid's
        # reach mask of the others is kept while the grid stays the same
        self._moved = np.zeros(self.points.shape[0], dtype=np.bool_)
        self._moved_idx = np.zeros(0, dtype=np.int64)
        self._static_mask = None
        self._static_key = None
        self._sort()

    @property
    def n_points(self) -> int:
        """Number of boundary particles ``M``."""
        return self.points.shape[0]

    def _sort(self):
        x = self.points
        m = x.shape[0]
        if m:
            lo, hi, _ = bounds(x)  # one pass (x.min(axis=0) and max take 20x longer)
            dims = (np.floor((hi - lo) / self.cell) + 1).astype(np.int64)
            if float(np.prod(dims.astype(np.float64))) > 2e8:
                raise ValueError("boundary spans more than 2e8 grid cells; increase spacing")
            keys = cell_keys(x, lo, 1.0 / self.cell, dims)
            start, order = counting_sort(keys, int(np.prod(dims)), numba.get_num_threads())
        else:
            lo = np.zeros(3)
            dims = np.ones(3, dtype=np.int64)
            start = np.zeros(2, dtype=np.int64)
            order = np.zeros(0, dtype=np.int64)
        self.order = order
        (self.sorted_points, self.sorted_velocities, self.sorted_normals, vol,
         self.sorted_friction) = _gather_sorted(order, x, self.velocities, self.normals,
                                                self.volumes, self.friction)
        self.sorted_volumes = vol
        self.sorted_mass = self.rest_density * vol
        self.sorted_friction_volumes = vol * self.sorted_friction
        self.origin = lo
        self.dims = dims
        self.start = start
        self.mask = self._reach_mask(lo, dims) if m else np.zeros(1, dtype=np.bool_)

    def _reach_mask(self, lo, dims):
        """:func:`boundary_reach_mask` of all particles: the unmoved ones' kept from the last
        sort on the same grid, the moved ones' marked on a copy (the same cells either way)."""
        if self._moved_idx.size == 0:
            return boundary_reach_mask(self.points, lo, self.cell, dims)
        key = (tuple(lo), tuple(dims), self._moved_idx.size)
        if key != self._static_key:
            self._static_mask = boundary_reach_mask(
                np.ascontiguousarray(self.points[~self._moved]), lo, self.cell, dims)
            self._static_key = key
        mask = self._static_mask.copy()
        mark_boundary_reach(mask, np.ascontiguousarray(self.points[self._moved_idx]), lo,
                            self.cell, dims)
        return mask

    def arrays(self) -> tuple:
        """The sorted boundary as the solvers take it: ``(points, start, origin, cell, dims, mask,
        volumes, mass, friction_volumes, normals, velocities, moving)``."""
        return (self.sorted_points, self.start, self.origin, self.cell, self.dims, self.mask,
                self.sorted_volumes, self.sorted_mass, self.sorted_friction_volumes,
                self.sorted_normals, self.sorted_velocities, self.moving)

    def move(self, points: ArrayLike | None = None, velocities: ArrayLike | None = None,
             volumes: ArrayLike | None = None, indices: ArrayLike | None = None,
             normals: ArrayLike | None = None) -> None:
        """Set new positions, velocities, volumes and/or normals of (some of) the boundary
        particles.

        Parameters
        ----------
        points : (K, 3) array_like, optional
            New positions (m) of the particles ``indices`` (all particles when ``indices`` is
            None, then ``K = M``).
        velocities : (K, 3) array_like, optional
            Their velocities (m/s); the fluid sees the boundary move with them during the next
            step (no-penetration and no-slip relative to the boundary).
        volumes : (K,) array_like, optional
            Their volumes (m^3), > 0, e.g. :func:`filters.sph.boundary.boundary_volumes` of a
            deformed surface.
        indices : (K,) array_like of int, optional
            Which particles, in the order of the ``BoundaryParticles`` the liquid was built with.
        normals : (K, 3) array_like, optional
            Their unit normals (a rotated body's), which tell its walls apart
            (:mod:`filters.sph.dfsph`); unit vectors or zeros.

        Raises
        ------
        ValueError
            For arrays of the wrong shape, non-finite values, volumes <= 0, normals that are
            neither unit nor zero, or indices out of range, before anything changes.
        """
        m = self.n_points
        if indices is None:
            sel = np.arange(m)
        else:
            sel = np.asarray(indices)
            if sel.ndim != 1 or not np.issubdtype(sel.dtype, np.integer):
                raise ValueError("indices must be a 1-D integer array")
            if sel.size and (sel.min() < 0 or sel.max() >= m):
                raise ValueError(f"indices must be in [0, {m - 1}]")
        k = sel.shape[0]
        new = {}
        for name, value, shape in (("points", points, (k, 3)), ("velocities", velocities, (k, 3)),
                                   ("volumes", volumes, (k,)), ("normals", normals, (k, 3))):
            if value is None:
                continue
            a = np.asarray(value, dtype=np.float64)
            if a.shape != shape or not np.isfinite(a).all():
                raise ValueError(f"{name} must be a finite array of shape {shape}, "
                                 f"got {a.shape}")
            if name == "volumes" and not (a > 0).all():
                raise ValueError("volumes must be > 0 (m^3)")
            if name == "normals":
                length = np.sqrt((a * a).sum(axis=1))
                if np.abs(length[length > 0] - 1.0).max(initial=0.0) > 1e-6:
                    raise ValueError("normals must be unit vectors (or zero where unknown)")
            new[name] = a
        for name, a in new.items():
            full = getattr(self, name).copy()
            full[sel] = a
            full.setflags(write=False)
            setattr(self, name, full)
        if "velocities" in new and np.any(new["velocities"] != 0.0):
            self.moving = True
        if "points" in new and not self._moved[sel].all():
            self._moved[sel] = True
            self._moved_idx = np.flatnonzero(self._moved)
        if new:
            self._sort()


@njit(cache=True)
def _gather_sorted(order, points, velocities, normals, volumes, friction):
    """``points[order]``, ``velocities[order]``, ``normals[order]``, ``volumes[order]``,
    ``friction[order]`` in one pass (new contiguous arrays)."""
    m = order.shape[0]
    sp = np.empty((m, 3))
    sv = np.empty((m, 3))
    sn = np.empty((m, 3))
    vol = np.empty(m)
    fr = np.empty(m)
    for k in range(m):
        i = order[k]
        for c in range(3):
            sp[k, c] = points[i, c]
            sv[k, c] = velocities[i, c]
            sn[k, c] = normals[i, c]
        vol[k] = volumes[i]
        fr[k] = friction[i]
    return sp, sv, sn, vol, fr


@njit(parallel=True, cache=True, error_model="numpy")
def _forces(sel, xb, vb, volb, fvolb, nrmb, x, start, origin, cell, dims, mass, h, kind, ptot,
            pw, ncl, cn, vv, nu_b, out):
    n = x.shape[0]
    h2 = h * h
    eps = 0.01 * 0.25 * h2
    inv = 1.0 / cell
    for k in prange(sel.shape[0]):
        b = sel[k]
        qx = xb[b, 0]
        qy = xb[b, 1]
        qz = xb[b, 2]
        fx = 0.0
        fy = 0.0
        fz = 0.0
        if n > 0:
            x0, x1 = cell_range(qx, origin[0], inv, dims[0])
            y0, y1 = cell_range(qy, origin[1], inv, dims[1])
            z0, z1 = cell_range(qz, origin[2], inv, dims[2])
            for iz in range(z0, z1 + 1):
                for iy in range(y0, y1 + 1):
                    row = (iz * dims[1] + iy) * dims[0]
                    for i in range(start[row + x0], start[row + x1 + 1]):
                        dx = x[i, 0] - qx
                        dy = x[i, 1] - qy
                        dz = x[i, 2] - qz
                        r2 = dx * dx + dy * dy + dz * dz
                        if r2 >= h2 or r2 == 0.0:
                            continue
                        r = math.sqrt(r2)
                        g = kernel_dw(kind, r, h) / r  # grad_i W_ib = g (x_i - x_b)
                        p = ptot[i]
                        if ncl[i] > 0:
                            p += pw[i, 0]
                            if ncl[i] > 1:  # the wall b was counted in (same rule as the pass)
                                mx, my, mz = wall_key(nrmb[b, 0], nrmb[b, 1], nrmb[b, 2],
                                                      dx, dy, dz)
                                w = wall_of(i, mx, my, mz, ncl[i], cn)
                                p += pw[i, min(w, ncl[i] - 1)]
                        c = mass * p * volb[b] * g
                        if nu_b > 0.0 and fvolb[b] > 0.0:
                            u = ((vv[i, 0] - vb[b, 0]) * dx + (vv[i, 1] - vb[b, 1]) * dy
                                 + (vv[i, 2] - vb[b, 2]) * dz)
                            c -= mass * 10.0 * nu_b * fvolb[b] * g * u / (r2 + eps)
                        fx += c * dx
                        fy += c * dy
                        fz += c * dz
        out[k, 0] = fx
        out[k, 1] = fy
        out[k, 2] = fz


def boundary_forces(record: dict, indices: ArrayLike | None = None) -> np.ndarray:
    """Force (N) the fluid exerted on boundary particles during the step described by ``record``.

    For each pair of a fluid particle ``i`` and a boundary particle ``b`` the fluid's pressure
    acceleration of ``i`` is ``-(pi_i + pi_w,ib) V_b grad W_ib`` (the density and divergence
    solves' pressures mirrored onto the boundary, Akinci et al. 2012, plus the wall pressure of
    the wall constraint, :mod:`filters.sph.dfsph`) and its viscous acceleration the boundary
    term of Weiler et al. (2018)'s implicit viscosity; the boundary particle takes the opposite
    of ``m_i`` times their sum (Newton's third law), so the forces on all boundary particles and
    on the fluid add up to zero.

    Parameters
    ----------
    record : dict
        What the liquid kept of its last step (positions, pressures, grid, boundary); see
        :meth:`filters.sph.SPHLiquid.boundary_forces`.
    indices : array_like of int, optional
        Boundary particles (in the caller's order); default all.

    Returns
    -------
    (K, 3) float64
    """
    bset = record["boundary"]
    m = bset["order"].shape[0]
    if indices is None:
        want = np.arange(m)
    else:
        want = np.asarray(indices)
        if want.ndim != 1 or not np.issubdtype(want.dtype, np.integer):
            raise ValueError("indices must be a 1-D integer array")
        if want.size and (want.min() < 0 or want.max() >= m):
            raise ValueError(f"indices must be in [0, {m - 1}]")
    where = np.empty(m, dtype=np.int64)
    where[bset["order"]] = np.arange(m)
    sel = np.ascontiguousarray(where[want])
    out = np.zeros((sel.shape[0], 3))
    if sel.size:
        _forces(sel, bset["points"], bset["velocities"], bset["volumes"],
                bset["friction_volumes"], bset["normals"], record["positions"],
                record["start"], record["origin"], record["cell"], record["dims"],
                record["mass"], record["support"], record["kind"], record["pressure"],
                record["wall_pressure"], record["clusters"], record["cluster_normals"],
                record["velocities"], record["boundary_viscosity"], out)
    return out
