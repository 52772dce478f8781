"""Impulses of the rigid-body contacts found by :func:`filters.rigid.contact.find_contacts`.

**Impulses** (:func:`solve_velocities`): projected Gauss-Seidel over the contacts with accumulated
impulses (sequential impulses, Catto 2005, "Iterative dynamics with temporal coherence", GDC):
per contact a normal impulse ``lambda_n >= 0`` with ``v_n^+ >= target`` and complementarity, and a
tangential impulse in the contact plane with the Coulomb bound ``|lambda_t| <= mu lambda_n``
(the cone, not a pyramid): a contact sticks with the 2x2 block impulse that stops its slip if
that is inside the cone; otherwise a scalar update (one effective mass for the plane) is
projected on the cone, whose fixed point is ``mu lambda_n`` exactly against the slip (maximal
dissipation; a 2x2 update would tilt it towards the stiffer direction), so that a slide in any
direction sees the same ``mu``.  The target is 0, or
``-phi / h`` for a gap, or ``-e v_n^-`` (Newton's restitution) for a point that reaches the
surface in this step faster than the threshold speed.  The impulses of the previous step start the
iteration (*warm starting*, matched by body, point and partner), so that a resting stack converges
to its exact impulses and stays at rest.  Sweeps alternate forward and backward.

**Separation** (:func:`solve_positions`): overlaps deeper than the slop are removed by
pseudo-velocities from a second, frictionless solve (the split impulse of Catto's Box2D and
Bullet): they move the bodies in the drift but are not kept, so removing an overlap adds no
kinetic energy and no momentum.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["solve_velocities", "solve_positions"]


@njit(cache=True, inline="always")
def _basis(n0, n1, n2):
    """An orthonormal tangent basis of the plane of ``n`` (Duff et al. 2017, JCGT 6(1))."""
    sign = 1.0 if n2 >= 0.0 else -1.0
    a = -1.0 / (sign + n2)
    b = n0 * n1 * a
    return (1.0 + sign * n0 * n0 * a, sign * b, -sign * n0), (b, sign + n1 * n1 * a, -n1)


@njit(cache=True, inline="always")
def _inverse_mass_along(im, ii, rx, ry, rz, dx, dy, dz):
    """``1/m + (r x d) . I^-1 (r x d)`` of one body."""
    cx = ry * dz - rz * dy
    cy = rz * dx - rx * dz
    cz = rx * dy - ry * dx
    return im + (cx * (ii[0, 0] * cx + ii[0, 1] * cy + ii[0, 2] * cz)
                 + cy * (ii[1, 0] * cx + ii[1, 1] * cy + ii[1, 2] * cz)
                 + cz * (ii[2, 0] * cx + ii[2, 1] * cy + ii[2, 2] * cz))


@njit(cache=True, inline="always")
def _apply(v, w, im, ii, b, rx, ry, rz, jx, jy, jz, sign):
    """Apply impulse ``sign * j`` at ``r`` to body ``b``."""
    v[b, 0] += sign * im * jx
    v[b, 1] += sign * im * jy
    v[b, 2] += sign * im * jz
    tx = sign * (ry * jz - rz * jy)
    ty = sign * (rz * jx - rx * jz)
    tz = sign * (rx * jy - ry * jx)
    w[b, 0] += ii[0, 0] * tx + ii[0, 1] * ty + ii[0, 2] * tz
    w[b, 1] += ii[1, 0] * tx + ii[1, 1] * ty + ii[1, 2] * tz
    w[b, 2] += ii[2, 0] * tx + ii[2, 1] * ty + ii[2, 2] * tz


@njit(cache=True, inline="always")
def _relative(v, w, a, b, r, c, dx, dy, dz):
    """``(u_a - u_b) . d`` at contact ``c``, ``u`` the point velocities; ``b < 0`` is static."""
    s = ((v[a, 0] + w[a, 1] * r[c, 2] - w[a, 2] * r[c, 1]) * dx
         + (v[a, 1] + w[a, 2] * r[c, 0] - w[a, 0] * r[c, 2]) * dy
         + (v[a, 2] + w[a, 0] * r[c, 1] - w[a, 1] * r[c, 0]) * dz)
    if b >= 0:
        s -= ((v[b, 0] + w[b, 1] * r[c, 5] - w[b, 2] * r[c, 4]) * dx
              + (v[b, 1] + w[b, 2] * r[c, 3] - w[b, 0] * r[c, 5]) * dy
              + (v[b, 2] + w[b, 0] * r[c, 4] - w[b, 1] * r[c, 3]) * dz)
    return s


@njit(cache=True)
def _arms(ints, floats, positions):
    k = ints.shape[0]
    r = np.zeros((k, 6))
    for c in range(k):
        a = ints[c, 0]
        b = ints[c, 1]
        for d in range(3):
            r[c, d] = floats[c, d] - positions[a, d]
            if b >= 0:
                r[c, 3 + d] = floats[c, d] - positions[b, d]
    return r


@njit(cache=True, inline="always")
def _cross_term(ii, rx, ry, rz, d, e):
    """``(r x d) . I^-1 (r x e)`` of one body."""
    cx = ry * d[2] - rz * d[1]
    cy = rz * d[0] - rx * d[2]
    cz = rx * d[1] - ry * d[0]
    ex = ry * e[2] - rz * e[1]
    ey = rz * e[0] - rx * e[2]
    ez = rx * e[1] - ry * e[0]
    return (cx * (ii[0, 0] * ex + ii[0, 1] * ey + ii[0, 2] * ez)
            + cy * (ii[1, 0] * ex + ii[1, 1] * ey + ii[1, 2] * ez)
            + cz * (ii[2, 0] * ex + ii[2, 1] * ey + ii[2, 2] * ez))


@njit(cache=True)
def _tangent_block(ints, r, inv_mass, inv_inertia, t1, t2):
    """The 2x2 effective mass of the contact plane (the inverse of its inverse-mass matrix
    ``K_t``), as ``(m11, m12, m22)`` -- the impulse ``-M v_t`` stops the slip ``v_t`` of this
    contact alone -- and the scalar ``1 / lambda_max(K_t)`` of the sliding update."""
    a = ints[0]
    b = ints[1]
    k11 = _inverse_mass_along(inv_mass[a], inv_inertia[a], r[0], r[1], r[2], t1[0], t1[1], t1[2])
    k22 = _inverse_mass_along(inv_mass[a], inv_inertia[a], r[0], r[1], r[2], t2[0], t2[1], t2[2])
    k12 = _cross_term(inv_inertia[a], r[0], r[1], r[2], t1, t2)
    if b >= 0:
        k11 += _inverse_mass_along(inv_mass[b], inv_inertia[b], r[3], r[4], r[5], t1[0], t1[1],
                                   t1[2])
        k22 += _inverse_mass_along(inv_mass[b], inv_inertia[b], r[3], r[4], r[5], t2[0], t2[1],
                                   t2[2])
        k12 += _cross_term(inv_inertia[b], r[3], r[4], r[5], t1, t2)
    det = k11 * k22 - k12 * k12
    top = 0.5 * (k11 + k22) + math.sqrt(0.25 * (k11 - k22) ** 2 + k12 * k12)
    if not (det > 0.0 and top > 0.0):
        return 0.0, 0.0, 0.0, 0.0
    return k22 / det, -k12 / det, k11 / det, 1.0 / top


@njit(cache=True)
def _mass_along(ints, r, inv_mass, inv_inertia, dx, dy, dz):
    a = ints[0]
    b = ints[1]
    k = _inverse_mass_along(inv_mass[a], inv_inertia[a], r[0], r[1], r[2], dx, dy, dz)
    if b >= 0:
        k += _inverse_mass_along(inv_mass[b], inv_inertia[b], r[3], r[4], r[5], dx, dy, dz)
    return 1.0 / k if k > 0.0 else 0.0


@njit(cache=True)
def solve_velocities(ints, floats, positions, v, w, inv_mass, inv_inertia, warm, threshold, h,
                     iterations, impulses):
    """Contact and friction impulses by projected Gauss-Seidel; ``v``, ``w`` (B, 3) in place.

    Parameters
    ----------
    ints, floats : arrays (K, 3), (K, 9)
        From :func:`find_contacts`.
    positions : (B, 3) float64
        Centres of mass (m).
    v, w : (B, 3) float64
        Velocities and world angular velocities after the forces of the step; updated.
    inv_mass : (B,) float64
        ``1/m`` (0 for fixed bodies).
    inv_inertia : (B, 3, 3) float64
        World inverse inertia tensors (0 for fixed bodies).
    warm : (K, 4) float64
        Starting impulses: normal (N s) and tangential world vector (N s).
    threshold : (B,) float64
        Approach speed (m/s) below which a body's contacts are inelastic.
    h : float
        Step (s).
    iterations : int
        Largest number of sweeps; they stop when no impulse changes by more than 1e-12 of the
        largest.
    impulses : (K, 4) float64
        Out: the impulses, as ``warm``.

    Returns
    -------
    int
        Sweeps done.
    """
    k = ints.shape[0]
    r = _arms(ints, floats, positions)
    tangents = np.empty((k, 6))
    masses = np.empty((k, 5))
    target = np.empty(k)
    lam = np.zeros((k, 3))
    for c in range(k):
        n0, n1, n2 = floats[c, 3], floats[c, 4], floats[c, 5]
        t1, t2 = _basis(n0, n1, n2)
        tangents[c, 0], tangents[c, 1], tangents[c, 2] = t1
        tangents[c, 3], tangents[c, 4], tangents[c, 5] = t2
        masses[c, 0] = _mass_along(ints[c], r[c], inv_mass, inv_inertia, n0, n1, n2)
        masses[c, 1], masses[c, 2], masses[c, 3], masses[c, 4] = _tangent_block(
            ints[c], r[c], inv_mass, inv_inertia, t1, t2)
        a = ints[c, 0]
        b = ints[c, 1]
        phi = floats[c, 6]
        e = floats[c, 7]
        vn = _relative(v, w, a, b, r, c, n0, n1, n2)
        goal = -phi / h if phi > 0.0 else 0.0
        slow = threshold[a] if b < 0 else max(threshold[a], threshold[b])
        if e > 0.0 and vn < -slow and vn * h < -max(phi, 0.0):
            goal = max(goal, -e * vn)
        target[c] = goal
    # warm start
    for c in range(k):
        a = ints[c, 0]
        b = ints[c, 1]
        ln = max(warm[c, 0], 0.0)
        l1 = (warm[c, 1] * tangents[c, 0] + warm[c, 2] * tangents[c, 1]
              + warm[c, 3] * tangents[c, 2])
        l2 = (warm[c, 1] * tangents[c, 3] + warm[c, 2] * tangents[c, 4]
              + warm[c, 3] * tangents[c, 5])
        lt = math.sqrt(l1 * l1 + l2 * l2)
        cap = floats[c, 8] * ln
        if lt > cap:
            l1 *= cap / lt
            l2 *= cap / lt
        lam[c, 0] = ln
        lam[c, 1] = l1
        lam[c, 2] = l2
        jx = ln * floats[c, 3] + l1 * tangents[c, 0] + l2 * tangents[c, 3]
        jy = ln * floats[c, 4] + l1 * tangents[c, 1] + l2 * tangents[c, 4]
        jz = ln * floats[c, 5] + l1 * tangents[c, 2] + l2 * tangents[c, 5]
        _apply(v, w, inv_mass[a], inv_inertia[a], a, r[c, 0], r[c, 1], r[c, 2], jx, jy, jz, 1.0)
        if b >= 0:
            _apply(v, w, inv_mass[b], inv_inertia[b], b, r[c, 3], r[c, 4], r[c, 5], jx, jy, jz,
                   -1.0)
    sweeps = 0
    for it in range(iterations):
        sweeps += 1
        change = 0.0
        largest = 0.0
        for s in range(k):
            c = s if it % 2 == 0 else k - 1 - s
            a = ints[c, 0]
            b = ints[c, 1]
            n0, n1, n2 = floats[c, 3], floats[c, 4], floats[c, 5]
            # normal
            vn = _relative(v, w, a, b, r, c, n0, n1, n2)
            new = max(lam[c, 0] + masses[c, 0] * (target[c] - vn), 0.0)
            dl = new - lam[c, 0]
            lam[c, 0] = new
            if dl != 0.0:
                _apply(v, w, inv_mass[a], inv_inertia[a], a, r[c, 0], r[c, 1], r[c, 2],
                       dl * n0, dl * n1, dl * n2, 1.0)
                if b >= 0:
                    _apply(v, w, inv_mass[b], inv_inertia[b], b, r[c, 3], r[c, 4], r[c, 5],
                           dl * n0, dl * n1, dl * n2, -1.0)
            change = max(change, abs(dl))
            # friction, in the cone |lambda_t| <= mu lambda_n
            cap = floats[c, 8] * lam[c, 0]
            v1 = _relative(v, w, a, b, r, c, tangents[c, 0], tangents[c, 1], tangents[c, 2])
            v2 = _relative(v, w, a, b, r, c, tangents[c, 3], tangents[c, 4], tangents[c, 5])
            # sticking: the impulse that stops this contact's slip (a 2x2 block)
            l1 = lam[c, 1] - (masses[c, 1] * v1 + masses[c, 2] * v2)
            l2 = lam[c, 2] - (masses[c, 2] * v1 + masses[c, 3] * v2)
            lt = math.sqrt(l1 * l1 + l2 * l2)
            if lt > cap:
                # sliding: a scalar update projected on the cone, whose fixed point is the
                # largest friction exactly against the slip (maximal dissipation)
                l1 = lam[c, 1] - masses[c, 4] * v1
                l2 = lam[c, 2] - masses[c, 4] * v2
                lt = math.sqrt(l1 * l1 + l2 * l2)
                if lt > cap:
                    l1 *= cap / lt
                    l2 *= cap / lt
            d1 = l1 - lam[c, 1]
            d2 = l2 - lam[c, 2]
            lam[c, 1] = l1
            lam[c, 2] = l2
            if d1 != 0.0 or d2 != 0.0:
                jx = d1 * tangents[c, 0] + d2 * tangents[c, 3]
                jy = d1 * tangents[c, 1] + d2 * tangents[c, 4]
                jz = d1 * tangents[c, 2] + d2 * tangents[c, 5]
                _apply(v, w, inv_mass[a], inv_inertia[a], a, r[c, 0], r[c, 1], r[c, 2],
                       jx, jy, jz, 1.0)
                if b >= 0:
                    _apply(v, w, inv_mass[b], inv_inertia[b], b, r[c, 3], r[c, 4], r[c, 5],
                           jx, jy, jz, -1.0)
            change = max(change, abs(d1), abs(d2))
            largest = max(largest, lam[c, 0])
        if change <= 1e-12 * largest:
            break
    for c in range(k):
        impulses[c, 0] = lam[c, 0]
        for d in range(3):
            impulses[c, 1 + d] = lam[c, 1] * tangents[c, d] + lam[c, 2] * tangents[c, 3 + d]
    return sweeps


@njit(cache=True)
def solve_positions(ints, floats, positions, inv_mass, inv_inertia, slop, rate, h, iterations,
                    v_push, w_push):
    """Pseudo-velocities ``v_push``, ``w_push`` (B, 3) that remove the fraction ``rate`` of
    every overlap deeper than ``slop`` (m) in a step ``h`` (frictionless projected
    Gauss-Seidel, normal only).  Returns the sweeps done (0 when nothing overlaps)."""
    k = ints.shape[0]
    v_push[:] = 0.0
    w_push[:] = 0.0
    deepest = 0.0
    for c in range(k):
        deepest = max(deepest, -floats[c, 6] - slop)
    if deepest <= 0.0:
        return 0
    r = _arms(ints, floats, positions)
    masses = np.empty(k)
    target = np.empty(k)
    for c in range(k):
        masses[c] = _mass_along(ints[c], r[c], inv_mass, inv_inertia, floats[c, 3],
                                floats[c, 4], floats[c, 5])
        target[c] = rate * max(-floats[c, 6] - slop, 0.0) / h
    lam = np.zeros(k)
    sweeps = 0
    for it in range(iterations):
        sweeps += 1
        change = 0.0
        largest = 0.0
        for s in range(k):
            c = s if it % 2 == 0 else k - 1 - s
            a = ints[c, 0]
            b = ints[c, 1]
            n0, n1, n2 = floats[c, 3], floats[c, 4], floats[c, 5]
            vn = _relative(v_push, w_push, a, b, r, c, n0, n1, n2)
            new = max(lam[c] + masses[c] * (target[c] - vn), 0.0)
            dl = new - lam[c]
            lam[c] = new
            if dl != 0.0:
                _apply(v_push, w_push, inv_mass[a], inv_inertia[a], a, r[c, 0], r[c, 1],
                       r[c, 2], dl * n0, dl * n1, dl * n2, 1.0)
                if b >= 0:
                    _apply(v_push, w_push, inv_mass[b], inv_inertia[b], b, r[c, 3], r[c, 4],
                           r[c, 5], dl * n0, dl * n1, dl * n2, -1.0)
            change = max(change, abs(dl))
            largest = max(largest, lam[c])
        if change <= 1e-12 * largest:
            break
    return sweeps
