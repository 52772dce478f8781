"""Per-particle anisotropic kernels for flat liquid surfaces (Yu & Turk 2013), in Numba.

Yu & Turk (2013), "Reconstructing surfaces of particle-based fluids using anisotropic
kernels", ACM Transactions on Graphics 32(1):5. For every particle ``i`` with neighbours
``j`` within the neighbourhood radius ``r_i`` (the particle itself included):

* weights ``w_ij = 1 - (|x_i - x_j| / r_i)^3`` for ``|x_i - x_j| < r_i``, else 0 (their Eq. 11);
* weighted mean ``xw_i = sum_j w_ij x_j / sum_j w_ij`` and weighted covariance
  ``C_i = sum_j w_ij (x_j - xw_i)(x_j - xw_i)^T / sum_j w_ij`` (Eqs. 9-10);
* a dead zone for sampling noise (ours): with ``m = tr(C) / 3`` and the deviatoric part
  ``D = C - m I``, ``C' = m I + max(0, 1 - tau m / |D|_F) D`` (a soft threshold of the
  anisotropy, continuous in ``C``). Inside a jittered lattice (+-10 %) ``|D|_F / m < 0.06``;
  one spacing below a flat surface 0.24-0.31; at the surface 0.60-0.68 (measured,
  neighbourhood of 3 spacings); ``tau = 0.12`` makes the interior exactly isotropic, so most
  particles need no eigen-decomposition and keep ``G = I / h``;
* eigen-decomposition ``C' = R diag(s_1, s_2, s_3) R^T`` with ``s_1 >= s_2 >= s_3`` (cyclic
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
neighbourhood gets *exactly* the isotropic kernel. A cap keeps the longest semi-axis at
``max_axis * h_i`` (default 1.26 = ``k_r^(1/3)``: a flat surface's ellipsoid passes, line-like
neighbourhoods at the liquid's edges, which would reach ``k_r^(2/3)``, are scaled down), so the
splat's reach stays close to the isotropic one. Isolated particles get ``G_i = I / h_i`` (Yu &
Turk shrink them by ``k_n``; we keep the isotropic kernel, so a lone droplet has the radius
:func:`filters.surface.splat.lone_particle_radius` predicts).

Stretch. ``k_r = 2`` rather than Yu & Turk's 4: with volume-keeping ellipsoids the top layer's
kernels at ``k_r = 4`` are so thin across the surface (0.4 h) that the field falls off within
0.8 spacings of the top layer, and no single iso value then puts a flat pool's surface on the
true plane while keeping a ball's volume (measured with the earlier defaults: iso 0.45, plane
-0.011 spacings, ball +1.8 %). (Scaling the longest axis to ``h``, Yu & Turk's shape, left
dimples between the surface particles: RMS 0.30 spacings on a flat pool.)

Amplitudes. The splat weights each ellipsoid with its SPH volume under the ellipsoids
themselves (:func:`anisotropic_volumes`), not, as Yu & Turk, with the volume of the isotropic
kernel at the unsmoothed position; see there for why (flatter SPH-settled pools).

Smoothed centres (Laplacian smoothing, their Eq. 6): ``xbar_i = (1 - lambda) x_i +
lambda xw_i`` with ``lambda`` about 0.9; this removes the jitter of surface particles. The plain
weighted mean of a particle on a free surface lies inside the liquid (its neighbourhood is a
half ball): on a flat pool it pulls the top layer down by half a spacing. For anisotropic
particles (outside the dead zone, i.e. near a surface) the mean is therefore taken over the
slab ``|(x_j - x_i) . n_i| < layer_band * r_i`` about the particle's tangent plane (``n_i`` the
axis of least variance, weights ``w_ij (1 - (d_n / band)^2)``): the particle's own layer, whose
mean height is the surface's, without the layers below; and the centre moves only along
``n_i`` (to the layer's mean height; the lateral part of the mean would bunch the particles
of small drops together). On a flat surface the slab's width does not matter; on a curved
one it sets how far the centres move inward, and with it the volume of a ball.

Defaults, chosen on the flatness benchmark (``benchmarks/bench_anisotropy.py``; RMS from the
true plane in spacings): neighbourhood 3.5 spacings, slab 1.25 r: jittered lattice pool 0.015,
SPH-settled pools 0.028 / 0.025 (with the earlier 3 spacings, slab 1.5 r, isotropic-kernel
volumes and the full lateral move: 0.022 / 0.037 / 0.031; pysplashsurf raw 0.042 / 0.049 /
0.033). 4 spacings flatten further (0.013 / 0.024 / 0.022) for 1.55x instead of 1.42x the
isotropic reconstruction's time. Lattice balls (no jitter) of radius 4 to 7 spacings keep
their volume within 1.1 %; small clusters come out larger, as the calibrated iso is low
(:data:`filters.surface.ellipsoids.ANISOTROPIC_ISO`): radius 3 spacings (93 particles) +18 %,
clusters of 3 x 3 x 3 / 2 x 2 x 2 / 2 x 2 x 1 particles -4 / +14 / +68 % (the earlier defaults
+8 / 0 / -6 / +28 %; the isotropic kernel +0.5 / -6 / -11 / -4 %; measured).

Cost. With the uniform-grid backend (cells half as wide as the neighbourhood, searched two
cells out) every cell gathers the points of its 125 neighbour cells once, in float32 relative
to the cell, and each of its points sums weights, SPH density and first and second moments in
one branch-free loop that the compiler vectorises; the slab mean is a second loop over the same
gathered points, run only for anisotropic particles. 0.07 s for 100k particles on 2 cores with
a neighbourhood of 4 spacings (cells as wide as the neighbourhood: 0.08 s; smaller cells,
per-thread gather buffers or dropping the points beyond the search radius of a cell's box
before the sums did not help, measured; the former list-free float64 cell walk: 0.2 s for 2.5
spacings).

Determinism. Every particle's sums run over its candidates in a fixed order (stable counting
sort into cells; neighbour cells in a fixed order) by one task, so the output is bitwise
identical for any number of threads.
"""

from __future__ import annotations

import math
import numbers

import numpy as np
from numba import njit, prange

from ..neighbors import NeighborSearch
from ..validation import check_choice, check_int, check_points, check_range

__all__ = ["anisotropic_kernels", "anisotropic_volumes", "kernel_axes", "DEFAULTS"]

#: Defaults of :func:`anisotropic_kernels` (see its docstring).
DEFAULTS = {
    "neighbor_factor": 3.5,   # neighbourhood radius / particle spacing 2 r
    "stretch": 2.0,           # k_r
    "min_neighbors": 15,      # N_eps (self excluded)
    "smoothing": 0.9,         # lambda
    "layer_band": 1.25,       # slab half-width of the centre smoothing / particle radius r
    "max_axis": 1.26,         # longest semi-axis / h
    "isotropy": 0.12,         # tau, dead zone of the covariance's anisotropy
}



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
                rho += mass[j] * _spline(q2) / (hh * hh * hh)
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


@njit(cache=True, inline="always")
def _cell_window(cidx, dims, reach, start, origin, cell):
    """Corner (m) of cell ``cidx`` and the window of cells within ``reach`` of it: returns
    ``(ox, oy, oz, xa, xb, ya, yb, za, zb, total)`` with the inclusive x / y / z cell ranges and
    the number of points in the window (cells sorted by :func:`_cell_sort`)."""
    nx = dims[0]
    ny = dims[1]
    nz = dims[2]
    ix = cidx % nx
    iy = (cidx // nx) % ny
    iz = cidx // (nx * ny)
    xa = max(ix - reach, 0)
    xb = min(ix + reach, nx - 1)
    ya = max(iy - reach, 0)
    yb = min(iy + reach, ny - 1)
    za = max(iz - reach, 0)
    zb = min(iz + reach, nz - 1)
    total = 0
    for z in range(za, zb + 1):
        for y in range(ya, yb + 1):
            row = (z * ny + y) * nx
            total += start[row + xb + 1] - start[row + xa]
    return (origin[0] + ix * cell, origin[1] + iy * cell, origin[2] + iz * cell,
            xa, xb, ya, yb, za, zb, total)


@njit(parallel=True, cache=True, fastmath=True)
def _anisotropy_cells(sx, order, start, origin, cell, dims, reach, rn, hs, band, mass, uniform,
                      kr, neps, lam, amax, tau, centres, G, volumes, dets):
    """The same on points sorted into the cells of a uniform grid (:func:`_cell_sort`) as wide
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
    two = np.float32(2.0)
    eight = np.float32(8.0)
    big = np.float32(1e30)
    for cidx in prange(nx * ny * nz):
        s0 = start[cidx]
        s1 = start[cidx + 1]
        if s0 == s1:
            continue
        ox, oy, oz, xa, xb, ya, yb, za, zb, total = _cell_window(cidx, dims, reach, start,
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
                    q = dist * inv_h32
                    e = max(one - q, zero)
                    f = max(half - q, zero)
                    rho += two * e * e * e - eight * f * f * f
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
                    q = dist / hh
                    e = max(one - q, zero)
                    f = max(half - q, zero)
                    rho += cm[k] * (two * e * e * e - eight * f * f * f) / (hh * hh * hh)
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


@njit(cache=True)
def _cell_sort(x, origin, inv_cell, dims):
    """Stable counting sort of the points ``x`` into the cells of a uniform grid (x fastest):
    returns ``order``, ``start`` (cell ``c`` holds ``order[start[c]:start[c + 1]]``) and the
    sorted points."""
    n = x.shape[0]
    nx = dims[0]
    ny = dims[1]
    nz = dims[2]
    keys = np.empty(n, np.int64)
    start = np.zeros(nx * ny * nz + 1, np.int64)
    for i in range(n):
        # clamped in float before the conversion: the same cells, and no undefined int
        # conversion where x - origin overflows (points +-1.7e308 apart)
        cx = int(min(max(np.floor((x[i, 0] - origin[0]) * inv_cell), 0.0), nx - 1.0))
        cy = int(min(max(np.floor((x[i, 1] - origin[1]) * inv_cell), 0.0), ny - 1.0))
        cz = int(min(max(np.floor((x[i, 2] - origin[2]) * inv_cell), 0.0), nz - 1.0))
        k = (cz * ny + cy) * nx + cx
        keys[i] = k
        start[k + 1] += 1
    for c in range(nx * ny * nz):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(n, np.int64)
    sx = np.empty((n, 3))
    for i in range(n):
        k = keys[i]
        t = fill[k]
        fill[k] = t + 1
        order[t] = i
        sx[t, 0] = x[i, 0]
        sx[t, 1] = x[i, 1]
        sx[t, 2] = x[i, 2]
    return order, start, sx


@njit(parallel=True, cache=True, fastmath=True)
def _volumes_cells(sc, order, start, origin, cell, dims, reach, sg, smd, need, volumes,
                   exact=False):
    """SPH volumes under the anisotropic kernels themselves, on centres sorted into cells
    (:func:`_cell_sort`) ``reach`` of which span the longest kernel reach: ``V_j = m_j /
    rho_j`` with ``rho_j = sum_k m_k (8 / pi) det(G_k) P(|G_k (c_j - c_k)|)`` (``P`` the cubic
    spline of unit support and peak 1, ``8 / pi`` its normalisation; the particle itself
    included). ``sg`` holds the 6 entries of ``G_k`` and ``smd`` the
    products ``m_k det(G_k)``, both in sorted order; the neighbour cells' kernels are gathered
    once per cell in float32 and summed in a branch-free loop, in a fixed order. Only targets
    with ``need`` (sorted order) are computed; a cell without any is skipped.

    With ``exact`` every target sums its candidates in float64 relative to itself: for cells
    grown over a sparse domain, where float32 offsets from a cell corner would lose the
    kernels (a cell 1e293 m wide) or overflow."""
    nx = dims[0]
    ny = dims[1]
    nz = dims[2]
    zero = np.float32(0.0)
    one = np.float32(1.0)
    half = np.float32(0.5)
    two = np.float32(2.0)
    eight = np.float32(8.0)
    for cidx in prange(nx * ny * nz):
        s0 = start[cidx]
        s1 = start[cidx + 1]
        if s0 == s1:
            continue
        wanted = False
        for t in range(s0, s1):
            wanted = wanted or need[t]
        if not wanted:
            continue
        ox, oy, oz, xa, xb, ya, yb, za, zb, total = _cell_window(cidx, dims, reach, start,
                                                                 origin, cell)
        if exact:
            for t in range(s0, s1):
                if not need[t]:
                    continue
                rho64 = 0.0
                for z in range(za, zb + 1):
                    for y in range(ya, yb + 1):
                        row = (z * ny + y) * nx
                        for k in range(start[row + xa], start[row + xb + 1]):
                            d0 = sc[t, 0] - sc[k, 0]
                            d1 = sc[t, 1] - sc[k, 1]
                            d2 = sc[t, 2] - sc[k, 2]
                            u0 = sg[k, 0] * d0 + sg[k, 1] * d1 + sg[k, 2] * d2
                            u1 = sg[k, 1] * d0 + sg[k, 3] * d1 + sg[k, 4] * d2
                            u2 = sg[k, 2] * d0 + sg[k, 4] * d1 + sg[k, 5] * d2
                            q2 = u0 * u0 + u1 * u1 + u2 * u2
                            if q2 < 1.0:
                                q = math.sqrt(q2)
                                e = 1.0 - q
                                f = max(0.5 - q, 0.0)
                                rho64 += smd[k] * (2.0 * e * e * e - 8.0 * f * f * f)
                volumes[order[t]] = (math.pi / 8.0) / rho64
            continue
        cx = np.empty(total, np.float32)
        cy = np.empty(total, np.float32)
        cz = np.empty(total, np.float32)
        g = np.empty((6, total), np.float32)
        md = np.empty(total, np.float32)
        c = 0
        for z in range(za, zb + 1):
            for y in range(ya, yb + 1):
                row = (z * ny + y) * nx
                for k in range(start[row + xa], start[row + xb + 1]):
                    cx[c] = np.float32(sc[k, 0] - ox)
                    cy[c] = np.float32(sc[k, 1] - oy)
                    cz[c] = np.float32(sc[k, 2] - oz)
                    for a in range(6):
                        g[a, c] = np.float32(sg[k, a])
                    md[c] = np.float32(smd[k])
                    c += 1
        for t in range(s0, s1):
            if not need[t]:
                continue
            px = np.float32(sc[t, 0] - ox)
            py = np.float32(sc[t, 1] - oy)
            pz = np.float32(sc[t, 2] - oz)
            rho = zero
            for k in range(total):
                d0 = px - cx[k]
                d1 = py - cy[k]
                d2 = pz - cz[k]
                u0 = g[0, k] * d0 + g[1, k] * d1 + g[2, k] * d2
                u1 = g[1, k] * d0 + g[3, k] * d1 + g[4, k] * d2
                u2 = g[2, k] * d0 + g[4, k] * d1 + g[5, k] * d2
                q = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
                e = max(one - q, zero)
                f = max(half - q, zero)
                rho += md[k] * (two * e * e * e - eight * f * f * f)
            volumes[order[t]] = (math.pi / 8.0) / np.float64(rho)


def anisotropic_volumes(centres, G, masses=None, *, only=None):
    """SPH particle volumes under the anisotropic kernels themselves.

    ``V_j = m_j / rho_j`` with ``rho_j = sum_k m_k (8 / pi) det(G_k) P(|G_k (c_j - c_k)|)``
    (``P`` Monaghan's cubic spline of unit support and peak 1, ``8 / pi`` its normalisation):
    the density at each kernel centre from the same ellipsoidal kernels that the splat then
    sums, so that inside the liquid ``sum_j V_j W_j`` is the SPH partition of unity of *those*
    kernels. With uniform masses ``m = 1`` a particle inside a lattice of spacing ``s`` gets
    ``V = s^3``.

    Yu & Turk (2013) weight the ellipsoids with the volumes of the isotropic kernels at the
    unsmoothed positions. Those are blind to how the flattened top-layer kernels overlap
    within their layer, and the surface then follows how densely each patch of the top layer
    is packed: on SPH-settled pools the isotropic-kernel volumes left 0.037 / 0.031 spacings RMS
    from the true plane, these 0.031 / 0.028, and a jittered lattice pool went 0.022 -> 0.018
    (measured with a neighbourhood of 3 spacings; ``benchmarks/bench_anisotropy.py``).
    Top-layer kernels of a flat surface get ``V = 0.82 s^3`` here against ``1.18 s^3`` from the
    isotropic density, which is why the anisotropic field has its own iso
    (:data:`filters.surface.ellipsoids.ANISOTROPIC_ISO`). The splat computes these volumes for
    the ellipsoids only (``only``); the spherical kernels inside the liquid keep their
    isotropic SPH volumes, which is the same to sampling noise and 3x cheaper at 100k.

    Parameters
    ----------
    centres : (N, 3) float64
        Kernel centres (m), e.g. the smoothed centres of :func:`anisotropic_kernels`.
    G : (N, 3, 3) float64
        Symmetric kernel matrices (1/m).
    masses : (N,) float64, optional
        Particle masses (any unit; default 1).
    only : (N,) bool, optional
        Compute the volumes of these particles only (the others are NaN); all by default.

    Returns
    -------
    (N,) float64
        ``V_j`` (m^3 per unit mass, times ``pi / 8``).
    """
    centres = check_points("centres", centres)
    n = centres.shape[0]
    G = np.ascontiguousarray(G, dtype=np.float64)
    if G.shape != (n, 3, 3):
        raise ValueError(f"G must have shape ({n}, 3, 3), got {G.shape}")
    m = np.ones(n) if masses is None else np.ascontiguousarray(masses, dtype=np.float64)
    if m.shape != (n,) or (n and not (np.isfinite(m).all() and m.min() > 0)):
        raise ValueError(f"masses must be finite, > 0 and have shape ({n},)")
    need = np.ones(n, bool) if only is None else np.asarray(only, dtype=bool)
    if need.shape != (n,):
        raise ValueError(f"only must have shape ({n},), got {need.shape}")
    if n == 0 or not need.any():
        return np.full(n, np.nan)
    if not np.isfinite(G).all():
        raise ValueError("G must be finite")
    dets = np.linalg.det(G)
    if not dets.min() > 0:
        raise ValueError("G must be positive definite for every particle")
    # longest reach of any kernel: 1 / smallest eigenvalue of G
    reach = float(1.0 / np.linalg.eigvalsh(G)[:, 0].min())
    return _volumes(centres, G, dets, m, need, reach)


def _volumes(centres, G, dets, m, need, reach):
    """:func:`anisotropic_volumes` on checked inputs, with ``det(G)`` and a bound ``reach``
    (m) on every kernel's longest semi-axis given."""
    n = centres.shape[0]
    volumes = np.full(n, np.nan)
    # cells as wide as the reach: each holds ~16 centres, which amortises gathering its 27
    # neighbour cells (half-width cells were slower here: 0.105 against 0.070 s at 100k)
    lo, cell, dims = _fitting_cells(centres, reach)
    o, start, sc = _cell_sort(centres, lo, 1.0 / cell, dims)
    g6 = G[:, [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]]
    # float32 offsets from a cell's corner resolve the kernels to ~1e-5 while cells are at most
    # 64 reaches wide (grown over a sparse domain, see _fitting_cells); wider ones (a domain
    # ~10^4 reaches across, up to 1e293 m cells for a 1e300 m spread) sum in float64 about
    # each target, slower but exact
    grown = cell > 64.0 * reach
    _volumes_cells(sc, o, start, lo, cell, dims, 1, np.ascontiguousarray(g6[o]),
                   (m * dets)[o], need[o], volumes, grown)
    return volumes * m


#: Largest number of grid cells the ``grid`` path allocates (32 MB of cell offsets); ``auto``
#: falls back to the spatial hash above it (sparse splashes over a large domain).
_MAX_CELLS = 4_000_000


def _fitting_cells(points, width):
    """Origin, cell size and dims of a grid over ``points`` with cells at least ``width`` wide
    (padded as in NeighborSearch, so that the 27 cells around a point hold all points within
    ``width``); over a large sparse domain the cells grow until there are at most about
    ``_MAX_CELLS`` (up to twice that; more candidates per cell, the same sums)."""
    lo = points.min(axis=0)
    with np.errstate(over="ignore"):  # +-1.7e308 apart: the extent overflows; cap it
        extent = np.minimum(points.max(axis=0) - lo, np.finfo(np.float64).max)
    cell = width * (1.0 + 1e-9)
    with np.errstate(over="ignore"):
        count = float(np.prod(np.floor(extent / cell) + 1.0))
    # grow the cells until they fit: one step by the cube root of the excess for a cloud spread
    # along all three axes (then within the +1 per axis of the budget, as always); more steps,
    # by the root of as many axes as the cloud spreads along, for thinner spreads (one step
    # used to leave a cloud spread along one axis with up to 4e6 ** (2/3) times too many cells,
    # and cell counts past int64 at a 1e300 spread)
    first = True
    while count > (_MAX_CELLS if first else 2 * _MAX_CELLS):
        if math.isinf(count):  # extent / cell overflowed (points ~1e308 apart)
            cell = max(cell, float(extent.max()) / _MAX_CELLS)
        else:
            axes = max(int((np.floor(extent / cell) > 0).sum()), 1)
            cell *= max((count / _MAX_CELLS) ** (1.0 / axes), 1.0 + 1e-6)
        first = False
        with np.errstate(over="ignore"):
            count = float(np.prod(np.floor(extent / cell) + 1.0))
    return lo, cell, (np.floor(extent / cell) + 1.0).astype(np.int64)


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
                        max_axis: float = DEFAULTS["max_axis"],
                        isotropy: float = DEFAULTS["isotropy"], return_volumes: bool = False,
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
        :func:`filters.surface.splat.splat_sparse`; 4 for the ``sph`` kernel), in (0, 1000].
    neighbor_factor : float
        Neighbourhood radius for the covariance and the smoothing over the *particle spacing*
        ``2 r``: ``r_i = neighbor_factor * 2 r_i`` (m), in [1, 10]. The default 3.5 holds about
        180 neighbours inside a liquid and about 100 at a flat free surface.
    stretch : float
        ``k_r``, the largest ratio of the longest to the shortest covariance axis, in [1, 100].
        1 gives spherical kernels. See the module docstring for the default (2, not Yu & Turk's 4).
    min_neighbors : int
        ``N_eps``: particles with fewer neighbours (self excluded) within ``r_i`` keep the
        spherical kernel ``I / h``; >= 0. 15 rather than Yu & Turk's 25: a single sheet of
        particles has about 28 neighbours within 3 spacings, and 25 would leave thin sheets'
        rims spherical.
    smoothing : float
        ``lambda`` of the Laplacian smoothing of the centres, in [0, 1]; 0 keeps the positions.
        Anisotropic particles move along their normal only.
    layer_band : float
        Half-width (multiples of ``r``) of the slab about the particle's tangent plane over which
        the centres of anisotropic particles are smoothed; 0 gives Yu & Turk's plain weighted
        mean over the whole neighbourhood. The default 1.25 (0.63 particle spacings) keeps a
        particle's own layer and drops the layers below it; it was chosen so that lattice
        balls keep their volume (see the module docstring).
    max_axis : float
        Longest semi-axis of any kernel ellipsoid over ``h``, in [1, 10]. The ellipsoids keep
        the isotropic kernel's volume (``det(G) = 1/h^3``) unless that would stretch an axis
        beyond ``max_axis * h`` (line-like neighbourhoods at edges of the liquid: up to
        ``k_r^(2/3) h``); then they are scaled down to it (``det(G) > 1/h^3``; the splat's
        ``det(G)`` factor keeps every particle's mass). The default 1.26 just admits a flat
        surface's ``k_r^(1/3) h`` (k_r = 2); 1 gives Yu & Turk's shape (longest axis ``h``).
    isotropy : float
        ``tau``, the dead zone of the covariance's anisotropy, in [0, 1]: the deviatoric part
        ``D`` of the covariance ``C`` is soft-thresholded, ``C' = m I + max(0, 1 - tau m /
        |D|_F) D`` (``m = tr C / 3``), so particles with ``|D|_F <= tau m`` get exactly the
        isotropic kernel (and the plain smoothed centre) without an eigen-decomposition. Inside
        a jittered lattice (+-10 %) ``|D|_F / m`` stays below 0.11, one spacing below a flat
        surface it is 0.15-0.30, at the surface 0.56-0.71 (measured with a neighbourhood of 3
        spacings; wider ones average more neighbours, so the interior stays below); the default
        0.12 makes the interior isotropic (tested). 0 gives Yu & Turk's kernels everywhere.
    return_volumes : bool
        Also return the SPH particle volumes ``V_i = m_i / rho_i`` of the isotropic kernels
        (m^3, unsmoothed positions, cubic spline of support ``(h_i + h_j) / 2``, ``m ~ r^3``);
        the ``sph`` splat uses them for the spherical kernels and :func:`anisotropic_volumes`
        for the ellipsoids.
    backend : {"auto", "grid", "hash", "kdtree"}
        Neighbour search. ``grid``: a uniform grid of cells half as wide as the neighbourhood
        (its own serial counting sort); each cell gathers its neighbours once and the sums run in
        float32 SIMD loops (fastest). ``hash`` and ``kdtree``: CSR lists from
        :class:`filters.neighbors.NeighborSearch`, sums in float64. ``auto``: the grid unless
        it would need more than 4 million cells, then the hash. They agree to float32
        rounding (about 1e-6 relative).

    Returns
    -------
    centres : (N, 3) float64
        Smoothed kernel centres ``xbar_i`` (m).
    G : (N, 3, 3) float64
        Symmetric kernel matrices (1/m): particle ``i`` contributes ``det(G_i) P(|G_i (x -
        xbar_i)|)`` with ``P`` a kernel of unit support; ``det(G_i) = 1 / h_i^3`` unless
        ``max_axis`` caps it.
    volumes : (N,) float64
        Only with ``return_volumes``: SPH volumes (m^3).
    """
    centres, G, volumes, _ = _kernels(positions, radius, support=support,
                                      neighbor_factor=neighbor_factor, stretch=stretch,
                                      min_neighbors=min_neighbors, smoothing=smoothing,
                                      layer_band=layer_band, max_axis=max_axis,
                                      isotropy=isotropy, backend=backend)
    return (centres, G, volumes) if return_volumes else (centres, G)


def _grid_cells(positions, search, backend):
    """Cells for the ``grid`` path: half the search radius wide, searched two cells out
    (1.7x fewer candidates than cells as wide as the radius), or as wide as the radius when
    half-width cells would exceed ``_MAX_CELLS``; None when both would (use the hash). Cells are
    padded as in NeighborSearch, so that rounding in the binning cannot put a neighbour beyond
    the cells searched. Returns ``(origin, cell, dims, reach)``."""
    lo = positions.min(axis=0)
    with np.errstate(over="ignore"):  # points ~1e308 apart: inf cells, hence the hash
        extent = positions.max(axis=0) - lo
        for reach in (2, 1):
            cell = search / reach * (1.0 + 1e-9)
            dims = np.floor(extent / cell) + 1.0
            if float(np.prod(dims)) <= _MAX_CELLS:
                return lo, cell, dims.astype(np.int64), reach
    if backend == "grid":
        raise ValueError(f"the grid backend would need {float(np.prod(dims)):.3g} cells (max "
                         f"{_MAX_CELLS}); use backend='hash' for sparse or unbounded domains")
    return None


def _kernels(positions, radius, *, support, neighbor_factor, stretch, min_neighbors, smoothing,
             layer_band, max_axis, isotropy, backend="auto"):
    """:func:`anisotropic_kernels` returning ``(centres, G, volumes, det(G))``."""
    positions = check_points("positions", positions)
    n = positions.shape[0]
    radii = _radii("radius", radius, n)
    support = check_range("support", support, 0.0, 1e3, low_inclusive=False)
    neighbor_factor = check_range("neighbor_factor", neighbor_factor, 1.0, 10.0)
    stretch = check_range("stretch", stretch, 1.0, 100.0)
    min_neighbors = check_int("min_neighbors", min_neighbors, 0)
    smoothing = check_range("smoothing", smoothing, 0.0, 1.0)
    layer_band = check_range("layer_band", layer_band, 0.0, 100.0)
    backend = check_choice("backend", backend, ("auto", "grid", "hash", "kdtree"))
    max_axis = check_range("max_axis", max_axis, 1.0, 10.0)
    isotropy = check_range("isotropy", isotropy, 0.0, 1.0)
    hs = radii * support
    rn = radii * (2.0 * neighbor_factor)
    centres = np.empty((n, 3))
    G = np.empty((n, 3, 3))
    volumes = np.empty(n)
    dets = np.empty(n)
    if n == 0:
        return centres, G, volumes, dets
    search = float(max(rn.max(), hs.max()))
    rmax = radii.max()
    mass = (radii / rmax) ** 3
    band = radii * layer_band
    grid = _grid_cells(positions, search, backend) if backend in ("auto", "grid") else None
    if grid is not None:
        lo, cell, dims, reach = grid
        o, start, sx = _cell_sort(positions, lo, 1.0 / cell, dims)
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
