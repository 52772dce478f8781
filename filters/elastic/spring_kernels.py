"""Per-spring Numba kernels of :mod:`filters.elastic.springs`: forces, energies, Jacobians and the
implicit system's blocks.

Spring ``s`` joins particles ``pairs[s] = (a, b)`` with effective stiffness ``ke[s]`` (N/m),
rest length ``rest[s]`` (m) and damping ``c[s]`` (N s/m), damping model ``mode`` (0 axial,
1 relative); see :mod:`filters.elastic.springs` for the formulas (Baraff & Witkin 1998; Choi &
Ko 2002). Forces are computed per spring and gathered per particle through the incidence lists
(:func:`incidence`), so every particle's sum runs in a fixed order: no atomics, no races, the
same bits for any number of threads.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = [
    "EPS",
    "spring_force3",
    "spring_forces_into",
    "symplectic_serial",
    "per_spring_forces",
    "total_forces",
    "total_forces_serial",
    "symplectic_parallel",
    "elastic_energy_serial",
    "elastic_energy",
    "point_energies",
    "jacobian_blocks",
    "incidence",
    "incidence_in_spring_order",
    "assemble_system",
    "operator_coefficients",
    "operator_diagonal",
]

#: Springs shorter than this (m) have no direction.
EPS = 1e-12


@njit(cache=True, inline="always")
def spring_force3(xa, xb, va, vb, ke, rest, c, mode):
    """Force (f0, f1, f2) on end ``a`` of one spring."""
    d0 = xa[0] - xb[0]
    d1 = xa[1] - xb[1]
    d2 = xa[2] - xb[2]
    w0 = va[0] - vb[0]
    w1 = va[1] - vb[1]
    w2 = va[2] - vb[2]
    f0 = 0.0
    f1 = 0.0
    f2 = 0.0
    if rest == 0.0:
        # a linear spring: relative damping in both modes (no direction at zero length)
        return -ke * d0 - c * w0, -ke * d1 - c * w1, -ke * d2 - c * w2
    l = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if l > EPS:
        inv = 1.0 / l
        u0 = d0 * inv
        u1 = d1 * inv
        u2 = d2 * inv
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
    f0, f1, f2 = spring_force3(xa, xb, va, vb, ke, rest, c, mode)
    out[0] = f0
    out[1] = f1
    out[2] = f2


#: Springs per work item of the parallel force kernels.
FORCE_CHUNK = 2048


@njit(cache=True, error_model="numpy", inline="always")
def spring_forces_into(x, v, pa, pb, ke, rest, c, mode, buf, start, stop):
    """Forces on end ``a`` of springs ``start:stop`` into ``buf[0:3, start:stop]`` (rows: the
    force's components; rows 3-5 are scratch).

    Two passes: the end-point differences are gathered into the rows of ``buf``, then the
    forces computed from them in a contiguous loop without branches (selects), which the
    compiler vectorises (square roots and divisions four at a time; ``error_model="numpy"``
    drops the division-by-zero check, whose quotient is never selected).  Each force is the
    operations of :func:`spring_force3` in the same order: the same bits.  ``pa``, ``pb``: the
    springs' end points (S,) uint32 (no negative-index wrap-around).
    """
    d0 = buf[0]
    d1 = buf[1]
    d2 = buf[2]
    w0 = buf[3]
    w1 = buf[4]
    w2 = buf[5]
    for s in range(start, stop):
        a = pa[s]
        b = pb[s]
        d0[s] = x[a, 0] - x[b, 0]
        d1[s] = x[a, 1] - x[b, 1]
        d2[s] = x[a, 2] - x[b, 2]
        w0[s] = v[a, 0] - v[b, 0]
        w1[s] = v[a, 1] - v[b, 1]
        w2[s] = v[a, 2] - v[b, 2]
    axial = mode == 0
    relative = mode == 1
    for s in range(start, stop):
        r = rest[s]
        k = ke[s]
        cs = c[s]
        e0 = d0[s]
        e1 = d1[s]
        e2 = d2[s]
        q0 = w0[s]
        q1 = w1[s]
        q2 = w2[s]
        l = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        inv = 1.0 / l  # inf or nan where l <= EPS: not selected below
        u0 = e0 * inv
        u1 = e1 * inv
        u2 = e2 * inv
        sc = -k * (l - r)
        sa = sc - cs * (q0 * u0 + q1 * u1 + q2 * u2)
        sc = sa if axial else sc
        ok = l > EPS
        f0 = 0.0 + sc * u0 if ok else 0.0
        f1 = 0.0 + sc * u1 if ok else 0.0
        f2 = 0.0 + sc * u2 if ok else 0.0
        g0 = f0 - cs * q0
        g1 = f1 - cs * q1
        g2 = f2 - cs * q2
        f0 = g0 if relative else f0
        f1 = g1 if relative else f1
        f2 = g2 if relative else f2
        lin = r == 0.0  # a linear spring: relative damping in both modes
        d0[s] = -k * e0 - cs * q0 if lin else f0
        d1[s] = -k * e1 - cs * q1 if lin else f1
        d2[s] = -k * e2 - cs * q2 if lin else f2


@njit(cache=True, error_model="numpy")
def symplectic_serial(x, v, pa, pb, ke, rest, c, mode, masses, inv_mass, gravity, drag, h, f,
                      buf):
    """Serial symplectic Euler step in place; returns the largest speed (m/s).

    The springs' forces by :func:`spring_forces_into` (``buf`` (6, S) scratch), scattered in
    spring order (no races on one thread): the same sums, bit for bit, as one fused loop.
    """
    n = x.shape[0]
    ns = pa.shape[0]
    spring_forces_into(x, v, pa, pb, ke, rest, c, mode, buf, 0, ns)
    d0 = buf[0]
    d1 = buf[1]
    d2 = buf[2]
    for i in range(n):
        f[i, 0] = masses[i] * gravity[0] - drag * v[i, 0]
        f[i, 1] = masses[i] * gravity[1] - drag * v[i, 1]
        f[i, 2] = masses[i] * gravity[2] - drag * v[i, 2]
    for s in range(ns):
        a = pa[s]
        b = pb[s]
        f0 = d0[s]
        f1 = d1[s]
        f2 = d2[s]
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
def per_spring_forces(x, v, pairs, ke, rest, c, mode, fs):
    for s in prange(pairs.shape[0]):
        _spring_force(x[pairs[s, 0]], x[pairs[s, 1]], v[pairs[s, 0]], v[pairs[s, 1]],
                      ke[s], rest[s], c[s], mode, fs[s])


@njit(cache=True, inline="always")
def _add_incident_rows(buf, inc_ptr, inc_spring, inc_sign, i, a0, a1, a2):
    """``(a0, a1, a2) + sum of sign * buf[0:3, s]`` over the springs ``s`` incident to particle
    ``i`` (in the incidence lists' fixed order)."""
    for p in range(inc_ptr[i], inc_ptr[i + 1]):
        s = inc_spring[p]
        sg = inc_sign[p]
        a0 += sg * buf[0, s]
        a1 += sg * buf[1, s]
        a2 += sg * buf[2, s]
    return a0, a1, a2


@njit(cache=True, error_model="numpy")
def total_forces_serial(x, v, pa, pb, ke, rest, c, mode, inc_ptr, inc_spring, inc_sign, masses,
                        gravity, drag, buf, f):
    """:func:`total_forces` on one thread (not a parallel region: its loops vectorise)."""
    spring_forces_into(x, v, pa, pb, ke, rest, c, mode, buf, 0, pa.shape[0])
    for i in range(f.shape[0]):
        a0 = masses[i] * gravity[0] - drag * v[i, 0]
        a1 = masses[i] * gravity[1] - drag * v[i, 1]
        a2 = masses[i] * gravity[2] - drag * v[i, 2]
        a0, a1, a2 = _add_incident_rows(buf, inc_ptr, inc_spring, inc_sign, i, a0, a1, a2)
        f[i, 0] = a0
        f[i, 1] = a1
        f[i, 2] = a2


@njit(parallel=True, cache=True, error_model="numpy")
def total_forces(x, v, pa, pb, ke, rest, c, mode, inc_ptr, inc_spring, inc_sign, masses,
                 gravity, drag, buf, f):
    """Spring + gravity + drag forces on every particle into ``f`` (N, 3); ``buf`` (6, S)
    scratch (:func:`spring_forces_into`), gathered per particle in incidence order."""
    ns = pa.shape[0]
    for ch in prange((ns + FORCE_CHUNK - 1) // FORCE_CHUNK):
        spring_forces_into(x, v, pa, pb, ke, rest, c, mode, buf, ch * FORCE_CHUNK,
                           min(ns, (ch + 1) * FORCE_CHUNK))
    for i in prange(f.shape[0]):
        a0 = masses[i] * gravity[0] - drag * v[i, 0]
        a1 = masses[i] * gravity[1] - drag * v[i, 1]
        a2 = masses[i] * gravity[2] - drag * v[i, 2]
        a0, a1, a2 = _add_incident_rows(buf, inc_ptr, inc_spring, inc_sign, i, a0, a1, a2)
        f[i, 0] = a0
        f[i, 1] = a1
        f[i, 2] = a2


@njit(parallel=True, cache=True, error_model="numpy")
def symplectic_parallel(x, v, pa, pb, ke, rest, c, mode, inc_ptr, inc_spring, inc_sign, masses,
                        inv_mass, gravity, drag, h, buf):
    """One symplectic Euler step in place: v += h f(x, v) / m; x += h v (pinned: inv_mass 0);
    ``buf`` (6, S) scratch.  With the incidence lists in spring order
    (:func:`incidence_in_spring_order`) the same bits as :func:`symplectic_serial`."""
    ns = pa.shape[0]
    for ch in prange((ns + FORCE_CHUNK - 1) // FORCE_CHUNK):
        spring_forces_into(x, v, pa, pb, ke, rest, c, mode, buf, ch * FORCE_CHUNK,
                           min(ns, (ch + 1) * FORCE_CHUNK))
    vmax = 0.0
    for i in prange(x.shape[0]):
        a0 = masses[i] * gravity[0] - drag * v[i, 0]
        a1 = masses[i] * gravity[1] - drag * v[i, 1]
        a2 = masses[i] * gravity[2] - drag * v[i, 2]
        a0, a1, a2 = _add_incident_rows(buf, inc_ptr, inc_spring, inc_sign, i, a0, a1, a2)
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
def elastic_energy_serial(x, pairs, ke, rest):
    """Serial :func:`_elastic_energy` (below :data:`PARALLEL_MIN_SPRINGS` springs)."""
    e = 0.0
    for s in range(pairs.shape[0]):
        e += _spring_energy(x, pairs, ke, rest, s)
    return e


@njit(cache=True)
def point_energies(x, v, masses, gravity):
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
def elastic_energy(x, pairs, ke, rest):
    e = 0.0
    for s in prange(pairs.shape[0]):
        e += _spring_energy(x, pairs, ke, rest, s)
    return e


@njit(parallel=True, cache=True)
def jacobian_blocks(x, v, pairs, ke, rest, c, mode, definite, with_damping_dx, jx, jv):
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
        if rest[s] == 0.0:  # linear spring, relative damping in both modes
            for p in range(3):
                jx[s, p, p] = -ke[s]
                jv[s, p, p] = -c[s]
            continue
        if mode == 1:
            for p in range(3):
                jv[s, p, p] = -c[s]
        if l <= EPS:
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


def incidence_in_spring_order(pairs: np.ndarray,
                               n: int) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The incident springs and signs of :func:`incidence` (same ``ptr``), each particle's in
    increasing spring order: a per-particle gather in this order adds the same numbers in the
    same order as scattering the springs' forces in spring order (:func:`symplectic_serial`),
    so the parallel and the serial step give the same bits."""
    s = pairs.shape[0]
    nodes = np.concatenate([pairs[:, 0], pairs[:, 1]])
    springs = np.concatenate([np.arange(s), np.arange(s)])
    signs = np.concatenate([np.ones(s), -np.ones(s)])
    order = np.lexsort((springs, nodes))
    return springs[order].astype(np.int64), signs[order]


def incidence(pairs: np.ndarray,
              n: int) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64],
                               NDArray[np.int64]]:
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
def assemble_system(jx, jv, inc_ptr, inc_spring, inc_other, inc_slot, diag_slot, bptr, masses,
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


@njit(cache=True)
def operator_coefficients(x, xdir, pairs, ke, rest, c, mode, h, blocks):
    """Per-spring symmetric blocks ``K_s + C_s / h`` (6 entries: xx, xy, xz, yy, yz, zz).

    Equal to the blocks that :meth:`SpringSystem.system_matrix` assembles (definite ``K``,
    compressed springs clamped; no position derivative of the damping force):
    ``alpha u u^T + beta I + gamma w w^T`` with ``u`` the direction at ``x`` and ``w`` the frozen
    damping direction at ``xdir``; for ``L > 0``, ``K_s = k_e [u u^T + t (I - u u^T)]`` with
    ``t = max(1 - L/l, 0)``, i.e. ``alpha = k_e (1 - t)``, ``beta = k_e t``; for ``L = 0``,
    ``K_s = k_e I``; axial damping ``C_s = c w w^T``, relative damping (and any damping of a
    zero-rest-length spring) ``C_s = c I``.
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
            if l > EPS:
                inv_l = 1.0 / l
                t = 1.0 - rest[s] * inv_l
                if t < 0.0:
                    t = 0.0
                u0 = d0 * inv_l
                u1 = d1 * inv_l
                u2 = d2 * inv_l
                alpha = ke[s] * (1.0 - t)
                beta = ke[s] * t
        if mode == 1 or rest[s] == 0.0:
            beta += c[s] * inv_h
        elif c[s] != 0.0:
            e0 = xdir[a, 0] - xdir[b, 0]
            e1 = xdir[a, 1] - xdir[b, 1]
            e2 = xdir[a, 2] - xdir[b, 2]
            le = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
            if le > EPS:
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
def operator_diagonal(masses, pinned, h, drag, contact_blocks, diag):
    """Particle diagonal blocks ``(m/h^2 + drag/h) I`` (+ ``contact_blocks`` when it has N
    rows); identity if pinned."""
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
