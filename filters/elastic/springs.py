"""Damped springs: forces, energies and analytic 3x3 Jacobians, and a spring system for the integrators.

A spring joins particles ``a`` and ``b`` with rest length ``L`` and stiffness ``k``.  With
``d = x_a - x_b``, ``l = |d|`` and ``u = d / l`` the force on ``a`` is the seed's

.. math::  f_a = -k (l / L - 1) u \\qquad (L > 0),

i.e. ``k`` is a *strain* stiffness in newtons, so a chain of ``n`` springs of total length ``n L``
has the same overall stiffness ``k / (n L)`` at every resolution.  A zero-rest-length spring
(``L = 0``) is the linear spring ``f_a = -k d`` with ``k`` in N/m.  Internally both are written
``f_a = -k_e (l - L) u`` with the *effective* stiffness ``k_e = k / L`` (N/m) or ``k``.

Damping (``c`` in N s/m), with ``w = v_a - v_b``:

* ``"axial"`` (the seed's): ``f_a = -c (w . u) u`` — damps stretching only;
* ``"relative"``: ``f_a = -c w`` (the simplified form);
* a per-particle *drag* ``f_i = -c_drag v_i`` (the simplest form) lives in :class:`SpringSystem`.

The force on ``b`` is always ``-f_a``, so linear momentum is conserved to round-off.

Jacobians (Baraff & Witkin 1998, "Large steps in cloth simulation", SIGGRAPH):
``J_x = df_a/dx_a = -k_e [u u^T + (1 - L/l)(I - u u^T)]`` plus, for axial damping,
``-(c/l) [u w^T P + (w . u) P]`` with ``P = I - u u^T``; ``J_v = df_a/dv_a = -c u u^T`` (axial) or
``-c I`` (relative).  ``df_a/dx_b = -J_x`` and so on.  For a compressed spring (``l < L``) the
transverse term ``(1 - L/l) < 0`` makes ``-J_x`` indefinite; the *definite* Jacobians clamp it to 0
(Choi & Ko 2002, "Stable but responsive cloth"), which keeps the implicit system matrix SPD.
"""

from __future__ import annotations

import math
from contextlib import contextmanager

import numba
import numpy as np
from numba import njit, prange

from ..validation import check_choice, check_finite_vector, check_points, check_range

__all__ = [
    "DAMPING_MODES",
    "effective_stiffness",
    "spring_forces",
    "spring_energy",
    "spring_jacobians",
    "SpringSystem",
    "SpringOperator",
]

#: Spring damping models: 0 = axial (seed), 1 = relative velocity.
DAMPING_MODES = ("axial", "relative")

_EPS = 1e-12

#: Below this many springs the kernels run on one thread: a parallel region costs more than the
#: work, and on a busy machine a descheduled worker thread stalls every region.
PARALLEL_MIN_SPRINGS = 50_000

#: The fused symplectic Euler step is one parallel region of ~10 ns per spring, so it pays off
#: from fewer springs (64x64 cloth, 23,938 springs: 235 us serial, 160-175 us on 2 threads,
#: benchmarks/results/springs.json).  On a machine shared with other busy processes a parallel
#: region can stall: set this above the spring count to force the serial kernel.
PARALLEL_MIN_SPRINGS_EXPLICIT = 8_192


@contextmanager
def _threads(work):
    """Run the enclosed Numba parallel kernels on one thread when ``work`` is small."""
    if work >= PARALLEL_MIN_SPRINGS:
        yield
        return
    previous = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(previous)


# ---------------------------------------------------------------------------------------------
# Per-spring kernels
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _spring_force3(xa, xb, va, vb, ke, rest, c, mode):
    """Force (f0, f1, f2) on end ``a`` of one spring."""
    d0 = xa[0] - xb[0]
    d1 = xa[1] - xb[1]
    d2 = xa[2] - xb[2]
    w0 = va[0] - vb[0]
    w1 = va[1] - vb[1]
    w2 = va[2] - vb[2]
    l = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    f0 = 0.0
    f1 = 0.0
    f2 = 0.0
    if rest == 0.0:
        f0 = -ke * d0
        f1 = -ke * d1
        f2 = -ke * d2
    if l > _EPS:
        inv = 1.0 / l
        u0 = d0 * inv
        u1 = d1 * inv
        u2 = d2 * inv
        s = 0.0
        if rest > 0.0:
            s = -ke * (l - rest)
        if mode == 0:
            s -= c * (w0 * u0 + w1 * u1 + w2 * u2)
        f0 += s * u0
        f1 += s * u1
        f2 += s * u2
    if mode == 1:
        f0 -= c * w0
        f1 -= c * w1
        f2 -= c * w2
    return f0, f1, f2


@njit(cache=True, inline="always")
def _spring_force(xa, xb, va, vb, ke, rest, c, mode, out):
    """Force on end ``a`` of one spring into ``out`` (3,)."""
    f0, f1, f2 = _spring_force3(xa, xb, va, vb, ke, rest, c, mode)
    out[0] = f0
    out[1] = f1
    out[2] = f2


@njit(cache=True)
def _symplectic_serial(x, v, pairs, ke, rest, c, mode, masses, inv_mass, gravity, drag, h, f):
    """Serial symplectic Euler step: scatter spring forces (no races on one thread), integrate."""
    n = x.shape[0]
    for i in range(n):
        f[i, 0] = masses[i] * gravity[0] - drag * v[i, 0]
        f[i, 1] = masses[i] * gravity[1] - drag * v[i, 1]
        f[i, 2] = masses[i] * gravity[2] - drag * v[i, 2]
    for s in range(pairs.shape[0]):
        a = pairs[s, 0]
        b = pairs[s, 1]
        f0, f1, f2 = _spring_force3(x[a], x[b], v[a], v[b], ke[s], rest[s], c[s], mode)
        f[a, 0] += f0
        f[a, 1] += f1
        f[a, 2] += f2
        f[b, 0] -= f0
        f[b, 1] -= f1
        f[b, 2] -= f2
    vmax = 0.0
    for i in range(n):
        w = h * inv_mass[i]
        v[i, 0] += w * f[i, 0]
        v[i, 1] += w * f[i, 1]
        v[i, 2] += w * f[i, 2]
        x[i, 0] += h * v[i, 0]
        x[i, 1] += h * v[i, 1]
        x[i, 2] += h * v[i, 2]
        vmax = max(vmax, v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1] + v[i, 2] * v[i, 2])
    return math.sqrt(vmax)


@njit(parallel=True, cache=True)
def _per_spring_forces(x, v, pairs, ke, rest, c, mode, fs):
    for s in prange(pairs.shape[0]):
        _spring_force(x[pairs[s, 0]], x[pairs[s, 1]], v[pairs[s, 0]], v[pairs[s, 1]],
                      ke[s], rest[s], c[s], mode, fs[s])


@njit(cache=True, inline="always")
def _add_incident(fs, inc_ptr, inc_spring, inc_sign, i, a0, a1, a2):
    """``(a0, a1, a2) + sum of sign * fs[s]`` over the springs incident to particle ``i``."""
    for p in range(inc_ptr[i], inc_ptr[i + 1]):
        s = inc_spring[p]
        sg = inc_sign[p]
        a0 += sg * fs[s, 0]
        a1 += sg * fs[s, 1]
        a2 += sg * fs[s, 2]
    return a0, a1, a2


@njit(parallel=True, cache=True)
def _gather(fs, inc_ptr, inc_spring, inc_sign, f):
    """f[i] = sum over incident springs of sign * fs[s] (no races: one thread per particle)."""
    for i in prange(f.shape[0]):
        a0, a1, a2 = _add_incident(fs, inc_ptr, inc_spring, inc_sign, i, 0.0, 0.0, 0.0)
        f[i, 0] = a0
        f[i, 1] = a1
        f[i, 2] = a2


@njit(parallel=True, cache=True)
def _total_forces(x, v, pairs, ke, rest, c, mode, inc_ptr, inc_spring, inc_sign, masses,
                  gravity, drag, fs, f):
    """Spring + gravity + drag forces on every particle into ``f`` (N, 3)."""
    for s in prange(pairs.shape[0]):
        _spring_force(x[pairs[s, 0]], x[pairs[s, 1]], v[pairs[s, 0]], v[pairs[s, 1]],
                      ke[s], rest[s], c[s], mode, fs[s])
    for i in prange(f.shape[0]):
        a0 = masses[i] * gravity[0] - drag * v[i, 0]
        a1 = masses[i] * gravity[1] - drag * v[i, 1]
        a2 = masses[i] * gravity[2] - drag * v[i, 2]
        a0, a1, a2 = _add_incident(fs, inc_ptr, inc_spring, inc_sign, i, a0, a1, a2)
        f[i, 0] = a0
        f[i, 1] = a1
        f[i, 2] = a2


@njit(parallel=True, cache=True)
def _symplectic_kernel(x, v, pairs, ke, rest, c, mode, inc_ptr, inc_spring, inc_sign, masses,
                       inv_mass, gravity, drag, h, fs):
    """One symplectic Euler step in place: v += h f(x, v) / m; x += h v (pinned: inv_mass 0)."""
    for s in prange(pairs.shape[0]):
        _spring_force(x[pairs[s, 0]], x[pairs[s, 1]], v[pairs[s, 0]], v[pairs[s, 1]],
                      ke[s], rest[s], c[s], mode, fs[s])
    vmax = 0.0
    for i in prange(x.shape[0]):
        a0 = masses[i] * gravity[0] - drag * v[i, 0]
        a1 = masses[i] * gravity[1] - drag * v[i, 1]
        a2 = masses[i] * gravity[2] - drag * v[i, 2]
        a0, a1, a2 = _add_incident(fs, inc_ptr, inc_spring, inc_sign, i, a0, a1, a2)
        w = h * inv_mass[i]
        v[i, 0] += w * a0
        v[i, 1] += w * a1
        v[i, 2] += w * a2
        x[i, 0] += h * v[i, 0]
        x[i, 1] += h * v[i, 1]
        x[i, 2] += h * v[i, 2]
        sp = v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1] + v[i, 2] * v[i, 2]
        vmax = max(vmax, sp)
    return math.sqrt(vmax)


@njit(cache=True, inline="always")
def _spring_energy(x, pairs, ke, rest, s):
    """Elastic energy (J) of spring ``s``: ``k_e (|x_ab| - L)^2 / 2`` (``k_e |x_ab|^2 / 2`` at
    zero rest length)."""
    a = pairs[s, 0]
    b = pairs[s, 1]
    d0 = x[a, 0] - x[b, 0]
    d1 = x[a, 1] - x[b, 1]
    d2 = x[a, 2] - x[b, 2]
    l2 = d0 * d0 + d1 * d1 + d2 * d2
    if rest[s] == 0.0:
        return 0.5 * ke[s] * l2
    dl = math.sqrt(l2) - rest[s]
    return 0.5 * ke[s] * dl * dl


@njit(cache=True)
def _elastic_energy_serial(x, pairs, ke, rest):
    """Serial :func:`_elastic_energy` (below :data:`PARALLEL_MIN_SPRINGS` springs)."""
    e = 0.0
    for s in range(pairs.shape[0]):
        e += _spring_energy(x, pairs, ke, rest, s)
    return e


@njit(cache=True)
def _point_energies(x, v, masses, gravity):
    """(kinetic, gravitational) energy (J) of point masses: serial Numba instead of NumPy's
    BLAS calls (``x @ g``, ``dot``), whose threads stall on a busy machine."""
    kinetic = 0.0
    potential = 0.0
    for i in range(x.shape[0]):
        kinetic += masses[i] * (v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1] + v[i, 2] * v[i, 2])
        potential -= masses[i] * (x[i, 0] * gravity[0] + x[i, 1] * gravity[1]
                                  + x[i, 2] * gravity[2])
    return 0.5 * kinetic, potential


@njit(parallel=True, cache=True)
def _elastic_energy(x, pairs, ke, rest):
    e = 0.0
    for s in prange(pairs.shape[0]):
        e += _spring_energy(x, pairs, ke, rest, s)
    return e


@njit(parallel=True, cache=True)
def _jacobian_blocks(x, v, pairs, ke, rest, c, mode, definite, with_damping_dx, jx, jv):
    """Per-spring ``J_x = df_a/dx_a`` and ``J_v = df_a/dv_a`` (S, 3, 3)."""
    for s in prange(pairs.shape[0]):
        a = pairs[s, 0]
        b = pairs[s, 1]
        d = np.empty(3)
        w = np.empty(3)
        for k in range(3):
            d[k] = x[a, k] - x[b, k]
            w[k] = v[a, k] - v[b, k]
        l = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        for p in range(3):
            for q in range(3):
                jx[s, p, q] = 0.0
                jv[s, p, q] = 0.0
        if rest[s] == 0.0:
            for p in range(3):
                jx[s, p, p] = -ke[s]
        if mode == 1:
            for p in range(3):
                jv[s, p, p] = -c[s]
        if l <= _EPS:
            continue
        u = d / l
        if rest[s] > 0.0:
            t = 1.0 - rest[s] / l
            if definite and t < 0.0:
                t = 0.0
            for p in range(3):
                for q in range(3):
                    uu = u[p] * u[q]
                    jx[s, p, q] += -ke[s] * (uu + t * ((1.0 if p == q else 0.0) - uu))
        if mode == 0:
            for p in range(3):
                for q in range(3):
                    jv[s, p, q] = -c[s] * u[p] * u[q]
            if with_damping_dx and c[s] != 0.0:
                wu = w[0] * u[0] + w[1] * u[1] + w[2] * u[2]
                # w^T P = w - (w.u) u^T
                for p in range(3):
                    for q in range(3):
                        pq = (1.0 if p == q else 0.0) - u[p] * u[q]
                        wp = w[q] - wu * u[q]
                        jx[s, p, q] += -(c[s] / l) * (u[p] * wp + wu * pq)


# ---------------------------------------------------------------------------------------------
# Array-level public functions
# ---------------------------------------------------------------------------------------------
def _check_springs(pairs, n_points):
    pairs = np.ascontiguousarray(pairs, dtype=np.int64)
    if pairs.ndim != 2 or pairs.shape[1] != 2:
        raise ValueError(f"springs must have shape (S, 2), got {pairs.shape}")
    if pairs.size and (pairs.min() < 0 or pairs.max() >= n_points):
        raise ValueError(f"springs must index particles in [0, {n_points - 1}]")
    if pairs.size and np.any(pairs[:, 0] == pairs[:, 1]):
        raise ValueError("springs must join two different particles (found a spring i-i)")
    return pairs


def _per_spring(name, value, n, low=0.0):
    arr = np.ascontiguousarray(np.broadcast_to(np.asarray(value, dtype=np.float64), (n,)))
    if not np.isfinite(arr).all() or (arr.size and arr.min() < low):
        raise ValueError(f"{name} must be finite and >= {low:g} for every spring")
    return arr.copy()


def effective_stiffness(stiffness, rest_lengths):
    """Effective spring constants ``k_e`` (N/m): ``k / L`` for ``L > 0``, ``k`` for ``L == 0``.

    Parameters
    ----------
    stiffness : (S,) array_like
        Seed-form strain stiffness ``k`` (N) or, for zero rest length, spring constant (N/m).
    rest_lengths : (S,) array_like
        Rest lengths ``L`` (m), >= 0.

    Returns
    -------
    (S,) float64 array
    """
    k = np.asarray(stiffness, dtype=np.float64)
    L = np.asarray(rest_lengths, dtype=np.float64)
    return np.where(L > 0.0, k / np.where(L > 0.0, L, 1.0), k)


def _prep(positions, velocities, springs, rest_lengths, stiffness, damping, damping_mode):
    x = check_points("positions", positions)
    v = np.zeros_like(x) if velocities is None else check_points("velocities", velocities)
    if v.shape != x.shape:
        raise ValueError("velocities must have the same shape as positions")
    pairs = _check_springs(springs, x.shape[0])
    s = pairs.shape[0]
    rest = _per_spring("rest_lengths", rest_lengths, s)
    k = _per_spring("stiffness", stiffness, s)
    c = _per_spring("damping", damping, s)
    mode = DAMPING_MODES.index(check_choice("damping_mode", damping_mode, DAMPING_MODES))
    return x, v, pairs, rest, effective_stiffness(k, rest), c, mode


def spring_forces(positions, springs, rest_lengths, stiffness, velocities=None, damping=0.0,
                  damping_mode="axial"):
    """Per-spring force on the first end of every spring.

    Parameters
    ----------
    positions : (N, 3) array_like
        Particle positions (m).
    springs : (S, 2) int array_like
        Particle indices ``(a, b)`` of every spring.
    rest_lengths : (S,) or scalar
        Rest lengths (m), >= 0.
    stiffness : (S,) or scalar
        Seed-form stiffness ``k`` (N) (N/m for zero rest length), >= 0.
    velocities : (N, 3) array_like, optional
        Particle velocities (m/s), for damping.
    damping : (S,) or scalar
        Damping coefficient ``c`` (N s/m), >= 0.
    damping_mode : {"axial", "relative"}
        See the module docstring.

    Returns
    -------
    (S, 3) float64 array
        Force (N) on particle ``a``; the force on ``b`` is its negative.
    """
    x, v, pairs, rest, ke, c, mode = _prep(positions, velocities, springs, rest_lengths,
                                           stiffness, damping, damping_mode)
    fs = np.empty((pairs.shape[0], 3))
    _per_spring_forces(x, v, pairs, ke, rest, c, mode, fs)
    return fs


def spring_energy(positions, springs, rest_lengths, stiffness):
    """Elastic energy ``sum 0.5 k_e (l - L)^2`` (J) of a set of springs (arguments as in
    :func:`spring_forces`)."""
    x, _, pairs, rest, ke, _, _ = _prep(positions, None, springs, rest_lengths, stiffness, 0.0,
                                        "axial")
    return float(_elastic_energy(x, pairs, ke, rest))


def spring_jacobians(positions, springs, rest_lengths, stiffness, velocities=None, damping=0.0,
                     damping_mode="axial", *, definite=False, damping_dx=True):
    """Analytic Jacobians of the force on the first end of every spring.

    Parameters
    ----------
    positions, springs, rest_lengths, stiffness, velocities, damping, damping_mode
        As in :func:`spring_forces`.
    definite : bool
        Clamp the transverse term of compressed springs to zero so that ``-J_x`` is positive
        semi-definite (for implicit solves).  ``False`` gives the exact derivative.
    damping_dx : bool
        Include the (non-symmetric) derivative of axial damping with respect to positions.

    Returns
    -------
    jx : (S, 3, 3) float64 array
        ``df_a/dx_a`` (N/m); ``df_a/dx_b = -jx``, ``df_b/dx_b = jx``.
    jv : (S, 3, 3) float64 array
        ``df_a/dv_a`` (N s/m); ``df_a/dv_b = -jv``.
    """
    x, v, pairs, rest, ke, c, mode = _prep(positions, velocities, springs, rest_lengths,
                                           stiffness, damping, damping_mode)
    s = pairs.shape[0]
    jx = np.empty((s, 3, 3))
    jv = np.empty((s, 3, 3))
    _jacobian_blocks(x, v, pairs, ke, rest, c, mode, bool(definite), bool(damping_dx), jx, jv)
    return jx, jv


# ---------------------------------------------------------------------------------------------
# Block-sparse pattern and assembly
# ---------------------------------------------------------------------------------------------
def _incidence(pairs, n):
    """Particle -> incident springs in CSR form: (ptr (N+1,), spring (2S,), sign (2S,), other)."""
    s = pairs.shape[0]
    nodes = np.concatenate([pairs[:, 0], pairs[:, 1]])
    springs = np.concatenate([np.arange(s), np.arange(s)])
    signs = np.concatenate([np.ones(s), -np.ones(s)])
    others = np.concatenate([pairs[:, 1], pairs[:, 0]])
    order = np.argsort(nodes, kind="stable")
    ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(nodes, minlength=n), out=ptr[1:])
    return (ptr, springs[order].astype(np.int64), signs[order].astype(np.float64),
            others[order].astype(np.int64))


@njit(parallel=True, cache=True)
def _assemble(jx, jv, inc_ptr, inc_spring, inc_other, inc_slot, diag_slot, bptr, masses,
              pinned, h, drag, data):
    """Fill CSR data of ``H = M/h^2 + K + C/h`` (``K = -J_x``, ``C = -J_v`` per spring, drag on
    the diagonal); pinned particles' rows and columns are replaced by the identity."""
    inv_h2 = 1.0 / (h * h)
    inv_h = 1.0 / h
    for i in prange(masses.shape[0]):
        b0 = bptr[i]
        nb = bptr[i + 1] - b0
        base = 9 * b0
        for r in range(3):
            for q in range(3 * nb):
                data[base + 3 * r * nb + q] = 0.0
        dpos = diag_slot[i] - b0
        if pinned[i]:
            for r in range(3):
                data[base + 3 * r * nb + 3 * dpos + r] = 1.0
            continue
        for r in range(3):
            data[base + 3 * r * nb + 3 * dpos + r] = masses[i] * inv_h2 + drag * inv_h
        for p in range(inc_ptr[i], inc_ptr[i + 1]):
            s = inc_spring[p]
            o = inc_other[p]
            opos = inc_slot[p] - b0
            for r in range(3):
                for q in range(3):
                    val = -jx[s, r, q] - jv[s, r, q] * inv_h
                    data[base + 3 * r * nb + 3 * dpos + q] += val
                    if not pinned[o]:
                        data[base + 3 * r * nb + 3 * opos + q] -= val


@njit(parallel=True, cache=True)
def _add_diagonal_blocks(blocks, diag_slot, bptr, pinned, data):
    for i in prange(blocks.shape[0]):
        if pinned[i]:
            continue
        b0 = bptr[i]
        nb = bptr[i + 1] - b0
        dpos = diag_slot[i] - b0
        for r in range(3):
            for q in range(3):
                data[9 * b0 + 3 * r * nb + 3 * dpos + q] += blocks[i, r, q]


# ---------------------------------------------------------------------------------------------
# Matrix-free implicit operator
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _operator_coefficients(x, xdir, pairs, ke, rest, c, mode, h, blocks):
    """Per-spring symmetric blocks ``K_s + C_s / h`` (6 entries: xx, xy, xz, yy, yz, zz).

    Equal to the blocks that :meth:`SpringSystem.system_matrix` assembles (definite ``K``,
    compressed springs clamped; no position derivative of the damping force):
    ``alpha u u^T + beta I + gamma w w^T`` with ``u`` the direction at ``x`` and ``w`` the frozen
    damping direction at ``xdir``; for ``L > 0``, ``K_s = k_e [u u^T + t (I - u u^T)]`` with
    ``t = max(1 - L/l, 0)``, i.e. ``alpha = k_e (1 - t)``, ``beta = k_e t``; for ``L = 0``,
    ``K_s = k_e I``; axial damping ``C_s = c w w^T``, relative damping ``C_s = c I``.
    Serial: one pass over 24k springs costs ~0.1 ms, less than a parallel region's start-up on a
    busy machine.
    """
    inv_h = 1.0 / h
    for s in range(pairs.shape[0]):
        a = pairs[s, 0]
        b = pairs[s, 1]
        alpha = 0.0
        beta = 0.0
        gamma = 0.0
        u0 = 0.0
        u1 = 0.0
        u2 = 0.0
        w0 = 0.0
        w1 = 0.0
        w2 = 0.0
        if rest[s] == 0.0:
            beta = ke[s]
        else:
            d0 = x[a, 0] - x[b, 0]
            d1 = x[a, 1] - x[b, 1]
            d2 = x[a, 2] - x[b, 2]
            l = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            if l > _EPS:
                inv_l = 1.0 / l
                t = 1.0 - rest[s] * inv_l
                if t < 0.0:
                    t = 0.0
                u0 = d0 * inv_l
                u1 = d1 * inv_l
                u2 = d2 * inv_l
                alpha = ke[s] * (1.0 - t)
                beta = ke[s] * t
        if mode == 1:
            beta += c[s] * inv_h
        elif c[s] != 0.0:
            e0 = xdir[a, 0] - xdir[b, 0]
            e1 = xdir[a, 1] - xdir[b, 1]
            e2 = xdir[a, 2] - xdir[b, 2]
            le = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
            if le > _EPS:
                w0 = e0 / le
                w1 = e1 / le
                w2 = e2 / le
                gamma = c[s] * inv_h
        blocks[s, 0] = alpha * u0 * u0 + gamma * w0 * w0 + beta
        blocks[s, 1] = alpha * u0 * u1 + gamma * w0 * w1
        blocks[s, 2] = alpha * u0 * u2 + gamma * w0 * w2
        blocks[s, 3] = alpha * u1 * u1 + gamma * w1 * w1 + beta
        blocks[s, 4] = alpha * u1 * u2 + gamma * w1 * w2
        blocks[s, 5] = alpha * u2 * u2 + gamma * w2 * w2 + beta


@njit(cache=True)
def _operator_diagonal(masses, pinned, h, drag, contact_blocks, diag):
    """Particle diagonal blocks ``(m/h^2 + drag/h) I`` (+ contact blocks); identity if pinned."""
    dm = drag / h
    with_contacts = contact_blocks.shape[0] == masses.shape[0]
    for i in range(masses.shape[0]):
        for r in range(3):
            for q in range(3):
                diag[i, r, q] = 0.0
        if pinned[i]:
            for r in range(3):
                diag[i, r, r] = 1.0
            continue
        for r in range(3):
            diag[i, r, r] = masses[i] / (h * h) + dm
        if with_contacts:
            for r in range(3):
                for q in range(3):
                    diag[i, r, q] += contact_blocks[i, r, q]


@njit(cache=True)
def _operator_matvec(pairs, free, blocks, diag, p, y):
    """``y = H p`` for the matrix-free operator (vectors (N, 3)); returns ``p . H p``."""
    acc = 0.0
    for i in range(p.shape[0]):
        p0 = p[i, 0]
        p1 = p[i, 1]
        p2 = p[i, 2]
        y0 = diag[i, 0, 0] * p0 + diag[i, 0, 1] * p1 + diag[i, 0, 2] * p2
        y1 = diag[i, 1, 0] * p0 + diag[i, 1, 1] * p1 + diag[i, 1, 2] * p2
        y2 = diag[i, 2, 0] * p0 + diag[i, 2, 1] * p1 + diag[i, 2, 2] * p2
        y[i, 0] = y0
        y[i, 1] = y1
        y[i, 2] = y2
        acc += p0 * y0 + p1 * y1 + p2 * y2
    for s in range(pairs.shape[0]):
        a = pairs[s, 0]
        b = pairs[s, 1]
        fa = free[a]
        fb = free[b]
        d0 = fa * p[a, 0] - fb * p[b, 0]
        d1 = fa * p[a, 1] - fb * p[b, 1]
        d2 = fa * p[a, 2] - fb * p[b, 2]
        k0 = blocks[s, 0] * d0 + blocks[s, 1] * d1 + blocks[s, 2] * d2
        k1 = blocks[s, 1] * d0 + blocks[s, 3] * d1 + blocks[s, 4] * d2
        k2 = blocks[s, 2] * d0 + blocks[s, 4] * d1 + blocks[s, 5] * d2
        acc += d0 * k0 + d1 * k1 + d2 * k2
        y[a, 0] += fa * k0
        y[a, 1] += fa * k1
        y[a, 2] += fa * k2
        y[b, 0] -= fb * k0
        y[b, 1] -= fb * k1
        y[b, 2] -= fb * k2
    return acc


class SpringOperator:
    """The implicit system matrix ``H = M/h^2 + K + C/h`` of a :class:`SpringSystem`, matrix-free.

    Per spring ``s`` joining ``a`` and ``b`` the symmetric block ``K_s + C_s/h`` (from the
    Baraff & Witkin 1998 spring Jacobians) is stored as its 6 distinct entries, and
    ``H p = D p + sum_s [e_a - e_b] (K_s + C_s/h) (p_a - p_b)`` with ``D`` the particle diagonal
    blocks.  Rows and columns of pinned particles are the identity (``free`` masks them).  Equal
    to :meth:`SpringSystem.system_matrix` (same SPD matrix) but 6 numbers per spring instead of
    ~39 CSR non-zeros with their column indices: a product costs ~0.1 ms instead of ~0.5 ms on
    the 64x64 benchmark cloth.

    Attributes
    ----------
    pairs : (S, 2) int64 array
        Spring end points.
    free : (N,) float64 array
        1 for free particles, 0 for pinned ones.
    blocks : (S, 6) float64 array
        Entries xx, xy, xz, yy, yz, zz of ``K_s + C_s/h`` (N/m).
    diag : (N, 3, 3) float64 array
        Particle blocks ``(m/h^2 + drag/h) I`` plus contact Hessian blocks (N/m); identity if
        pinned.
    lower, upper : tuple of 3 int64 arrays
        Particle ``i`` -> incident springs whose other end ``j`` is ``< i`` (``lower``) or
        ``> i`` (``upper``), in CSR form ``(ptr (N+1,), spring, other)``, for the forward and
        backward Gauss-Seidel sweeps.
    upper_ordered : bool
        True when the springs are in upper-incidence order (``pairs[:, 0] < pairs[:, 1]``,
        sorted by ``pairs[:, 0]``), so that ``upper[1]`` is ``arange(S)`` and the SSOR sweeps
        of :func:`filters.integrators.pcg_operator` stream ``blocks`` in place.
        :meth:`SpringSystem.implicit_operator` builds its operator in this order.
    """

    def __init__(self, pairs, free, blocks, diag, inc_ptr, inc_spring, inc_other):
        self.pairs = pairs
        self.free = free
        self.blocks = blocks
        self.diag = diag
        n = diag.shape[0]
        node = np.repeat(np.arange(n), np.diff(inc_ptr))
        halves = []
        for keep in (inc_other < node, inc_other > node):
            ptr = np.zeros(n + 1, dtype=np.int64)
            np.cumsum(np.bincount(node[keep], minlength=n), out=ptr[1:])
            halves.append((ptr, np.ascontiguousarray(inc_spring[keep], dtype=np.int64),
                           np.ascontiguousarray(inc_other[keep], dtype=np.int64)))
        self.lower, self.upper = halves
        s = pairs.shape[0]
        self.upper_ordered = bool(self.upper[1].shape[0] == s
                                  and np.array_equal(self.upper[1], np.arange(s)))

    @property
    def shape(self):
        """``(3N, 3N)``."""
        n = 3 * self.diag.shape[0]
        return (n, n)

    def matvec(self, p):
        """``H p`` for ``p`` of shape (N, 3) or (3N,); same shape out."""
        p = np.ascontiguousarray(p, dtype=np.float64)
        y = np.empty_like(p)
        _operator_matvec(self.pairs, self.free, self.blocks, self.diag, p.reshape(-1, 3),
                         y.reshape(-1, 3))
        return y

    def __matmul__(self, p):
        return self.matvec(p)


class SpringSystem:
    """A set of damped springs between particles with masses, gravity, drag and pins.

    It supplies what :mod:`filters.integrators` needs: total forces, potential energy, the
    frozen-direction damping force, and the implicit system matrix
    ``H = M / h^2 + K + C / h`` assembled in Numba into a fixed-pattern ``scipy.sparse`` CSR
    matrix (``K = -df/dx`` made definite, ``C = -df/dv``); rows and columns of pinned particles are
    eliminated (replaced by the identity).

    Parameters
    ----------
    springs : (S, 2) int array_like
        Particle indices of every spring.
    rest_lengths : (S,) array_like or float
        Rest lengths (m), >= 0.
    stiffness : (S,) array_like or float
        Seed-form stiffness ``k`` (N) (N/m for zero rest length), >= 0.
    masses : (N,) array_like
        Particle masses (kg), > 0.
    damping : (S,) array_like or float
        Spring damping ``c`` (N s/m), >= 0.
    damping_mode : {"axial", "relative"}
        Spring damping model.
    drag : float
        Per-particle drag ``-drag * v_i`` (N s/m), >= 0.
    gravity : sequence of 3 float
        Gravitational acceleration (m/s^2).
    pinned : (N,) bool array_like, optional
        Particles held fixed.
    colliders : filters.elastic.contact.Colliders, optional
        Obstacles handled *inside* the forces, energy and system matrix by a penalty
        ``contact_stiffness/2 min(phi - thickness, 0)^2`` (for implicit schemes, whose solve then
        sees the contacts; a projection after a large implicit step would inject elastic energy).
    contact_stiffness : float, optional
        Penalty stiffness (N/m), > 0; default 10 times the stiffest spring's ``k_e``, at least
        ``1e4`` N/m.
    """

    def __init__(self, springs, rest_lengths, stiffness, masses, *, damping=0.0,
                 damping_mode="axial", drag=0.0, gravity=(0.0, 0.0, -9.81), pinned=None,
                 colliders=None, contact_stiffness=None):
        masses = np.ascontiguousarray(masses, dtype=np.float64)
        if masses.ndim != 1 or masses.size == 0:
            raise ValueError(f"masses must be a non-empty (N,) array, got shape {masses.shape}")
        if not np.isfinite(masses).all() or masses.min() <= 0.0:
            raise ValueError("masses must be finite and > 0 (kg)")
        n = masses.shape[0]
        self.n_points = n
        self.masses = masses
        self.pairs = _check_springs(springs, n)
        s = self.pairs.shape[0]
        self.rest = _per_spring("rest_lengths", rest_lengths, s)
        self.stiffness = _per_spring("stiffness", stiffness, s)
        self.damping = _per_spring("damping", damping, s)
        self.damping_mode = check_choice("damping_mode", damping_mode, DAMPING_MODES)
        self.mode = DAMPING_MODES.index(self.damping_mode)
        self.drag = check_range("drag", drag, 0.0)
        self.gravity = check_finite_vector("gravity", gravity, 3).copy()
        if pinned is None:
            pinned = np.zeros(n, dtype=bool)
        pinned = np.ascontiguousarray(pinned, dtype=bool)
        if pinned.shape != (n,):
            raise ValueError(f"pinned must have shape ({n},), got {pinned.shape}")
        self.pinned = pinned
        self.inv_mass = np.where(pinned, 0.0, 1.0 / masses)
        self.ke = np.ascontiguousarray(effective_stiffness(self.stiffness, self.rest))
        self.inc_ptr, self.inc_spring, self.inc_sign, self.inc_other = _incidence(self.pairs, n)
        self._fs = np.empty((s, 3))
        self._zero_c = np.zeros(s)
        self._zero_k = np.zeros(s)
        self._zero_g = np.zeros(3)
        self._pairs32 = self.pairs.astype(np.int32)
        self._f_scratch = None
        self._pattern = None
        self._operator = None
        self._undamped = self.drag == 0.0 and not np.any(self.damping)
        self._no_blocks = np.zeros((0, 3, 3))
        self.colliders = colliders
        if colliders is not None:
            default = max(1e4, 10.0 * float(self.ke.max(initial=0.0)))
            self.contact_stiffness = default if contact_stiffness is None else check_range(
                "contact_stiffness", contact_stiffness, 0.0, math.inf, low_inclusive=False)
            self._fc = np.zeros((n, 3))
            self._cb = np.zeros((n, 3, 3))
            self._mu = np.zeros(n)

    def _contacts(self, x):
        """Penalty contact energy (J); fills contact forces, Hessian blocks and friction."""
        from .contact import contact_penalty

        c = self.colliders
        with _threads(x.shape[0]):
            return float(contact_penalty(x, c.planes, c.spheres, c.boxes, c.thickness,
                                         self.contact_stiffness, self.pinned, self._fc,
                                         self._cb, self._mu))

    def apply_contact_friction(self, x, v, h):
        """Coulomb friction of the penalty contacts at ``x`` on velocities ``v`` (in place)."""
        if self.colliders is None:
            return
        from .contact import penalty_friction

        self._contacts(x)
        with _threads(x.shape[0]):
            penalty_friction(v, self._fc, self._mu, self.inv_mass, float(h))

    # -- forces and energies --------------------------------------------------------------
    def _force_kernel(self, x, v, ke, c, mode, gravity, drag, f):
        """Spring + gravity + drag forces into ``f`` (per-spring forces gathered per particle:
        every particle's sum in a fixed order, which keeps the momentum test's round-off)."""
        with _threads(self.pairs.shape[0]):
            _total_forces(x, v, self.pairs, ke, self.rest, c, mode, self.inc_ptr,
                          self.inc_spring, self.inc_sign, self.masses, gravity, drag, self._fs,
                          f)

    def forces(self, x, v, out=None):
        """Total force (N) on every particle: springs, damping, gravity and drag, (N, 3)."""
        f = np.empty_like(x) if out is None else out
        self._force_kernel(x, v, self.ke, self.damping, self.mode, self.gravity, self.drag, f)
        return f

    def conservative_forces(self, x, out=None):
        """Spring elastic forces plus gravity (no damping), (N, 3)."""
        f = np.empty_like(x) if out is None else out
        self._force_kernel(x, x, self.ke, self._zero_c, 1, self.gravity, 0.0, f)
        if self.colliders is not None:
            self._contacts(x)
            f += self._fc
        return f

    def damping_forces(self, xdir, v, out=None):
        """Damping force (springs and drag) at velocity ``v`` with directions from ``xdir``.

        Linear in ``v``: it equals ``-C v`` with ``C`` the damping matrix at ``xdir``.
        """
        f = np.empty_like(v) if out is None else out
        if self._undamped:
            f[...] = 0.0
            return f
        self._force_kernel(xdir, v, self._zero_k, self.damping, self.mode, self._zero_g,
                           self.drag, f)
        return f

    def potential_energy(self, x):
        """Elastic plus gravitational potential energy (J)."""
        if self.pairs.shape[0] < PARALLEL_MIN_SPRINGS:
            elastic = _elastic_energy_serial(x, self.pairs, self.ke, self.rest)
        else:
            elastic = _elastic_energy(x, self.pairs, self.ke, self.rest)
        contact = self._contacts(x) if self.colliders is not None else 0.0
        x = np.ascontiguousarray(x, dtype=np.float64)
        return float(elastic + contact + _point_energies(x, x, self.masses, self.gravity)[1])

    def kinetic_energy(self, v):
        """Kinetic energy (J)."""
        v = np.ascontiguousarray(v, dtype=np.float64)
        return float(_point_energies(v, v, self.masses, self.gravity)[0])

    def energy(self, x, v):
        """Total mechanical energy (J)."""
        return self.kinetic_energy(v) + self.potential_energy(x)

    def symplectic_step(self, x, v, h):
        """Symplectic Euler in one fused kernel (in place); returns the largest speed (m/s).

        Below :data:`PARALLEL_MIN_SPRINGS_EXPLICIT` springs a serial kernel scatters the forces
        directly; above, a parallel kernel computes them per spring and gathers them per
        particle (no atomics, no races).  Contacts are not included (see
        :meth:`filters.elastic.contact.Colliders.resolve`).
        """
        if self.pairs.shape[0] < PARALLEL_MIN_SPRINGS_EXPLICIT:
            if self._f_scratch is None:
                self._f_scratch = np.empty((self.n_points, 3))
            return _symplectic_serial(x, v, self._pairs32, self.ke, self.rest, self.damping,
                                      self.mode, self.masses, self.inv_mass, self.gravity,
                                      self.drag, h, self._f_scratch)
        return _symplectic_kernel(x, v, self.pairs, self.ke, self.rest, self.damping, self.mode,
                                  self.inc_ptr, self.inc_spring, self.inc_sign, self.masses,
                                  self.inv_mass, self.gravity, self.drag, h, self._fs)

    # -- implicit system --------------------------------------------------------------------
    def _build_pattern(self):
        import scipy.sparse as sp

        n = self.n_points
        a, b = self.pairs[:, 0], self.pairs[:, 1]
        keys = np.unique(np.concatenate([a * n + b, b * n + a, np.arange(n) * (n + 1)]))
        rows = keys // n
        cols = keys % n
        bptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(rows, minlength=n), out=bptr[1:])
        diag_slot = np.searchsorted(keys, np.arange(n) * (n + 1)).astype(np.int64)
        node = np.repeat(np.arange(n), np.diff(self.inc_ptr))
        inc_slot = np.searchsorted(keys, node * n + self.inc_other).astype(np.int64)
        nb = np.diff(bptr)
        # Scalar CSR: row 3i+r holds, for every block k of block-row i, columns 3*col_k + q.
        indptr = np.zeros(3 * n + 1, dtype=np.int64)
        indptr[1:] = np.cumsum(np.repeat(3 * nb, 3))
        row_cols = np.repeat(3 * cols, 3) + np.tile(np.arange(3), cols.size)
        indices = np.empty(9 * keys.size, dtype=np.int64)
        blocks_start = 3 * bptr[:-1]
        # Row 3i+r's indices are row_cols[3*bptr[i] : 3*bptr[i+1]] for r = 0, 1, 2.
        seg = np.repeat(np.arange(n), 3 * nb)  # block-row of each entry of row_cols
        within = np.arange(row_cols.size) - np.repeat(blocks_start, 3 * nb)
        for r in range(3):
            pos = 9 * bptr[seg] + 3 * r * nb[seg] + within
            indices[pos] = row_cols
        data = np.zeros(9 * keys.size)
        index_dtype = np.int32 if 9 * keys.size < 2**31 else np.int64
        mat = sp.csr_matrix((data, indices.astype(index_dtype), indptr.astype(index_dtype)),
                            shape=(3 * n, 3 * n), copy=False)
        mat.has_sorted_indices = True
        self._pattern = dict(bptr=bptr, diag_slot=diag_slot, inc_slot=inc_slot, matrix=mat,
                             jx=np.empty((self.pairs.shape[0], 3, 3)),
                             jv=np.empty((self.pairs.shape[0], 3, 3)),
                             jx2=np.empty((self.pairs.shape[0], 3, 3)))

    def system_matrix(self, x, xdir, h):
        """Assemble ``H = M/h^2 + K(x) + C(xdir)/h`` in place into the fixed-pattern CSR matrix.

        Parameters
        ----------
        x : (N, 3) array
            Positions (m) where the stiffness ``K = -df/dx`` (made definite) is evaluated.
        xdir : (N, 3) array
            Positions fixing the axial damping directions of ``C = -df/dv``.
        h : float
            Time step (s).

        Returns
        -------
        scipy.sparse.csr_matrix, (3N, 3N)
            The same object every call (its ``data`` is overwritten).
        """
        if self._pattern is None:
            self._build_pattern()
        p = self._pattern
        jx, jv = p["jx"], p["jv"]
        zero_v = np.zeros_like(x)
        mat = p["matrix"]
        with _threads(self.pairs.shape[0]):
            _jacobian_blocks(x, zero_v, self.pairs, self.ke, self.rest, self.damping, self.mode,
                             True, False, jx, jv)
            if self.mode == 0 and xdir is not x:
                _jacobian_blocks(xdir, zero_v, self.pairs, self.ke, self.rest, self.damping,
                                 self.mode, True, False, p["jx2"], jv)
            _assemble(jx, jv, self.inc_ptr, self.inc_spring, self.inc_other, p["inc_slot"],
                      p["diag_slot"], p["bptr"], self.masses, self.pinned, float(h), self.drag,
                      mat.data)
            if self.colliders is not None:
                self._contacts(x)
                _add_diagonal_blocks(self._cb, p["diag_slot"], p["bptr"], self.pinned, mat.data)
        return mat

    def implicit_operator(self, x, xdir, h):
        """The matrix ``H`` of :meth:`system_matrix`, as a matrix-free :class:`SpringOperator`.

        Same arguments and same matrix as :meth:`system_matrix`; the PCG solver of
        :mod:`filters.integrators` uses it (the CSR matrix remains for direct solves).  The
        returned object's arrays are reused (overwritten) by the next call.

        Returns
        -------
        SpringOperator
        """
        if self._operator is None:
            # The operator keeps its springs in upper-incidence order (sorted by their lower
            # end point), which makes every sweep over them a sequential stream.
            n = self.n_points
            s = self.pairs.shape[0]
            lo = np.minimum(self.pairs[:, 0], self.pairs[:, 1])
            hi = np.maximum(self.pairs[:, 0], self.pairs[:, 1])
            order = np.lexsort((hi, lo))
            pairs = np.ascontiguousarray(np.stack([lo[order], hi[order]], axis=1))
            self._op_params = tuple(np.ascontiguousarray(a[order])
                                    for a in (self.ke, self.rest, self.damping))
            inc_ptr, inc_spring, _, inc_other = _incidence(pairs, n)
            self._operator = SpringOperator(pairs, np.where(self.pinned, 0.0, 1.0),
                                            np.empty((s, 6)), np.empty((n, 3, 3)),
                                            inc_ptr, inc_spring, inc_other)
        op = self._operator
        ke, rest, damping = self._op_params
        _operator_coefficients(x, xdir, op.pairs, ke, rest, damping, self.mode, float(h),
                               op.blocks)
        if self.colliders is not None:
            self._contacts(x)
            blocks = self._cb
        else:
            blocks = self._no_blocks
        _operator_diagonal(self.masses, self.pinned, float(h), self.drag, blocks, op.diag)
        return op
