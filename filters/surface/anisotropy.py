"""Per-particle anisotropic kernels for flat liquid surfaces (Yu & Turk 2013), in Numba.

Yu & Turk (2013), "Reconstructing surfaces of particle-based fluids using anisotropic
kernels", ACM Transactions on Graphics 32(1):5. For every particle ``i`` with neighbours
``j`` within the neighbourhood radius ``n_i = neighbor_radius_r * r_i`` (the particle itself
included):

* weights ``w_ij = 1 - (|x_i - x_j| / n_i)^3`` for ``|x_i - x_j| < n_i``, else 0 (their Eq. 11);
* weighted mean ``xw_i = sum_j w_ij x_j / sum_j w_ij`` and weighted covariance
  ``C_i = sum_j w_ij (x_j - xw_i)(x_j - xw_i)^T / sum_j w_ij`` (Eqs. 9-10);
* a dead zone for sampling noise: with ``m = tr(C) / 3`` and the deviatoric part
  ``D = C - m I``, ``C' = m I + max(0, 1 - tau m / |D|_F) D`` (a soft threshold of the
  anisotropy, continuous in ``C``), so that particles inside the liquid need no
  eigen-decomposition and keep ``G = I / h``;
* eigen-decomposition ``C' = R diag(s_1, s_2, s_3) R^T`` with ``s_1 >= s_2 >= s_3`` (cyclic
  Jacobi rotations, Golub & Van Loan 2013, deterministic);
* clamped stretch: ``t_k = max(s_k, s_1 / k_r)`` (Eq. 15), so no axis is more than ``k_r``
  times shorter than the longest;
* particles with fewer than ``N_eps`` neighbours ("isolated", splashes) keep the spherical
  kernel;
* the kernel matrix ``G_i = (1 / h_i) R diag(c / t_1, c / t_2, c / t_3) R^T`` with the kernel's
  support radius ``h_i = support_r * r_i``, and the kernel
  ``W(x - xbar_i, G_i) = det(G_i) P(|G_i (x - xbar_i)|)`` (Eq. 7), which integrates to the same
  mass whatever the scale of ``G_i``.

Scale. Yu & Turk scale ``diag(t)`` by a global constant ``k_s``. Here ``c = (t_1 t_2 t_3)^(1/3)``
per particle, so that ``det(G_i) = 1 / h_i^3``: every ellipsoid encloses the volume of the
isotropic kernel it replaces, and a particle in a uniform neighbourhood gets *exactly* the
isotropic kernel. A cap keeps the longest semi-axis within ``max_axis_r * r_i`` (default
``1.26 h_i``, ``k_r^(1/3) h_i``: a flat surface's ellipsoid passes, line-like neighbourhoods at
the liquid's edges, which would reach ``k_r^(2/3) h_i``, are scaled down), so the splat's
reach stays close to the isotropic one. Isolated particles get ``G_i = I / h_i`` (Yu & Turk
shrink them by ``k_n``; keeping the isotropic kernel gives a lone droplet the radius
:func:`filters.kernels.lone_particle_radius` predicts). ``k_r = 2`` rather than Yu & Turk's 4,
with volume-keeping ellipsoids (see ``benchmarks/results/surface_notes.md`` for the
measurements behind every default).

Smoothed centres (Laplacian smoothing, their Eq. 6): ``xbar_i = (1 - lambda) x_i +
lambda xw_i``; this removes the jitter of surface particles. The plain weighted mean of a
particle on a free surface lies inside the liquid (its neighbourhood is a half ball). For
anisotropic particles (outside the dead zone, i.e. near a surface) the mean is therefore taken
over the slab ``|(x_j - x_i) . n_i| < layer_band_r * r_i`` about the particle's tangent plane
(``n_i`` the axis of least variance, weights ``w_ij (1 - (d_n / band)^2)``): the particle's own
layer, whose mean height is the surface's, without the layers below; and the centre moves only
along ``n_i``.

Evaluation. With the uniform-grid backend (cells half as wide as the neighbourhood, searched
two cells out) every cell gathers the points of its neighbour cells once, in float32 relative
to the cell, and each of its points sums weights, SPH density and first and second moments in
one branch-free loop that the compiler vectorises; the slab mean is a second loop over the same
gathered points, run only for anisotropic particles. Every particle's sums run over its
candidates in a fixed order (stable counting sort into cells; neighbour cells in a fixed order)
by one task, so the output is bitwise identical for any number of threads.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..binning import MAX_CELLS, cell_window, sort_into_cells
from ..kernels import spline_profile, spline_row
from ..neighbors import NeighborSearch
from ..validation import check_choice, check_int, check_points, check_radii, check_range

__all__ = ["anisotropic_kernels", "kernel_matrices", "kernel_axes", "DEFAULTS", "MAX_AXIS_H",
           "check_anisotropy"]

#: Defaults of :func:`anisotropic_kernels` (see its docstring); lengths are multiples of the
#: particle radius ``r`` (suffix ``_r``).
DEFAULTS = {
    "neighbor_radius_r": 7.0,  # neighbourhood radius / r (3.5 particle spacings)
    "stretch": 2.0,            # k_r
    "min_neighbors": 15,       # N_eps (self excluded)
    "smoothing": 0.9,          # lambda
    "layer_band_r": 1.25,      # slab half-width of the centre smoothing / r
    "max_axis_r": None,        # longest semi-axis / r; None: MAX_AXIS_H * support_r
    "isotropy": 0.12,          # tau, dead zone of the covariance's anisotropy
}

#: Default cap of the longest semi-axis over the kernel's support radius ``h`` (``k_r^(1/3)``).
MAX_AXIS_H = 1.26


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


@njit(cache=True)
def _frame(c00, c01, c02, c11, c12, c22, tau, kr, amax, inv_h, g):
    """Kernel matrix of one particle from its weighted covariance ``C`` (upper triangle).

    Writes ``G`` into ``g`` (3, 3) and returns ``(det G, n0, n1, n2, anisotropic)`` with ``n``
    the axis of least variance. ``C`` is first shrunk towards its mean eigenvalue ``m``: its
    deviatoric part ``D = C - m I`` is soft-thresholded, ``C' = m I + max(0, 1 - tau m / |D|) D``
    (Frobenius norm), so a covariance whose anisotropy is at the level of the sampling noise
    inside the liquid (``|D| <= tau m``) gives exactly the isotropic kernel ``I / h`` without an
    eigen-decomposition, and ``G`` stays continuous in ``C``."""
    m = (c00 + c11 + c22) / 3.0
    d00 = c00 - m
    d11 = c11 - m
    d22 = c22 - m
    nd = math.sqrt(d00 * d00 + d11 * d11 + d22 * d22
                   + 2.0 * (c01 * c01 + c02 * c02 + c12 * c12))
    if not (m > 0.0) or nd <= tau * m:
        for a in range(3):
            for b in range(3):
                g[a, b] = inv_h if a == b else 0.0
        return inv_h * inv_h * inv_h, 0.0, 0.0, 1.0, False
    c = np.empty((3, 3))
    c[0, 0] = c00
    c[0, 1] = c01
    c[0, 2] = c02
    c[1, 0] = c01
    c[1, 1] = c11
    c[1, 2] = c12
    c[2, 0] = c02
    c[2, 1] = c12
    c[2, 2] = c22
    v = np.empty((3, 3))
    _jacobi3(c, v)
    s0 = c[0, 0]
    s1 = c[1, 1]
    s2 = c[2, 2]
    kmin = 0 if (s0 <= s1 and s0 <= s2) else (1 if s1 <= s2 else 2)
    f = 1.0 - tau * m / nd
    s0 = m + f * (s0 - m)
    s1 = m + f * (s1 - m)
    s2 = m + f * (s2 - m)
    smax = max(s0, s1, s2)
    floor = smax / kr
    t0 = max(s0, floor)
    t1 = max(s1, floor)
    t2 = max(s2, floor)
    scale = max((t0 * t1 * t2) ** (1.0 / 3.0), smax / amax)
    g0 = scale / t0 * inv_h
    g1 = scale / t1 * inv_h
    g2 = scale / t2 * inv_h
    for a in range(3):
        for b in range(a, 3):
            val = g0 * v[a, 0] * v[b, 0] + g1 * v[a, 1] * v[b, 1] + g2 * v[a, 2] * v[b, 2]
            g[a, b] = val
            g[b, a] = val
    return g0 * g1 * g2, v[0, kmin], v[1, kmin], v[2, kmin], True


@njit(parallel=True, cache=True)
def _anisotropy(x, offsets, indices, rn, hs, band, mass, kr, neps, lam, amax, tau, centres, G,
                volumes, dets):
    """Reference path on CSR neighbour lists (hash / kd-tree backends), float64."""
    n = x.shape[0]
    for i in prange(n):
        xi0 = x[i, 0]
        xi1 = x[i, 1]
        xi2 = x[i, 2]
        inv_r = 1.0 / rn[i]
        hi = hs[i]
        # the particle itself: w = 1, K(0) = 1
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
        rho = mass[i] / (hi * hi * hi)
        for k in range(offsets[i], offsets[i + 1]):
            j = indices[k]
            d0 = x[j, 0] - xi0
            d1 = x[j, 1] - xi1
            d2 = x[j, 2] - xi2
            dd = d0 * d0 + d1 * d1 + d2 * d2
            hh = 0.5 * (hi + hs[j])
            q2 = dd / (hh * hh)
            if q2 < 1.0:
                rho += mass[j] * spline_profile(q2) / (hh * hh * hh)
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
        volumes[i] = mass[i] / rho * (math.pi / 8.0)
        mu0 = a0 / ws
        mu1 = a1 / ws
        mu2 = a2 / ws
        centres[i, 0] = xi0 + lam * mu0
        centres[i, 1] = xi1 + lam * mu1
        centres[i, 2] = xi2 + lam * mu2
        inv_h = 1.0 / hi
        if count < neps:
            for a in range(3):
                for b in range(3):
                    G[i, a, b] = inv_h if a == b else 0.0
            dets[i] = inv_h * inv_h * inv_h
            continue
        det, n0, n1, n2, aniso = _frame(
            c00 / ws - mu0 * mu0, c01 / ws - mu0 * mu1, c02 / ws - mu0 * mu2,
            c11 / ws - mu1 * mu1, c12 / ws - mu1 * mu2, c22 / ws - mu2 * mu2, tau, kr, amax,
            inv_h, G[i])
        dets[i] = det
        if aniso and band[i] > 0.0:
            inv_b2 = 1.0 / (band[i] * band[i])
            ws = 1.0
            a0 = 0.0
            a1 = 0.0
            a2 = 0.0
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
                    a0 += w * d0
                    a1 += w * d1
                    a2 += w * d2
            # only the move along the normal: the layer's mean height, not its lateral mean
            sn = lam * (a0 * n0 + a1 * n1 + a2 * n2) / ws
            centres[i, 0] = xi0 + sn * n0
            centres[i, 1] = xi1 + sn * n1
            centres[i, 2] = xi2 + sn * n2


@njit(parallel=True, cache=True, fastmath=True)
def _anisotropy_cells(sx, order, start, origin, cell, dims, reach, rn, hs, band, mass, uniform,
                      kr, neps, lam, amax, tau, centres, G, volumes, dets):
    """The same on points sorted into the cells of a uniform grid (:func:`filters.binning.sort_into_cells`) as wide
    as the search radius: every non-empty cell gathers the points of its 27 neighbour
    cells once (float32, relative to the cell's corner) and each of its points sums over them
    in branch-free loops the compiler vectorises (weights, SPH density and the first and second
    moments in one pass; the slab mean in a second pass only for anisotropic points). Inputs
    ``rn, hs, band, mass`` are in sorted order; outputs go to the original indices. With
    ``uniform`` all radii are equal and ``mass`` is ignored (all 1)."""
    nx = dims[0]
    ny = dims[1]
    nz = dims[2]
    zero = np.float32(0.0)
    one = np.float32(1.0)
    half = np.float32(0.5)
    big = np.float32(1e30)
    for cidx in prange(nx * ny * nz):
        s0 = start[cidx]
        s1 = start[cidx + 1]
        if s0 == s1:
            continue
        ox, oy, oz, xa, xb, ya, yb, za, zb, total = cell_window(cidx, dims, reach, start,
                                                                 origin, cell)
        cx = np.empty(total, np.float32)
        cy = np.empty(total, np.float32)
        cz = np.empty(total, np.float32)
        ch = np.empty(total if not uniform else 0, np.float32)
        cm = np.empty(total if not uniform else 0, np.float32)
        c = 0
        for z in range(za, zb + 1):
            for y in range(ya, yb + 1):
                row = (z * ny + y) * nx
                for k in range(start[row + xa], start[row + xb + 1]):
                    cx[c] = np.float32(sx[k, 0] - ox)
                    cy[c] = np.float32(sx[k, 1] - oy)
                    cz[c] = np.float32(sx[k, 2] - oz)
                    if not uniform:
                        ch[c] = np.float32(hs[k])
                        cm[c] = np.float32(mass[k])
                    c += 1
        for t in range(s0, s1):
            px = np.float32(sx[t, 0] - ox)
            py = np.float32(sx[t, 1] - oy)
            pz = np.float32(sx[t, 2] - oz)
            inv_r = np.float32(1.0 / rn[t])
            hi = hs[t]
            inv_h32 = np.float32(1.0 / hi)
            h32 = np.float32(hi)
            ws = zero
            a0 = zero
            a1 = zero
            a2 = zero
            c00 = zero
            c01 = zero
            c02 = zero
            c11 = zero
            c12 = zero
            c22 = zero
            cnt = zero
            rho = zero
            # one pass: neighbourhood weights (self included: w = 1), moments, SPH density
            if uniform:
                for k in range(total):
                    d0 = cx[k] - px
                    d1 = cy[k] - py
                    d2 = cz[k] - pz
                    dist = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                    d = dist * inv_r
                    w = one - d * d * d
                    w = max(w, zero)
                    cnt += min(w * big, one)
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
                    rho += spline_row(dist * inv_h32)
            else:
                for k in range(total):
                    d0 = cx[k] - px
                    d1 = cy[k] - py
                    d2 = cz[k] - pz
                    dist = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                    d = dist * inv_r
                    w = one - d * d * d
                    w = max(w, zero)
                    cnt += min(w * big, one)
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
                    hh = half * (h32 + ch[k])
                    rho += cm[k] * spline_row(dist / hh) / (hh * hh * hh)
            i = order[t]
            if uniform:
                volumes[i] = hi * hi * hi / np.float64(rho) * (math.pi / 8.0)
            else:
                volumes[i] = mass[t] / np.float64(rho) * (math.pi / 8.0)
            W = np.float64(ws)
            mu0 = np.float64(a0) / W
            mu1 = np.float64(a1) / W
            mu2 = np.float64(a2) / W
            centres[i, 0] = sx[t, 0] + lam * mu0
            centres[i, 1] = sx[t, 1] + lam * mu1
            centres[i, 2] = sx[t, 2] + lam * mu2
            inv_h = 1.0 / hi
            if np.float64(cnt) - 1.0 < neps:
                for a in range(3):
                    for b in range(3):
                        G[i, a, b] = inv_h if a == b else 0.0
                dets[i] = inv_h * inv_h * inv_h
                continue
            det, n0, n1, n2, aniso = _frame(
                np.float64(c00) / W - mu0 * mu0, np.float64(c01) / W - mu0 * mu1,
                np.float64(c02) / W - mu0 * mu2, np.float64(c11) / W - mu1 * mu1,
                np.float64(c12) / W - mu1 * mu2, np.float64(c22) / W - mu2 * mu2, tau, kr, amax,
                inv_h, G[i])
            dets[i] = det
            if aniso and band[t] > 0.0:
                # layer smoothing: the weighted mean over the slab about the tangent plane
                m0 = np.float32(n0)
                m1 = np.float32(n1)
                m2 = np.float32(n2)
                inv_b2 = np.float32(1.0 / (band[t] * band[t]))
                ws = zero
                a0 = zero
                a1 = zero
                a2 = zero
                for k in range(total):
                    d0 = cx[k] - px
                    d1 = cy[k] - py
                    d2 = cz[k] - pz
                    d = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2) * inv_r
                    dn = d0 * m0 + d1 * m1 + d2 * m2
                    w = max(one - d * d * d, zero) * max(one - dn * dn * inv_b2, zero)
                    ws += w
                    a0 += w * d0
                    a1 += w * d1
                    a2 += w * d2
                # only the move along the normal: the layer's mean height, not its lateral mean
                sn = lam * (np.float64(a0) * n0 + np.float64(a1) * n1
                            + np.float64(a2) * n2) / np.float64(ws)
                centres[i, 0] = sx[t, 0] + sn * n0
                centres[i, 1] = sx[t, 1] + sn * n1
                centres[i, 2] = sx[t, 2] + sn * n2


def _grid_cells(positions, search, backend):
    """Cells for the ``grid`` path: half the search radius wide, searched two cells out
    (1.7x fewer candidates than cells as wide as the radius), or as wide as the radius when
    half-width cells would exceed ``MAX_CELLS``; None when both would (use the hash). Cells are
    padded as in NeighborSearch, so that rounding in the binning cannot put a neighbour beyond
    the cells searched. Returns ``(origin, cell, dims, reach)``."""
    lo = positions.min(axis=0)
    with np.errstate(over="ignore"):  # points ~1e308 apart: inf cells, hence the hash
        extent = positions.max(axis=0) - lo
        for reach in (2, 1):
            cell = search / reach * (1.0 + 1e-9)
            dims = np.floor(extent / cell) + 1.0
            if float(np.prod(dims)) <= MAX_CELLS:
                return lo, cell, dims.astype(np.int64), reach
    if backend == "grid":
        raise ValueError(f"the grid backend would need {float(np.prod(dims)):.3g} cells (max "
                         f"{MAX_CELLS}); use backend='hash' for sparse or unbounded domains")
    return None


def check_anisotropy(support_r: float, *, neighbor_radius_r=DEFAULTS["neighbor_radius_r"],
                     stretch=DEFAULTS["stretch"], min_neighbors=DEFAULTS["min_neighbors"],
                     smoothing=DEFAULTS["smoothing"], layer_band_r=DEFAULTS["layer_band_r"],
                     max_axis_r=DEFAULTS["max_axis_r"], isotropy=DEFAULTS["isotropy"]) -> dict:
    """Validate the options of :func:`anisotropic_kernels` for a kernel support ``support_r``.

    Returns
    -------
    dict
        The options as floats and ints, with ``max_axis_h`` (the cap over ``h``) in place of
        ``max_axis_r``.

    Raises
    ------
    TypeError, ValueError
        Naming the option and its valid range.
    """
    support_r = check_range("support_r", support_r, 0.0, 1e3, low_inclusive=False)
    options = dict(
        neighbor_radius_r=check_range("neighbor_radius_r", neighbor_radius_r, 2.0, 20.0),
        stretch=check_range("stretch", stretch, 1.0, 100.0),
        min_neighbors=check_int("min_neighbors", min_neighbors, 0),
        smoothing=check_range("smoothing", smoothing, 0.0, 1.0),
        layer_band_r=check_range("layer_band_r", layer_band_r, 0.0, 100.0),
        isotropy=check_range("isotropy", isotropy, 0.0, 1.0))
    if max_axis_r is None:
        options["max_axis_h"] = MAX_AXIS_H
    else:
        max_axis_r = check_range("max_axis_r", max_axis_r, support_r, 10.0 * support_r)
        options["max_axis_h"] = max_axis_r / support_r
    return options


def kernel_matrices(positions, radius, *, support_r: float = 4.0, backend: str = "auto",
                    **options):
    """:func:`anisotropic_kernels` with the determinants: ``(centres, G, volumes, det(G))``.

    Same parameters as :func:`anisotropic_kernels` (``return_volumes`` aside); the volumes are
    always computed.
    """
    positions = check_points("positions", positions)
    n = positions.shape[0]
    radii = check_radii("radius", radius, n)
    opts = check_anisotropy(support_r, **options)
    support_r = float(support_r)
    backend = check_choice("backend", backend, ("auto", "grid", "hash", "kdtree"))
    stretch, min_neighbors = opts["stretch"], opts["min_neighbors"]
    smoothing, max_axis, isotropy = opts["smoothing"], opts["max_axis_h"], opts["isotropy"]
    hs = radii * support_r
    rn = radii * opts["neighbor_radius_r"]
    centres = np.empty((n, 3))
    G = np.empty((n, 3, 3))
    volumes = np.empty(n)
    dets = np.empty(n)
    if n == 0:
        return centres, G, volumes, dets
    search = float(max(rn.max(), hs.max()))
    rmax = radii.max()
    mass = (radii / rmax) ** 3
    band = radii * opts["layer_band_r"]
    grid = _grid_cells(positions, search, backend) if backend in ("auto", "grid") else None
    if grid is not None:
        lo, cell, dims, reach = grid
        o, start, sx = sort_into_cells(positions, lo, 1.0 / cell, dims)
        uniform = bool(radii.min() == rmax)
        _anisotropy_cells(sx, o, start, lo, cell, dims, reach, rn[o], hs[o], band[o], mass[o],
                          uniform, stretch, min_neighbors, smoothing, max_axis, isotropy,
                          centres, G, volumes, dets)
    else:
        ns = NeighborSearch(search, "hash" if backend == "auto" else backend).build(positions)
        offsets, indices = ns.query()
        _anisotropy(positions, offsets, indices, rn, hs, band, mass, stretch, min_neighbors,
                    smoothing, max_axis, isotropy, centres, G, volumes, dets)
    return centres, G, volumes, dets


def anisotropic_kernels(positions, radius, *, support_r: float = 4.0,
                        return_volumes: bool = False, backend: str = "auto", **options):
    """Smoothed kernel centres and anisotropy matrices (Yu & Turk 2013).

    Parameters
    ----------
    positions : (N, 3) float64
        Particle centres (m); NaN or infinite values raise ValueError.
    radius : float or (N,) float64
        Particle radii ``r`` (m), > 0.
    support_r : float
        Kernel support radius over particle radius, ``h = support_r * r`` (as in
        :func:`filters.surface.splat.splat_sparse`; 4 for the ``sph`` kernel), in (0, 1000].
    neighbor_radius_r : float
        Neighbourhood radius for the covariance and the smoothing over the particle radius,
        ``n_i = neighbor_radius_r * r_i``, in [2, 20]. The default 7 (3.5 particle spacings)
        holds about 180 neighbours inside a liquid and about 100 at a flat free surface.
    stretch : float
        ``k_r``, the largest ratio of the longest to the shortest covariance axis, in [1, 100].
        1 gives spherical kernels; default 2 (not Yu & Turk's 4).
    min_neighbors : int
        ``N_eps``: particles with fewer neighbours (self excluded) within ``n_i`` keep the
        spherical kernel ``I / h``; >= 0. Default 15 rather than Yu & Turk's 25: a single sheet
        of particles has about 28 neighbours within 3 spacings, and 25 would leave thin sheets'
        rims spherical.
    smoothing : float
        ``lambda`` of the Laplacian smoothing of the centres, in [0, 1]; 0 keeps the positions.
        Anisotropic particles move along their normal only.
    layer_band_r : float
        Half-width over ``r`` of the slab about the particle's tangent plane over which the
        centres of anisotropic particles are smoothed, in [0, 100]; 0 gives Yu & Turk's plain
        weighted mean over the whole neighbourhood. The default 1.25 (0.63 particle spacings)
        keeps a particle's own layer and drops the layers below it.
    max_axis_r : float, optional
        Longest semi-axis of any kernel ellipsoid over ``r``, in ``[support_r, 10 support_r]``
        (i.e. between ``h`` and ``10 h``); default :data:`MAX_AXIS_H` ``* h``. The ellipsoids
        keep the isotropic kernel's volume (``det(G) = 1/h^3``) unless that would stretch an
        axis beyond it (line-like neighbourhoods at edges of the liquid); then they are scaled
        down to it (``det(G) > 1/h^3``; the splat's ``det(G)`` factor keeps every particle's
        mass). ``support_r`` gives Yu & Turk's shape (longest axis ``h``).
    isotropy : float
        ``tau``, the dead zone of the covariance's anisotropy, in [0, 1]: the deviatoric part
        ``D`` of the covariance ``C`` is soft-thresholded, ``C' = m I + max(0, 1 - tau m /
        |D|_F) D`` (``m = tr C / 3``), so particles with ``|D|_F <= tau m`` get exactly the
        isotropic kernel (and the plain smoothed centre) without an eigen-decomposition. The
        default 0.12 makes the interior of a jittered lattice isotropic (tested). 0 gives Yu &
        Turk's kernels everywhere.
    return_volumes : bool
        Also return the SPH particle volumes ``V_i = m_i / rho_i`` of the isotropic kernels
        (m^3, unsmoothed positions, cubic spline of support ``(h_i + h_j) / 2``, ``m ~ r^3``).
    backend : {"auto", "grid", "hash", "kdtree"}
        Neighbour search. ``grid``: a uniform grid of cells half as wide as the neighbourhood
        (sums in float32 SIMD loops, fastest). ``hash`` and ``kdtree``: CSR lists from
        :class:`filters.neighbors.NeighborSearch`, sums in float64. ``auto``: the grid unless it
        would need more than :data:`filters.binning.MAX_CELLS` cells, then the hash. They agree
        to float32 rounding (about 1e-6 relative).

    Returns
    -------
    centres : (N, 3) float64
        Smoothed kernel centres ``xbar_i`` (m).
    G : (N, 3, 3) float64
        Symmetric kernel matrices (1/m): particle ``i`` contributes ``det(G_i) P(|G_i (x -
        xbar_i)|)`` with ``P`` a kernel of unit support; ``det(G_i) = 1 / h_i^3`` unless
        ``max_axis_r`` caps it.
    volumes : (N,) float64
        Only with ``return_volumes``: SPH volumes (m^3).
    """
    centres, G, volumes, _ = kernel_matrices(positions, radius, support_r=support_r,
                                             backend=backend, **options)
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

