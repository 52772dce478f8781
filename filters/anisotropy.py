"""Per-particle anisotropic kernels for flat liquid surfaces (Yu & Turk 2013), in Numba.

Yu & Turk (2013), "Reconstructing surfaces of particle-based fluids using anisotropic
kernels", ACM Transactions on Graphics 32(1):5. For every particle ``i`` with neighbours
``j`` within the neighbourhood radius ``r_i`` (the particle itself included):

* weights ``w_ij = 1 - (|x_i - x_j| / r_i)^3`` for ``|x_i - x_j| < r_i``, else 0 (their Eq. 11);
* weighted mean ``xw_i = sum_j w_ij x_j / sum_j w_ij`` and weighted covariance
  ``C_i = sum_j w_ij (x_j - xw_i)(x_j - xw_i)^T / sum_j w_ij`` (Eqs. 9-10);
* eigen-decomposition ``C_i = R diag(s_1, s_2, s_3) R^T`` with ``s_1 >= s_2 >= s_3`` (cyclic
  Jacobi rotations, deterministic);
* clamped stretch: ``t_k = max(s_k, s_1 / k_r)`` (Eq. 15), so no axis is more than ``k_r``
  times shorter than the longest;
* particles with fewer than ``N_eps`` neighbours ("isolated", splashes) keep the spherical
  kernel;
* the kernel matrix ``G_i = (1 / h_i) R diag(c / t_1, c / t_2, c / t_3) R^T`` with the kernel's
  support radius ``h_i``, and the kernel
  ``W(x - xbar_i, G_i) = det(G_i) P(|G_i (x - xbar_i)|)`` (Eq. 7), which integrates to the same
  mass whatever the scale of ``G_i``.

Scale. Yu & Turk scale ``diag(t)`` by a global constant ``k_s`` (1400 in their scenes). Here
``c = (t_1 t_2 t_3)^(1/3)`` per particle, so that ``det(G_i) = 1 / h_i^3``: every ellipsoid
encloses the volume of the isotropic kernel it replaces, and a particle in a uniform
neighbourhood (isotropic covariance) gets *exactly* the isotropic kernel. A cap keeps the
longest semi-axis at ``max_axis * h_i`` (default 1.6: a flat surface's ``k_r^(1/3) = 1.587``
passes, line-like neighbourhoods at the liquid's edges, which would reach ``k_r^(2/3) = 2.52``,
are scaled down), so that the splat reaches no farther than two blocks, like the isotropic one.
(Scaling the longest axis to ``h``, Yu & Turk's shape, was measured to leave dimples between
the surface particles at iso 0.6: RMS 0.30 spacings on a flat pool against 0.02.) Isolated
particles get ``G_i = I / h_i`` (Yu & Turk shrink them by ``k_n``; we keep the isotropic kernel,
so a lone droplet has the radius :func:`filters.splat.lone_particle_radius` predicts).

Smoothed centres (Laplacian smoothing, their Eq. 6): ``xbar_i = (1 - lambda) x_i +
lambda xw_i`` with ``lambda`` about 0.9; this removes the jitter of surface particles. The plain
weighted mean of a particle on a free surface lies inside the liquid (its neighbourhood is a
half ball): on a flat pool it pulls the top layer down by half a spacing, shrinking a ball of
radius 7 spacings by 19 % in volume (measured). Where the covariance is anisotropic (smallest
over largest eigenvalue below 0.85, i.e. near a surface) the mean is therefore taken over the
slab ``|(x_j - x_i) . n_i| < layer_band * r_i`` about the particle's tangent plane (``n_i`` the
axis of least variance, weights ``w_ij (1 - (d_n / band)^2)``): the particle's own layer, whose
mean height is the surface's, without the layers below. With the default slab (0.8 spacings)
and iso 0.55 the same ball keeps its volume within 1 % (measured -0.9 %, -0.5 % for radius 6 spacings).

The neighbour lists come from :class:`filters.neighbors.NeighborSearch` (grid backend, stable
counting sort), and every particle's sums run over its list in that fixed order, so the output
is bitwise identical for any number of threads.
"""

from __future__ import annotations

import math
import numbers

import numpy as np
from numba import njit, prange

from .neighbors import NeighborSearch
from .validation import check_choice, check_int, check_points, check_range

__all__ = ["anisotropic_kernels", "kernel_axes", "DEFAULTS"]

#: Defaults of :func:`anisotropic_kernels` (see its docstring).
DEFAULTS = {
    "neighbor_factor": 2.5,   # neighbourhood radius / particle spacing 2 r
    "stretch": 4.0,           # k_r
    "min_neighbors": 15,      # N_eps (self excluded)
    "smoothing": 0.9,         # lambda
    "layer_band": 1.6,        # slab half-width of the centre smoothing / particle radius r
    "max_axis": 1.6,          # longest semi-axis / h
}



#: Layer smoothing applies where the covariance is anisotropic, smallest / largest eigenvalue
#: below this (near a free surface); inside the liquid the plain mean is unbiased already.
_LAYER_RATIO = 0.85

# --------------------------------------------------------------------------------------------
# 3x3 symmetric eigen-decomposition (cyclic Jacobi)
# --------------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _jacobi3(a, v):
    """Eigen-decomposition of the symmetric 3x3 ``a`` (overwritten: its diagonal ends up holding
    the eigenvalues); ``v`` (3, 3) receives the eigenvectors as columns. Cyclic Jacobi sweeps
    (Golub & Van Loan, Alg. 8.4.3) until the off-diagonal part is below 1e-30 relative."""
    for i in range(3):
        for j in range(3):
            v[i, j] = 1.0 if i == j else 0.0
    for _sweep in range(32):
        off = a[0, 1] * a[0, 1] + a[0, 2] * a[0, 2] + a[1, 2] * a[1, 2]
        diag = a[0, 0] * a[0, 0] + a[1, 1] * a[1, 1] + a[2, 2] * a[2, 2]
        if off <= 1e-30 * diag or off == 0.0:
            break
        for p in range(2):
            for q in range(p + 1, 3):
                apq = a[p, q]
                if apq == 0.0:
                    continue
                theta = (a[q, q] - a[p, p]) / (2.0 * apq)
                t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + math.sqrt(theta * theta + 1.0))
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                for k in range(3):
                    akp = a[k, p]
                    akq = a[k, q]
                    a[k, p] = c * akp - s * akq
                    a[k, q] = s * akp + c * akq
                for k in range(3):
                    apk = a[p, k]
                    aqk = a[q, k]
                    a[p, k] = c * apk - s * aqk
                    a[q, k] = s * apk + c * aqk
                for k in range(3):
                    vkp = v[k, p]
                    vkq = v[k, q]
                    v[k, p] = c * vkp - s * vkq
                    v[k, q] = s * vkp + c * vkq


@njit(cache=True, inline="always")
def _spline(q2):
    """Monaghan's (1992) cubic spline of ``q = |r| / h`` with peak 1 (support 1)."""
    if q2 >= 1.0:
        return 0.0
    q = math.sqrt(q2)
    if q < 0.5:
        return 1.0 - 6.0 * q2 + 6.0 * q2 * q
    t = 1.0 - q
    return 2.0 * t * t * t


@njit(parallel=True, cache=True)
def _anisotropy(x, offsets, indices, rn, hs, band, mass, kr, neps, lam, amax, centres, G,
                volumes):
    n = x.shape[0]
    for i in prange(n):
        xi0 = x[i, 0]
        xi1 = x[i, 1]
        xi2 = x[i, 2]
        r = rn[i]
        inv_r = 1.0 / r
        # the particle itself: w = 1
        ws = 1.0
        m0 = xi0
        m1 = xi1
        m2 = xi2
        count = 0
        hi = hs[i]
        rho_norm = mass[i] / (hi * hi * hi)  # self term, K(0) = 1
        for k in range(offsets[i], offsets[i + 1]):
            j = indices[k]
            d0 = x[j, 0] - xi0
            d1 = x[j, 1] - xi1
            d2 = x[j, 2] - xi2
            dd = d0 * d0 + d1 * d1 + d2 * d2
            hh = 0.5 * (hi + hs[j])
            q2 = dd / (hh * hh)
            if q2 < 1.0:
                rho_norm += mass[j] * _spline(q2) / (hh * hh * hh)
            d = math.sqrt(dd) * inv_r
            if d < 1.0:
                w = 1.0 - d * d * d
                ws += w
                m0 += w * x[j, 0]
                m1 += w * x[j, 1]
                m2 += w * x[j, 2]
                count += 1
        rho = rho_norm
        volumes[i] = mass[i] / rho * (math.pi / 8.0)  # V = m / rho with rho = sum m 8/(pi h^3) K
        m0 /= ws
        m1 /= ws
        m2 /= ws
        centres[i, 0] = (1.0 - lam) * xi0 + lam * m0
        centres[i, 1] = (1.0 - lam) * xi1 + lam * m1
        centres[i, 2] = (1.0 - lam) * xi2 + lam * m2
        inv_h = 1.0 / hi
        if count < neps:
            for a in range(3):
                for b in range(3):
                    G[i, a, b] = inv_h if a == b else 0.0
            continue
        c = np.zeros((3, 3))
        # self term
        e0 = xi0 - m0
        e1 = xi1 - m1
        e2 = xi2 - m2
        c[0, 0] = e0 * e0
        c[0, 1] = e0 * e1
        c[0, 2] = e0 * e2
        c[1, 1] = e1 * e1
        c[1, 2] = e1 * e2
        c[2, 2] = e2 * e2
        for k in range(offsets[i], offsets[i + 1]):
            j = indices[k]
            d0 = x[j, 0] - xi0
            d1 = x[j, 1] - xi1
            d2 = x[j, 2] - xi2
            d = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) * inv_r
            if d < 1.0:
                w = 1.0 - d * d * d
                e0 = x[j, 0] - m0
                e1 = x[j, 1] - m1
                e2 = x[j, 2] - m2
                c[0, 0] += w * e0 * e0
                c[0, 1] += w * e0 * e1
                c[0, 2] += w * e0 * e2
                c[1, 1] += w * e1 * e1
                c[1, 2] += w * e1 * e2
                c[2, 2] += w * e2 * e2
        c[1, 0] = c[0, 1]
        c[2, 0] = c[0, 2]
        c[2, 1] = c[1, 2]
        v = np.empty((3, 3))
        _jacobi3(c, v)
        s0 = c[0, 0]
        s1 = c[1, 1]
        s2 = c[2, 2]
        smax = max(s0, s1, s2)
        if band[i] > 0.0 and min(s0, s1, s2) < _LAYER_RATIO * smax:
            # layer smoothing: the weighted mean over the slab |(x_j - x_i) . n| < band about
            # the tangent plane (n: the axis of least variance), which removes the jitter
            # without pulling surface particles inward (see the module docstring)
            kmin = 0 if (s0 <= s1 and s0 <= s2) else (1 if s1 <= s2 else 2)
            n0 = v[0, kmin]
            n1 = v[1, kmin]
            n2 = v[2, kmin]
            inv_b2 = 1.0 / (band[i] * band[i])
            ws = 1.0
            m0 = xi0
            m1 = xi1
            m2 = xi2
            for k in range(offsets[i], offsets[i + 1]):
                j = indices[k]
                d0 = x[j, 0] - xi0
                d1 = x[j, 1] - xi1
                d2 = x[j, 2] - xi2
                d = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) * inv_r
                dn = d0 * n0 + d1 * n1 + d2 * n2
                b = 1.0 - dn * dn * inv_b2
                if d < 1.0 and b > 0.0:
                    w = (1.0 - d * d * d) * b
                    ws += w
                    m0 += w * x[j, 0]
                    m1 += w * x[j, 1]
                    m2 += w * x[j, 2]
            centres[i, 0] = (1.0 - lam) * xi0 + lam * m0 / ws
            centres[i, 1] = (1.0 - lam) * xi1 + lam * m1 / ws
            centres[i, 2] = (1.0 - lam) * xi2 + lam * m2 / ws
        if not smax > 0.0:
            for a in range(3):
                for b in range(3):
                    G[i, a, b] = inv_h if a == b else 0.0
            continue
        floor = smax / kr
        t0 = max(s0, floor)
        t1 = max(s1, floor)
        t2 = max(s2, floor)
        scale = max((t0 * t1 * t2) ** (1.0 / 3.0), max(t0, t1, t2) / amax)
        g0 = scale / t0 * inv_h
        g1 = scale / t1 * inv_h
        g2 = scale / t2 * inv_h
        for a in range(3):
            for b in range(a, 3):
                val = g0 * v[a, 0] * v[b, 0] + g1 * v[a, 1] * v[b, 1] + g2 * v[a, 2] * v[b, 2]
                G[i, a, b] = val
                G[i, b, a] = val


@njit(cache=True, inline="always")
def _cells(q, origin, inv_cell, dim, reach):
    f = math.floor((q - origin) * inv_cell)
    lo = min(max(f - reach, 0.0), float(dim))
    hi = max(min(f + reach, dim - 1.0), -1.0)
    return int(lo), int(hi)


@njit(cache=True, inline="always")
def _gap1(q, lo, hi):
    if q < lo:
        return lo - q
    if q > hi:
        return q - hi
    return 0.0


@njit(parallel=True, cache=True)
def _anisotropy_grid(sx, order, start, origin, cell, dims, reach, search2, rn, hs, band, mass,
                     kr, neps, lam, amax, centres, G, volumes):
    """:func:`_anisotropy` on the cell-sorted points of a :class:`NeighborSearch` grid: the
    neighbours are visited cell by cell (fixed order) without building lists, and the mean and
    covariance come from one pass (``C = sum w d d^T / W - mu mu^T`` with ``d = x_j - x_i``).
    Inputs ``rn, hs, band, mass`` are in sorted order; outputs go to the original indices."""
    n = sx.shape[0]
    inv_cell = 1.0 / cell
    for t in prange(n):
        q0 = sx[t, 0]
        q1 = sx[t, 1]
        q2_ = sx[t, 2]
        x0, x1 = _cells(q0, origin[0], inv_cell, dims[0], reach)
        y0, y1 = _cells(q1, origin[1], inv_cell, dims[1], reach)
        z0, z1 = _cells(q2_, origin[2], inv_cell, dims[2], reach)
        inv_r = 1.0 / rn[t]
        hi = hs[t]
        rho = mass[t] / (hi * hi * hi)
        ws = 1.0
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        c00 = 0.0
        c01 = 0.0
        c02 = 0.0
        c11 = 0.0
        c12 = 0.0
        c22 = 0.0
        count = 0
        for iz in range(z0, z1 + 1):
            gz = _gap1(q2_, origin[2] + iz * cell, origin[2] + (iz + 1) * cell)
            for iy in range(y0, y1 + 1):
                gy = _gap1(q1, origin[1] + iy * cell, origin[1] + (iy + 1) * cell)
                if gy * gy + gz * gz > search2:
                    continue
                row = (iz * dims[1] + iy) * dims[0]
                for k in range(start[row + x0], start[row + x1 + 1]):
                    if k == t:
                        continue
                    d0 = sx[k, 0] - q0
                    d1 = sx[k, 1] - q1
                    d2 = sx[k, 2] - q2_
                    dd = d0 * d0 + d1 * d1 + d2 * d2
                    if dd > search2:
                        continue
                    hh = 0.5 * (hi + hs[k])
                    qq = dd / (hh * hh)
                    if qq < 1.0:
                        rho += mass[k] * _spline(qq) / (hh * hh * hh)
                    d = math.sqrt(dd) * inv_r
                    if d < 1.0:
                        w = 1.0 - d * d * d
                        ws += w
                        a0 += w * d0
                        a1 += w * d1
                        a2 += w * d2
                        c00 += w * d0 * d0
                        c01 += w * d0 * d1
                        c02 += w * d0 * d2
                        c11 += w * d1 * d1
                        c12 += w * d1 * d2
                        c22 += w * d2 * d2
                        count += 1
        i = order[t]
        volumes[i] = mass[t] / rho * (math.pi / 8.0)
        mu0 = a0 / ws
        mu1 = a1 / ws
        mu2 = a2 / ws
        centres[i, 0] = q0 + lam * mu0
        centres[i, 1] = q1 + lam * mu1
        centres[i, 2] = q2_ + lam * mu2
        inv_h = 1.0 / hi
        if count < neps:
            for a in range(3):
                for b in range(3):
                    G[i, a, b] = inv_h if a == b else 0.0
            continue
        c = np.empty((3, 3))
        c[0, 0] = c00 / ws - mu0 * mu0
        c[0, 1] = c01 / ws - mu0 * mu1
        c[0, 2] = c02 / ws - mu0 * mu2
        c[1, 1] = c11 / ws - mu1 * mu1
        c[1, 2] = c12 / ws - mu1 * mu2
        c[2, 2] = c22 / ws - mu2 * mu2
        c[1, 0] = c[0, 1]
        c[2, 0] = c[0, 2]
        c[2, 1] = c[1, 2]
        v = np.empty((3, 3))
        _jacobi3(c, v)
        s0 = c[0, 0]
        s1 = c[1, 1]
        s2 = c[2, 2]
        smax = max(s0, s1, s2)
        if band[t] > 0.0 and min(s0, s1, s2) < _LAYER_RATIO * smax:
            kmin = 0 if (s0 <= s1 and s0 <= s2) else (1 if s1 <= s2 else 2)
            n0 = v[0, kmin]
            n1 = v[1, kmin]
            n2 = v[2, kmin]
            inv_b2 = 1.0 / (band[t] * band[t])
            ws = 1.0
            a0 = 0.0
            a1 = 0.0
            a2 = 0.0
            for iz in range(z0, z1 + 1):
                gz = _gap1(q2_, origin[2] + iz * cell, origin[2] + (iz + 1) * cell)
                for iy in range(y0, y1 + 1):
                    gy = _gap1(q1, origin[1] + iy * cell, origin[1] + (iy + 1) * cell)
                    if gy * gy + gz * gz > search2:
                        continue
                    row = (iz * dims[1] + iy) * dims[0]
                    for k in range(start[row + x0], start[row + x1 + 1]):
                        if k == t:
                            continue
                        d0 = sx[k, 0] - q0
                        d1 = sx[k, 1] - q1
                        d2 = sx[k, 2] - q2_
                        dn = d0 * n0 + d1 * n1 + d2 * n2
                        b = 1.0 - dn * dn * inv_b2
                        if b <= 0.0:
                            continue
                        d = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) * inv_r
                        if d < 1.0:
                            w = (1.0 - d * d * d) * b
                            ws += w
                            a0 += w * d0
                            a1 += w * d1
                            a2 += w * d2
            centres[i, 0] = q0 + lam * a0 / ws
            centres[i, 1] = q1 + lam * a1 / ws
            centres[i, 2] = q2_ + lam * a2 / ws
        if not smax > 0.0:
            for a in range(3):
                for b in range(3):
                    G[i, a, b] = inv_h if a == b else 0.0
            continue
        floor = smax / kr
        t0 = max(s0, floor)
        t1 = max(s1, floor)
        t2 = max(s2, floor)
        scale = max((t0 * t1 * t2) ** (1.0 / 3.0), max(t0, t1, t2) / amax)
        g0 = scale / t0 * inv_h
        g1 = scale / t1 * inv_h
        g2 = scale / t2 * inv_h
        for a in range(3):
            for b in range(a, 3):
                val = g0 * v[a, 0] * v[b, 0] + g1 * v[a, 1] * v[b, 1] + g2 * v[a, 2] * v[b, 2]
                G[i, a, b] = val
                G[i, b, a] = val


def _radii(name, radius, n):
    if isinstance(radius, numbers.Real) and not isinstance(radius, bool):
        r = check_range(name, radius, 0.0, math.inf, low_inclusive=False)
        if not math.isfinite(r):
            raise ValueError(f"{name} must be finite, got {radius!r}")
        return np.full(n, r)
    try:
        radii = np.ascontiguousarray(radius, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a positive number or an (N,) array") from None
    if radii.shape != (n,):
        raise ValueError(f"{name} must be a number or have shape ({n},), got {radii.shape}")
    if n and not (np.isfinite(radii).all() and radii.min() > 0):
        raise ValueError(f"{name} must be finite and > 0 for every particle")
    return radii


def anisotropic_kernels(positions, radius, *, support: float = 4.0,
                        neighbor_factor: float = DEFAULTS["neighbor_factor"],
                        stretch: float = DEFAULTS["stretch"],
                        min_neighbors: int = DEFAULTS["min_neighbors"],
                        smoothing: float = DEFAULTS["smoothing"],
                        layer_band: float = DEFAULTS["layer_band"],
                        max_axis: float = DEFAULTS["max_axis"], return_volumes: bool = False,
                        backend: str = "auto"):
    """Smoothed kernel centres and anisotropy matrices (Yu & Turk 2013).

    Parameters
    ----------
    positions : (N, 3) float64
        Particle centres (m); NaN or infinite values raise ValueError.
    radius : float or (N,) float64
        Particle radii ``r`` (m), > 0.
    support : float
        Kernel support radius over particle radius, ``h = support * r`` (as in
        :func:`filters.splat.splat_sparse`; 4 for the ``sph`` kernel), in (0, 1000].
    neighbor_factor : float
        Neighbourhood radius for the covariance and the smoothing over the *particle spacing*
        ``2 r``: ``r_i = neighbor_factor * 2 r_i`` (m), in [1, 10]. The default 2.5 holds about
        80 neighbours inside a liquid and about 50 at a flat free surface.
    stretch : float
        ``k_r``, the largest ratio of the longest to the shortest covariance axis, in [1, 100].
        1 gives spherical kernels.
    min_neighbors : int
        ``N_eps``: particles with fewer neighbours (self excluded) within ``r_i`` keep the
        spherical kernel ``I / h``; >= 0.
    smoothing : float
        ``lambda`` of the Laplacian smoothing of the centres, in [0, 1]; 0 keeps the positions.
    layer_band : float
        Half-width (multiples of ``r``) of the slab about the particle's tangent plane over which
        the centres are smoothed (particles with ``N_eps`` neighbours or more); 0 gives Yu &
        Turk's plain weighted mean over the whole neighbourhood. The default 1.6 (0.8 particle
        spacings) keeps a particle's own layer and drops the layers below it (narrower slabs,
        1.2 r, left bubbles of outside between the outer two layers near edges at iso 0.6).
    max_axis : float
        Longest semi-axis of any kernel ellipsoid over ``h``, in [1, 10]. The ellipsoids keep
        the isotropic kernel's volume (``det(G) = 1/h^3``) unless that would stretch an axis
        beyond ``max_axis * h`` (line-like neighbourhoods at edges of the liquid: up to
        ``k_r^(2/3) h``); then they are scaled down to it (``det(G) > 1/h^3``; the splat's
        ``det(G)`` factor keeps every particle's mass). The default 1.6 just admits a flat
        surface's ``k_r^(1/3) h = 1.587 h`` and keeps the splat's reach at that of the
        isotropic kernel's, two blocks; 1 gives Yu & Turk's shape (longest axis ``h``).
    return_volumes : bool
        Also return the SPH particle volumes ``V_i = m_i / rho_i`` (m^3, unsmoothed positions,
        cubic spline of support ``(h_i + h_j) / 2``, ``m ~ r^3``), which the ``sph`` splat needs.
    backend : {"auto", "grid", "hash", "kdtree"}
        Neighbour search (:class:`filters.neighbors.NeighborSearch`). With the uniform grid the
        neighbours are visited cell by cell without building lists (fastest); the others build
        CSR lists first. All give the same result up to rounding.

    Returns
    -------
    centres : (N, 3) float64
        Smoothed kernel centres ``xbar_i`` (m).
    G : (N, 3, 3) float64
        Symmetric kernel matrices (1/m): particle ``i`` contributes ``det(G_i) P(|G_i (x -
        xbar_i)|)`` with ``P`` a kernel of unit support; ``det(G_i) = 1 / h_i^3``.
    volumes : (N,) float64
        Only with ``return_volumes``: SPH volumes (m^3).
    """
    positions = check_points("positions", positions)
    n = positions.shape[0]
    radii = _radii("radius", radius, n)
    support = check_range("support", support, 0.0, 1e3, low_inclusive=False)
    neighbor_factor = check_range("neighbor_factor", neighbor_factor, 1.0, 10.0)
    stretch = check_range("stretch", stretch, 1.0, 100.0)
    min_neighbors = check_int("min_neighbors", min_neighbors, 0)
    smoothing = check_range("smoothing", smoothing, 0.0, 1.0)
    layer_band = check_range("layer_band", layer_band, 0.0, 100.0)
    return_volumes = bool(return_volumes)
    backend = check_choice("backend", backend, ("auto", "grid", "hash", "kdtree"))
    max_axis = check_range("max_axis", max_axis, 1.0, 10.0)
    hs = radii * support
    rn = radii * (2.0 * neighbor_factor)
    centres = np.empty((n, 3))
    G = np.empty((n, 3, 3))
    volumes = np.empty(n)
    if n == 0:
        return (centres, G, volumes) if return_volumes else (centres, G)
    search = float(max(rn.max(), hs.max()))
    ns = NeighborSearch(search, backend).build(positions)
    rmax = radii.max()
    mass = (radii / rmax) ** 3
    band = radii * layer_band
    if ns.backend == "grid":
        o = ns.order
        _anisotropy_grid(ns.sorted_points, o, ns.start, ns.origin, ns.cell, ns.dims, ns.reach,
                         search * search, rn[o], hs[o], band[o], mass[o], stretch,
                         min_neighbors, smoothing, max_axis, centres, G,
                         volumes)
    else:
        offsets, indices = ns.query()
        _anisotropy(positions, offsets, indices, rn, hs, band, mass, stretch, min_neighbors,
                    smoothing, max_axis, centres, G, volumes)
    return (centres, G, volumes) if return_volumes else (centres, G)


def kernel_axes(G):
    """Semi-axes (m) and directions of the kernel ellipsoids ``{r : |G r| <= 1}``.

    Parameters
    ----------
    G : (N, 3, 3) float64
        Symmetric kernel matrices (1/m), e.g. from :func:`anisotropic_kernels`.

    Returns
    -------
    lengths : (N, 3) float64
        Semi-axes (m), ascending.
    directions : (N, 3, 3) float64
        ``directions[i, :, k]`` is the unit axis of ``lengths[i, k]``.
    """
    G = np.asarray(G, dtype=np.float64)
    if G.ndim != 3 or G.shape[1:] != (3, 3):
        raise ValueError(f"G must have shape (N, 3, 3), got {G.shape}")
    w, v = np.linalg.eigh(G)  # ascending eigenvalues -> descending lengths
    return 1.0 / w[:, ::-1], v[:, :, ::-1]
