"""Numba kernels of :mod:`filters.elastic.contact_model`: the barrier, lagged friction and normal
damping of contact points (particles or embedded points) against packed colliders, their
derivatives, the feasibility filter of the line search, and the spread of per-point derivatives
on the particles.  Per-point loops run in parallel, one point per iteration (no races); the
spread on particles is serial in a fixed order, so results do not depend on the thread count.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .contact import primitive_sdf

__all__ = ["barrier", "lag_normal_forces", "contact_terms", "scatter_to_particles",
           "feasible_steps", "barrier_energies", "contact_clearance"]


@njit(cache=True, inline="always")
def _point(x, nodes, weights, j):
    p0 = 0.0
    p1 = 0.0
    p2 = 0.0
    for k in range(nodes.shape[1]):
        w = weights[j, k]
        i = nodes[j, k]
        p0 += w * x[i, 0]
        p1 += w * x[i, 1]
        p2 += w * x[i, 2]
    return p0, p1, p2


@njit(cache=True, inline="always")
def barrier(d, dhat):
    """IPC barrier ``b(d) = -(d - dhat)^2 ln(d / dhat)`` for ``0 < d < dhat`` (m^2), its first
    (m) and second (dimensionless) derivatives; zeros beyond ``dhat``, infinite at ``d <= 0``."""
    if d >= dhat:
        return 0.0, 0.0, 0.0
    if d <= 0.0:
        return np.inf, -np.inf, np.inf
    r = d - dhat
    lg = math.log(d / dhat)
    return -r * r * lg, -2.0 * r * lg - r * r / d, -2.0 * lg - 4.0 * r / d + r * r / (d * d)


@njit(cache=True, inline="always")
def _barrier_point(p, planes, spheres, boxes, dhat, kappa, grad, hess, j):
    """Barrier energy of point ``p`` (3,) over every collider; adds the gradient into
    ``grad[j]`` and the Gauss-Newton Hessian ``kappa b'' n n^T`` (6 entries xx, xy, xz, yy,
    yz, zz) into ``hess[j]`` when they have rows.  Also returns the repulsion force and its
    friction-weighted magnitude ``sum mu |f|``."""
    e = 0.0
    f0 = 0.0
    f1 = 0.0
    f2 = 0.0
    mu_f = 0.0
    for c in range(planes.shape[0] + spheres.shape[0] + boxes.shape[0]):
        phi, n0, n1, n2, mu = primitive_sdf(p, planes, spheres, boxes, c)
        if phi >= dhat:
            continue
        b, db, ddb = barrier(phi, dhat)
        e += kappa * b
        fn = -kappa * db  # > 0, along n
        f0 += fn * n0
        f1 += fn * n1
        f2 += fn * n2
        mu_f += mu * fn
        if grad.shape[0] > 0:
            grad[j, 0] -= fn * n0
            grad[j, 1] -= fn * n1
            grad[j, 2] -= fn * n2
        if hess.shape[0] > 0:
            k = kappa * ddb
            hess[j, 0] += k * n0 * n0
            hess[j, 1] += k * n0 * n1
            hess[j, 2] += k * n0 * n2
            hess[j, 3] += k * n1 * n1
            hess[j, 4] += k * n1 * n2
            hess[j, 5] += k * n2 * n2
    return e, f0, f1, f2, mu_f


@njit(parallel=True, cache=True)
def lag_normal_forces(x, nodes, weights, active, planes, spheres, boxes, dhat, kappa, masses,
                      zeta, lagged):
    """Normal forces of the barrier at positions ``x`` for the friction and damping of a step.

    Writes, per contact point ``j``, ``lagged[j] = (sum mu |f|, n0, n1, n2, c)``: the friction
    coefficients times the magnitudes (N) of its repulsions, the unit direction of their sum,
    and the normal damping ``c = 2 zeta sqrt(k m)`` (N s/m) for the barrier's stiffness ``k``
    there; zeros where the point is farther than ``dhat`` from every collider (or inactive).
    Returns the number of points within ``dhat``.
    """
    m = nodes.shape[0]
    touching = np.zeros(m, dtype=np.int64)
    no_grad = np.zeros((0, 3))
    hess = np.zeros((m, 6))
    for j in prange(m):
        for k in range(5):
            lagged[j, k] = 0.0
        if not active[j]:
            continue
        p = np.empty(3)
        p[0], p[1], p[2] = _point(x, nodes, weights, j)
        _, f0, f1, f2, mu_f = _barrier_point(p, planes, spheres, boxes, dhat, kappa[j],
                                             no_grad, hess, j)
        lam = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
        if lam > 0.0 and math.isfinite(lam):
            n0, n1, n2 = f0 / lam, f1 / lam, f2 / lam
            lagged[j, 0] = mu_f
            lagged[j, 1] = n0
            lagged[j, 2] = n1
            lagged[j, 3] = n2
            h = hess[j]
            k = (h[0] * n0 * n0 + h[3] * n1 * n1 + h[5] * n2 * n2
                 + 2.0 * (h[1] * n0 * n1 + h[2] * n0 * n2 + h[4] * n1 * n2))
            lagged[j, 4] = 2.0 * zeta * math.sqrt(max(k, 0.0) * masses[j])
            touching[j] = 1
    return touching.sum()


@njit(cache=True, inline="always")
def _friction_point(u0, u1, u2, mul, n0, n1, n2, eps, grad, hess, j):
    """Friction potential ``mu lambda f0(|u_t|)`` (J) of one point moved by ``u``; adds the
    gradient and the (positive semi-definite) Hessian when they have rows."""
    un = u0 * n0 + u1 * n1 + u2 * n2
    t0 = u0 - un * n0
    t1 = u1 - un * n1
    t2 = u2 - un * n2
    y = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    if y >= eps:
        e = mul * (y - eps / 3.0)
        g = mul / y  # f1 / y
        d = 0.0  # f1'
    else:
        r = y / eps
        e = mul * eps * (r * r - r * r * r / 3.0)
        g = mul * (2.0 - r) / eps
        d = mul * (2.0 - 2.0 * r) / eps
    if grad.shape[0] > 0:
        grad[j, 0] += g * t0
        grad[j, 1] += g * t1
        grad[j, 2] += g * t2
    if hess.shape[0] > 0:
        # g (I - n n^T - s s^T) + d s s^T, with s the unit slip (any tangent at y = 0)
        if y > 0.0:
            s0, s1, s2 = t0 / y, t1 / y, t2 / y
        else:
            s0, s1, s2 = 0.0, 0.0, 0.0
        a = d - g
        hess[j, 0] += g * (1.0 - n0 * n0) + a * s0 * s0
        hess[j, 1] += -g * n0 * n1 + a * s0 * s1
        hess[j, 2] += -g * n0 * n2 + a * s0 * s2
        hess[j, 3] += g * (1.0 - n1 * n1) + a * s1 * s1
        hess[j, 4] += -g * n1 * n2 + a * s1 * s2
        hess[j, 5] += g * (1.0 - n2 * n2) + a * s2 * s2
    return e


@njit(cache=True, inline="always")
def _normal_damping(u0, u1, u2, c, n0, n1, n2, h, grad, hess, j):
    """Dissipation ``c / (2 h) (n . u)^2`` (J) of the normal motion ``u`` of one point over a
    step ``h``; adds its gradient and Hessian when they have rows."""
    un = u0 * n0 + u1 * n1 + u2 * n2
    k = c / h
    if grad.shape[0] > 0:
        grad[j, 0] += k * un * n0
        grad[j, 1] += k * un * n1
        grad[j, 2] += k * un * n2
    if hess.shape[0] > 0:
        hess[j, 0] += k * n0 * n0
        hess[j, 1] += k * n0 * n1
        hess[j, 2] += k * n0 * n2
        hess[j, 3] += k * n1 * n1
        hess[j, 4] += k * n1 * n2
        hess[j, 5] += k * n2 * n2
    return 0.5 * k * un * un


@njit(parallel=True, cache=True)
def contact_terms(x0, dx, nodes, weights, active, planes, spheres, boxes, dhat, kappa, lagged,
                  eps, h, grad, hess, energies):
    """Barrier, friction and normal damping of every contact point for positions ``x0 + dx``.

    Writes the per-point energies (J) into ``energies`` (M,) (``inf`` for a point on or inside
    a collider); when ``grad`` (M, 3) and ``hess`` (M, 6) have rows, the per-point gradient
    and Hessian (upper triangle xx, xy, xz, yy, yz, zz) with respect to the point's position.
    """
    for j in prange(nodes.shape[0]):
        if grad.shape[0] > 0:
            grad[j, 0] = 0.0
            grad[j, 1] = 0.0
            grad[j, 2] = 0.0
        if hess.shape[0] > 0:
            for k in range(6):
                hess[j, k] = 0.0
        energies[j] = 0.0
        if not active[j]:
            continue
        p = np.empty(3)
        a0, a1, a2 = _point(x0, nodes, weights, j)
        b0, b1, b2 = _point(dx, nodes, weights, j)
        p[0] = a0 + b0
        p[1] = a1 + b1
        p[2] = a2 + b2
        e = _barrier_point(p, planes, spheres, boxes, dhat, kappa[j], grad, hess, j)[0]
        if lagged[j, 0] > 0.0:
            e += _friction_point(b0, b1, b2, lagged[j, 0], lagged[j, 1], lagged[j, 2],
                                 lagged[j, 3], eps, grad, hess, j)
        if lagged[j, 4] > 0.0:
            e += _normal_damping(b0, b1, b2, lagged[j, 4], lagged[j, 1], lagged[j, 2],
                                 lagged[j, 3], h, grad, hess, j)
        energies[j] = e


@njit(cache=True)
def scatter_to_particles(nodes, weights, grad_p, hess_p, grad, blocks):
    """Spread per-point gradients (M, 3) and Hessians (M, 6) on the particles: ``grad += W^T
    grad_p`` (N, 3), ``blocks[i] = sum_j w_ji H_j`` (N, 3, 3), a bound from above of
    ``W^T H W``; serial, in a fixed order (the same bits for any thread count)."""
    for i in range(blocks.shape[0]):
        for r in range(3):
            for q in range(3):
                blocks[i, r, q] = 0.0
    for j in range(nodes.shape[0]):
        for k in range(nodes.shape[1]):
            w = weights[j, k]
            if w == 0.0:
                continue
            i = nodes[j, k]
            grad[i, 0] += w * grad_p[j, 0]
            grad[i, 1] += w * grad_p[j, 1]
            grad[i, 2] += w * grad_p[j, 2]
            h = hess_p[j]
            blocks[i, 0, 0] += w * h[0]
            blocks[i, 0, 1] += w * h[1]
            blocks[i, 0, 2] += w * h[2]
            blocks[i, 1, 0] += w * h[1]
            blocks[i, 1, 1] += w * h[3]
            blocks[i, 1, 2] += w * h[4]
            blocks[i, 2, 0] += w * h[2]
            blocks[i, 2, 1] += w * h[4]
            blocks[i, 2, 2] += w * h[5]


@njit(cache=True, inline="always")
def _sphere_exit(q0, q1, q2, d0, d1, d2, radius):
    """Smallest ``a >= 0`` with ``|q + a d| = radius``, ``inf`` if none."""
    aa = d0 * d0 + d1 * d1 + d2 * d2
    bb = q0 * d0 + q1 * d1 + q2 * d2
    cc = q0 * q0 + q1 * q1 + q2 * q2 - radius * radius
    if aa == 0.0:
        return np.inf
    disc = bb * bb - aa * cc
    if disc < 0.0:
        return np.inf
    root = math.sqrt(disc)
    if cc > 0.0:  # outside the sphere: enter at the first root, if ahead
        a = (-bb - root) / aa
        return a if a >= 0.0 and bb < 0.0 else np.inf
    return max((-bb + root) / aa, 0.0)  # inside: leave at the second root


@njit(cache=True, inline="always")
def _primitive_step(p, dlt, planes, spheres, boxes, c, keep):
    """Largest ``a`` in [0, 1] such that the distance to primitive ``c`` stays at least
    ``keep`` times its value at ``p`` along ``p + a dlt`` (exact for planes and spheres,
    conservative advancement for boxes: a signed distance is 1-Lipschitz)."""
    phi0 = primitive_sdf(p, planes, spheres, boxes, c)[0]
    target = keep * phi0
    length = math.sqrt(dlt[0] * dlt[0] + dlt[1] * dlt[1] + dlt[2] * dlt[2])
    if phi0 - length > target or length == 0.0:
        return 1.0
    if c < planes.shape[0]:
        rate = planes[c, 0] * dlt[0] + planes[c, 1] * dlt[1] + planes[c, 2] * dlt[2]
        return min(1.0, (target - phi0) / rate) if rate < 0.0 else 1.0
    if c < planes.shape[0] + spheres.shape[0]:
        row = spheres[c - planes.shape[0]]
        side = row[4]
        radius = row[3] + side * target  # the surface at distance target
        a = _sphere_exit(p[0] - row[0], p[1] - row[1], p[2] - row[2], dlt[0], dlt[1], dlt[2],
                         radius)
        return min(1.0, a)
    q = np.empty(3)
    a = 0.0
    for _ in range(64):
        for k in range(3):
            q[k] = p[k] + a * dlt[k]
        gap = primitive_sdf(q, planes, spheres, boxes, c)[0] - target
        if gap <= 1e-3 * (phi0 - target):
            break
        a += gap / length
        if a >= 1.0:
            return 1.0
    return a


@njit(parallel=True, cache=True)
def feasible_steps(x0, dx, d, nodes, weights, active, planes, spheres, boxes, keep, out):
    """Per contact point, the largest fraction in [0, 1] of the step ``d`` from ``x0 + dx``
    that keeps every distance at least ``keep`` times its current value, into ``out`` (M,)."""
    n_prim = planes.shape[0] + spheres.shape[0] + boxes.shape[0]
    for j in prange(nodes.shape[0]):
        out[j] = 1.0
        if not active[j]:
            continue
        p = np.empty(3)
        dlt = np.empty(3)
        a0, a1, a2 = _point(x0, nodes, weights, j)
        b0, b1, b2 = _point(dx, nodes, weights, j)
        p[0] = a0 + b0
        p[1] = a1 + b1
        p[2] = a2 + b2
        dlt[0], dlt[1], dlt[2] = _point(d, nodes, weights, j)
        a = 1.0
        for c in range(n_prim):
            a = min(a, _primitive_step(p, dlt, planes, spheres, boxes, c, keep))
        out[j] = a


@njit(parallel=True, cache=True)
def barrier_energies(x, nodes, weights, active, planes, spheres, boxes, dhat, kappa, out):
    """Barrier (contact) energy (J) of every contact point at positions ``x`` into ``out``."""
    no_grad = np.zeros((0, 3))
    no_hess = np.zeros((0, 6))
    for j in prange(nodes.shape[0]):
        out[j] = 0.0
        if not active[j]:
            continue
        p = np.empty(3)
        p[0], p[1], p[2] = _point(x, nodes, weights, j)
        out[j] = _barrier_point(p, planes, spheres, boxes, dhat, kappa[j], no_grad, no_hess,
                                j)[0]


@njit(parallel=True, cache=True)
def contact_clearance(x, nodes, weights, planes, spheres, boxes, out):
    """Signed distance (m) of every contact point to the union of the colliders into ``out``."""
    for j in prange(nodes.shape[0]):
        p = np.empty(3)
        p[0], p[1], p[2] = _point(x, nodes, weights, j)
        best = np.inf
        for c in range(planes.shape[0] + spheres.shape[0] + boxes.shape[0]):
            best = min(best, primitive_sdf(p, planes, spheres, boxes, c)[0])
        out[j] = best
