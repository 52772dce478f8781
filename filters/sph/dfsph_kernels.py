"""Numba kernels of the DFSPH solves (:mod:`filters.sph.dfsph` describes the method).

All loops are gathers over the particle's own fixed-order neighbour list inside ``prange`` (no
scatter, no atomics) and every reduction is a per-particle array summed serially, so results are
bit-identical for any thread count.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .wall_profile import equivalent_distance

__all__ = ["density_rate", "pressure_accel", "pressure_accel_wall", "jacobi", "jacobi_wall",
           "density_start", "divergence_start", "wall_start", "wall_approach", "kick", "store",
           "drift", "NO_WALL", "DEGENERATE_WALL", "OPPOSED_WALLS"]

#: Marks a wall constraint that does not apply (no boundary near enough).
NO_WALL = 1e30
#: A wall constraint whose gradient ``|cgb_ik|`` is below this fraction of the flat-wall slope
#: ``g`` at its ``phi_ik`` is dropped: boundary on opposite sides of the particle whose
#: gradients cancel (the whole boundary's cluster in a film between a body and the floor), so
#: that moving the particle hardly changes ``phi_ik``; enforcing it would take a wall pressure
#: of ``slack / |cgb|^2`` and kick the particle by ``slack / |cgb|`` in whatever direction the
#: remainder points.
DEGENERATE_WALL = 0.1
#: Cosine below minus which the gradients of two single-wall constraints of a particle count as
#: opposed (walls on opposite sides of it, 135 degrees and more apart); both are dropped.
OPPOSED_WALLS = 0.7


@njit(parallel=True, cache=True, error_model="numpy")
def density_rate(v, x, ntab, ncnt, fw, gsum, vrate, out):
    """``(D rho_i / D t) / rho0 = sum_j V_j (v_i - v_j) . grad W_ij + sum_b V_b (v_i - v_b) .
    grad W_ib = v_i . gsum_i - sum_j fw_ij v_j . (x_i - x_j) - vrate_i`` (1/s), with ``vrate_i
    = sum_b V_b v_b . grad W_ib`` the moving boundary's part."""
    for i in prange(v.shape[0]):
        xi = x[i, 0]
        yi = x[i, 1]
        zi = x[i, 2]
        s = v[i, 0] * gsum[i, 0] + v[i, 1] * gsum[i, 1] + v[i, 2] * gsum[i, 2] - vrate[i]
        for k in range(ncnt[i]):
            j = ntab[i, k]
            s -= fw[i, k] * (v[j, 0] * (xi - x[j, 0]) + v[j, 1] * (yi - x[j, 1])
                             + v[j, 2] * (zi - x[j, 2]))
        out[i] = s


@njit(parallel=True, cache=True, error_model="numpy")
def pressure_accel(pi, x, ntab, ncnt, fw, gsum, a):
    """``a_i = -sum_j (pi_i + pi_j) V_j grad W_ij - pi_i sum_b V_b grad W_ib
    = -pi_i gsum_i - sum_j pi_j fw_ij (x_i - x_j)`` (m/s^2)."""
    for i in prange(pi.shape[0]):
        xi = x[i, 0]
        yi = x[i, 1]
        zi = x[i, 2]
        p = pi[i]
        ax = -p * gsum[i, 0]
        ay = -p * gsum[i, 1]
        az = -p * gsum[i, 2]
        for k in range(ncnt[i]):
            j = ntab[i, k]
            f = pi[j] * fw[i, k]
            ax -= f * (xi - x[j, 0])
            ay -= f * (yi - x[j, 1])
            az -= f * (zi - x[j, 2])
        a[i, 0] = ax
        a[i, 1] = ay
        a[i, 2] = az


@njit(parallel=True, cache=True, error_model="numpy")
def jacobi(a, x, src, pi, factor, active, ntab, ncnt, fw, gsum, scale, omega, err):
    """One relaxed Jacobi update of ``pi`` (see the module docstring); ``err[i]`` gets the
    predicted compression before the update.  Returns the mean and the largest of ``err``
    (serial reductions)."""
    n = pi.shape[0]
    inv = 1.0 / scale
    for i in prange(n):
        xi = x[i, 0]
        yi = x[i, 1]
        zi = x[i, 2]
        s = a[i, 0] * gsum[i, 0] + a[i, 1] * gsum[i, 1] + a[i, 2] * gsum[i, 2]
        for k in range(ncnt[i]):
            j = ntab[i, k]
            s -= fw[i, k] * (a[j, 0] * (xi - x[j, 0]) + a[j, 1] * (yi - x[j, 1])
                             + a[j, 2] * (zi - x[j, 2]))
        r = src[i] - scale * s
        err[i] = -r if (r < 0.0 and active[i]) else 0.0
        pi[i] = max(pi[i] - omega * r * factor[i] * inv, 0.0)
    total = 0.0
    peak = 0.0
    for i in range(n):
        total += err[i]
        peak = max(peak, err[i])
    return (total / n if n else 0.0), peak


@njit(parallel=True, cache=True, error_model="numpy")
def pressure_accel_wall(pi, pw, x, ntab, ncnt, fw, gsum, ncl, cgb, a):
    """:func:`pressure_accel` plus the wall pressures: ``a_i -= sum_k pw_ik cgb_ik`` (m/s^2),
    ``cgb_ik = sum_{b in wall k} V_b grad W_ib``."""
    for i in prange(pi.shape[0]):
        xi = x[i, 0]
        yi = x[i, 1]
        zi = x[i, 2]
        p = pi[i]
        ax = -p * gsum[i, 0]
        ay = -p * gsum[i, 1]
        az = -p * gsum[i, 2]
        for k in range(ncl[i]):
            q = pw[i, k]
            ax -= q * cgb[i, k, 0]
            ay -= q * cgb[i, k, 1]
            az -= q * cgb[i, k, 2]
        for k in range(ncnt[i]):
            j = ntab[i, k]
            f = pi[j] * fw[i, k]
            ax -= f * (xi - x[j, 0])
            ay -= f * (yi - x[j, 1])
            az -= f * (zi - x[j, 2])
        a[i, 0] = ax
        a[i, 1] = ay
        a[i, 2] = az


@njit(parallel=True, cache=True, error_model="numpy")
def jacobi_wall(a, x, src, pi, factor, ntab, ncnt, fw, gsum, scale, omega, err, wsrc, pw, ncl,
                cgb, werr):
    """One relaxed Jacobi update of the density solve's ``pi`` (as :func:`jacobi`) and of the
    wall pressures ``pw`` (see :mod:`filters.sph.dfsph`).  A particle's own unknowns are
    updated one after the other (Gauss-Seidel within the particle: its walls in a corner push
    it along overlapping directions and would overshoot together), each seeing the
    acceleration the previous ones changed: with ``r_ik = wsrc_ik - scale a_i . cgb_ik`` the
    slack left to wall ``k``, ``pw_ik <- max(pw_ik - omega r_ik / (scale |cgb_ik|^2), 0)``.
    ``err`` gets the predicted compressions, ``werr`` each particle's largest wall violation
    (fraction of the kernel).  Returns the mean and the largest compression and the largest
    violation (serial reductions)."""
    n = pi.shape[0]
    inv = 1.0 / scale
    for i in prange(n):
        xi = x[i, 0]
        yi = x[i, 1]
        zi = x[i, 2]
        s = a[i, 0] * gsum[i, 0] + a[i, 1] * gsum[i, 1] + a[i, 2] * gsum[i, 2]
        for k in range(ncnt[i]):
            j = ntab[i, k]
            s -= fw[i, k] * (a[j, 0] * (xi - x[j, 0]) + a[j, 1] * (yi - x[j, 1])
                             + a[j, 2] * (zi - x[j, 2]))
        r = src[i] - scale * s
        err[i] = -r if r < 0.0 else 0.0
        old = pi[i]
        pi[i] = max(old - omega * r * factor[i] * inv, 0.0)
        worst = 0.0
        if ncl[i] > 0:
            d = pi[i] - old  # the particle's own acceleration after this update
            ax = a[i, 0] - d * gsum[i, 0]
            ay = a[i, 1] - d * gsum[i, 1]
            az = a[i, 2] - d * gsum[i, 2]
            for k in range(ncl[i]):
                if wsrc[i, k] < NO_WALL:
                    gx = cgb[i, k, 0]
                    gy = cgb[i, k, 1]
                    gz = cgb[i, k, 2]
                    rk = wsrc[i, k] - scale * (ax * gx + ay * gy + az * gz)
                    worst = max(worst, -rk)
                    q = max(pw[i, k] - omega * rk * inv / (gx * gx + gy * gy + gz * gz), 0.0)
                    d = q - pw[i, k]
                    pw[i, k] = q
                    ax -= d * gx
                    ay -= d * gy
                    az -= d * gz
        werr[i] = worst
    total = 0.0
    peak = 0.0
    top = 0.0
    for i in range(n):
        total += err[i]
        peak = max(peak, err[i])
        top = max(top, werr[i])
    return (total / n if n else 0.0), peak, top


@njit(parallel=True, cache=True, error_model="numpy")
def wall_start(v, ncl, cphi, cgb, cvb, dt, fraction, dmin, reach, inv_d, inv_s, wsrc, pw):
    """Wall constraints of the density solve, per particle ``i`` and wall ``k``: with ``(d, g)``
    the equivalent distance of the wall and its slope (:func:`filters.sph.wall_profile.
    equivalent_distance`), the slack ``(d - dmin_k) g - dt (v_i . cgb_ik - cvb_ik)``
    (fraction of the kernel) that the particle's approach may use up, or :data:`NO_WALL` beyond
    ``dmin_k + reach``; ``dmin`` holds ``dmin_k`` for the whole boundary (k = 0) and for single
    walls (k >= 1).  The wall pressures start at 0.  With ``fraction < 1`` a violated constraint
    (``d < dmin_k``) asks for only that fraction of its violation back in this step."""
    for i in prange(v.shape[0]):
        for k in range(wsrc.shape[1]):
            pw[i, k] = 0.0
            wsrc[i, k] = NO_WALL
        for k in range(ncl[i]):
            gx = cgb[i, k, 0]
            gy = cgb[i, k, 1]
            gz = cgb[i, k, 2]
            g2 = gx * gx + gy * gy + gz * gz
            if cphi[i, k] <= 0.0 or g2 <= 0.0:
                continue
            d, g = equivalent_distance(cphi[i, k], inv_d, inv_s)
            dm = dmin[0] if k == 0 else dmin[1]
            if d > dm + reach or g2 < (DEGENERATE_WALL * g) ** 2:
                continue
            gap = d - dm
            if fraction < 1.0 and gap < 0.0:
                gap *= fraction
            wsrc[i, k] = gap * g - dt * (v[i, 0] * gx + v[i, 1] * gy + v[i, 2] * gz
                                         - cvb[i, k])
        # two single walls on opposite sides of the particle (a film under a landing body):
        # it cannot keep its distance to both, and two opposed wall pressures would only
        # escalate against each other; the density solve alone squeezes the film out
        for k in range(1, ncl[i]):
            if wsrc[i, k] >= NO_WALL:
                continue
            for q in range(k + 1, ncl[i]):
                if wsrc[i, q] >= NO_WALL:
                    continue
                dot = (cgb[i, k, 0] * cgb[i, q, 0] + cgb[i, k, 1] * cgb[i, q, 1]
                       + cgb[i, k, 2] * cgb[i, q, 2])
                nk = cgb[i, k, 0] ** 2 + cgb[i, k, 1] ** 2 + cgb[i, k, 2] ** 2
                nq = cgb[i, q, 0] ** 2 + cgb[i, q, 1] ** 2 + cgb[i, q, 2] ** 2
                if dot < 0.0 and dot * dot > OPPOSED_WALLS * OPPOSED_WALLS * nk * nq:
                    wsrc[i, k] = NO_WALL
                    wsrc[i, q] = NO_WALL


@njit(parallel=True, cache=True, error_model="numpy")
def density_start(rho, rate, rho0, dt, fraction, pi_prev, cap, warm, src, pi, active):
    """Density solve set-up: source ``1 - rho*/rho0`` with ``rho* = rho + dt D rho / D t`` and
    the warm start ``pi = warm min(pi_prev, cap / dt^2)`` where compressed, else 0.  With
    ``fraction < 1`` only that fraction of the density error the particles start with is
    removed in this step (``rho*/rho0 = 1 + fraction (rho/rho0 - 1) + dt D rho / D t / rho0``)."""
    inv2 = 1.0 / (dt * dt)
    for i in prange(rho.shape[0]):
        if fraction < 1.0:
            adv = 1.0 + fraction * (rho[i] / rho0 - 1.0) + dt * rate[i]
        else:
            adv = rho[i] / rho0 + dt * rate[i]
        src[i] = 1.0 - adv
        active[i] = True
        pi[i] = warm * min(pi_prev[i], cap * inv2) if adv > 1.0 else 0.0


@njit(parallel=True, cache=True, error_model="numpy")
def divergence_start(rate, nnb, min_nb, dt, kappa_v, cap, src, pi, active):
    """Divergence solve set-up: source ``-max(D rho / D t, 0) / rho0`` (0 for particles with
    fewer than ``min_nb`` neighbours) and the warm start ``pi = 0.5 min(kappa_v, cap) / dt``."""
    inv = 1.0 / dt
    for i in prange(rate.shape[0]):
        ok = nnb[i] >= min_nb
        d = max(rate[i], 0.0) if ok else 0.0
        src[i] = -d
        active[i] = ok
        pi[i] = 0.5 * min(kappa_v[i], cap) * inv if d > 0.0 else 0.0


@njit(parallel=True, cache=True, error_model="numpy")
def kick(v, a, dt):
    """``v += dt a``."""
    for i in prange(v.shape[0]):
        for c in range(3):
            v[i, c] += dt * a[i, c]


@njit(parallel=True, cache=True, error_model="numpy")
def store(pi, scale, kappa):
    """``kappa = pi * scale`` (the stored warm start)."""
    for i in prange(pi.shape[0]):
        kappa[i] = pi[i] * scale


@njit(parallel=True, cache=True, error_model="numpy")
def drift(x, v, dt):
    """``x += dt v``; returns ``max |v|`` (m/s)."""
    n = x.shape[0]
    vmax = np.zeros(n)
    for i in prange(n):
        s = 0.0
        for c in range(3):
            x[i, c] += dt * v[i, c]
            s += v[i, c] * v[i, c]
        vmax[i] = s
    best = 0.0
    for i in range(n):
        best = max(best, vmax[i])
    return math.sqrt(best)


@njit(parallel=True, cache=True, error_model="numpy")
def wall_approach(v, ncl, cphi, cgb, cvb, reach, inv_d, inv_s):
    """Largest speed (m/s) at which a particle within the equivalent distance ``reach`` (m) of
    a single wall (clusters ``k >= 1``) moves towards it: ``(v_i . cgb_ik - cvb_ik) / g(d_ik)``
    (the rate of change of ``phi_ik`` over the flat-wall slope)."""
    n = v.shape[0]
    out = np.zeros(n)
    for i in prange(n):
        best = 0.0
        for k in range(1, ncl[i]):
            if cphi[i, k] <= 0.0:
                continue
            d, g = equivalent_distance(cphi[i, k], inv_d, inv_s)
            if d > reach or g <= 0.0:
                continue
            rate = (v[i, 0] * cgb[i, k, 0] + v[i, 1] * cgb[i, k, 1] + v[i, 2] * cgb[i, k, 2]
                    - cvb[i, k]) / g
            best = max(best, rate)
        out[i] = best
    top = 0.0
    for i in range(n):
        top = max(top, out[i])
    return top
