"""One particle's anisotropic kernel from its weighted neighbourhood (Yu & Turk 2013), in Numba.

The per-particle step of :mod:`filters.surface.anisotropy`, shared by its uniform-grid path and
by the reference path on CSR neighbour lists defined here. From the weighted covariance ``C``
of a particle's neighbourhood (weights ``w_ij = 1 - (|x_i - x_j| / n_i)^3``, Yu & Turk's
Eq. 11) and its weighted neighbour count ``n_w = sum_{j != i} w_ij``:

* a **strength** ``f`` in [0, 1] of the anisotropy, continuous in the positions:
  ``f = g(n_w) max(0, 1 - tau m / |D|_F)`` with ``m = tr(C) / 3`` and ``D = C - m I`` (a soft
  threshold of the covariance's deviatoric part, the dead zone for sampling noise), and the
  gate ``g(n_w) = clip(2 n_w / N_eps - 1, 0, 1)`` of the neighbour count, which fades the
  anisotropy out between ``N_eps`` and ``N_eps / 2`` weighted neighbours (Yu & Turk switch
  their isolated particles to the spherical kernel at a hard count, which makes a kernel jump
  between two frames when one neighbour comes or goes);
* the shrunk covariance ``C' = m I + f D``; for ``f = 0`` the isotropic kernel ``G = I / h``
  without an eigen-decomposition;
* eigen-decomposition ``C' = R diag(s_1, s_2, s_3) R^T`` (cyclic Jacobi rotations, Golub & Van
  Loan 2013, Alg. 8.4.3), clamped stretch ``t_k = max(s_k, s_1 / k_r)`` (Yu & Turk Eq. 15) and
  ``G = (1 / h) R diag(c / t_k) R^T`` with ``c = (t_1 t_2 t_3)^(1/3)`` (volume of the
  isotropic kernel kept), unless the longest semi-axis ``c / t_1 h`` would exceed
  ``amax h``: then ``c = t_1 / amax``;
* the **anisotropy** ``a = (t_1 / t_3 - 1) / (k_r - 1)`` in [0, 1] (0 for a sphere, 1 for a kernel
  stretched to the clamp), and the axis of least variance ``n`` (the surface normal at a flat
  surface), about which the centre is smoothed;
* where the surface curves strongly (small drops), the strength is reduced further by
  :func:`curvature_gate`, from the layer about the tangent plane.

Every function here is deterministic: each particle's sums run over its neighbours in a fixed
order by one task.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..kernels import spline_profile

__all__ = ["jacobi3", "kernel_frame", "count_gate", "curvature_gate", "anisotropy_on_lists",
           "SMOOTHING_RAMP"]

#: Strength ``f`` from which a kernel's centre is smoothed (along its normal) and its volume
#: taken from the ellipsoids in full; below it both fade linearly to the isotropic kernel's.
SMOOTHING_RAMP = 0.5
CURV_A = 2.0
CURV_P = 1.0


@njit(cache=True, inline="always")
def jacobi3(a, v):
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
def count_gate(weighted_count, neps):
    """The neighbour-count gate ``g = clip(2 n_w / N_eps - 1, 0, 1)`` (1 when ``N_eps = 0``)."""
    if neps <= 0.0:
        return 1.0
    return min(max(2.0 * weighted_count / neps - 1.0, 0.0), 1.0)


@njit(cache=True, inline="always")
def curvature_gate(mean_height, mean_lateral2, reach):
    """The curvature gate ``c = max(0, 1 - (kappa L)^2)`` of a surface particle.

    ``kappa = 2 |z| / <t^2>`` is the curvature of the surface through the particle estimated
    from its layer (the slab about its tangent plane): neighbours at lateral distance ``t`` on
    a sphere of radius ``R`` lie ``t^2 / (2 R)`` below the tangent plane, so their weighted mean
    height ``z`` over their weighted mean ``<t^2>`` gives ``1 / (2 R)``. ``L`` (m) is the
    longest semi-axis a kernel may have: a kernel stretched that far along a tangent plane
    sticks out of a small drop (a drop 3 spacings in radius came out 24 % larger with its
    stretched kernels than its particles), so the anisotropy fades where ``kappa L``
    approaches 1 and stays on flat water (``c = 1``)."""
    if not (mean_lateral2 > 0.0):
        return 1.0
    k = 2.0 * abs(mean_height) / mean_lateral2 * reach
    return max(0.0, 1.0 - CURV_A * k ** CURV_P)


@njit(cache=True)
def kernel_frame(c00, c01, c02, c11, c12, c22, gate, tau, kr, amax, inv_h, g):
    """Kernel matrix of one particle from its weighted covariance ``C`` (upper triangle).

    Parameters
    ----------
    c00, c01, c02, c11, c12, c22 : float
        The covariance (m^2).
    gate : float
        The neighbour-count gate in [0, 1] (:func:`count_gate`).
    tau, kr, amax : float
        Dead zone, largest axis ratio, longest semi-axis over ``h``.
    inv_h : float
        ``1 / h`` (1/m).
    g : (3, 3) float64
        Receives ``G`` (1/m).

    Returns
    -------
    tuple
        ``(det G, n0, n1, n2, f, a)``: the determinant (1/m^3), the axis of least variance, the
        strength ``f`` and the anisotropy ``a`` (module docstring); ``f = a = 0`` and
        ``G = I / h`` for the isotropic kernel.
    """
    m = (c00 + c11 + c22) / 3.0
    d00 = c00 - m
    d11 = c11 - m
    d22 = c22 - m
    nd = math.sqrt(d00 * d00 + d11 * d11 + d22 * d22
                   + 2.0 * (c01 * c01 + c02 * c02 + c12 * c12))
    f = 0.0
    if m > 0.0 and nd > tau * m:
        f = gate * (1.0 - tau * m / nd)
    if not (f > 0.0):
        for a in range(3):
            for b in range(3):
                g[a, b] = inv_h if a == b else 0.0
        return inv_h * inv_h * inv_h, 0.0, 0.0, 1.0, 0.0, 0.0
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
    jacobi3(c, v)
    s0 = c[0, 0]
    s1 = c[1, 1]
    s2 = c[2, 2]
    kmin = 0 if (s0 <= s1 and s0 <= s2) else (1 if s1 <= s2 else 2)
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
    aniso = 0.0
    if kr > 1.0:
        aniso = min(max((smax / min(t0, t1, t2) - 1.0) / (kr - 1.0), 0.0), 1.0)
    return g0 * g1 * g2, v[0, kmin], v[1, kmin], v[2, kmin], f, aniso


@njit(parallel=True, cache=True)
def anisotropy_on_lists(x, offsets, indices, rn, hs, band, mass, kr, neps, lam, amax, tau,
                        ntargets, centres, G, volumes, dets, strength, anisotropy):
    """The anisotropic kernels on CSR neighbour lists (hash / kd-tree backends), float64: the
    reference for the uniform-grid path of :func:`filters.surface.anisotropy.kernel_matrices`.

    Per particle ``i`` (neighbours ``indices[offsets[i]:offsets[i + 1]]`` within the larger of
    ``rn`` and ``hs``): the SPH volume of the isotropic kernel, ``V_i = m_i / rho_i (pi / 8)``
    (cubic spline of support ``(h_i + h_j) / 2``), the frame (:func:`kernel_frame`) and the
    centre ``x_i + lam min(1, f / SMOOTHING_RAMP) s_n n`` with ``s_n`` the weighted mean
    height of the neighbours in the slab ``|(x_j - x_i) . n| < band_i`` about the tangent
    plane (``x_i`` itself for ``f = 0``). Outputs are written per particle, for the first
    ``ntargets`` particles."""
    for i in prange(ntargets):
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
        volumes[i] = mass[i] / rho * (math.pi / 8.0)
        mu0 = a0 / ws
        mu1 = a1 / ws
        mu2 = a2 / ws
        centres[i, 0] = xi0
        centres[i, 1] = xi1
        centres[i, 2] = xi2
        ws0 = ws
        det, n0, n1, n2, f, aniso = kernel_frame(
            c00 / ws - mu0 * mu0, c01 / ws - mu0 * mu1, c02 / ws - mu0 * mu2,
            c11 / ws - mu1 * mu1, c12 / ws - mu1 * mu2, c22 / ws - mu2 * mu2,
            count_gate(ws - 1.0, neps), tau, kr, amax, 1.0 / hi, G[i])
        dets[i] = det
        strength[i] = f
        anisotropy[i] = aniso
        if f > 0.0 and band[i] > 0.0 and lam > 0.0:
            inv_b2 = 1.0 / (band[i] * band[i])
            ws = 1.0
            sn = 0.0
            st = 0.0
            for k in range(offsets[i], offsets[i + 1]):
                j = indices[k]
                d0 = x[j, 0] - xi0
                d1 = x[j, 1] - xi1
                d2 = x[j, 2] - xi2
                dd = d0 * d0 + d1 * d1 + d2 * d2
                d = math.sqrt(dd) * inv_r
                dn = d0 * n0 + d1 * n1 + d2 * n2
                b = 1.0 - dn * dn * inv_b2
                if d < 1.0 and b > 0.0:
                    w = (1.0 - d * d * d) * b
                    ws += w
                    sn += w * dn
                    st += w * (dd - dn * dn)
            c = curvature_gate(sn / ws, st / ws, amax * hi)
            if c < 1.0:
                det, n0, n1, n2, f, aniso = kernel_frame(
                    c00 / ws0 - mu0 * mu0, c01 / ws0 - mu0 * mu1, c02 / ws0 - mu0 * mu2,
                    c11 / ws0 - mu1 * mu1, c12 / ws0 - mu1 * mu2, c22 / ws0 - mu2 * mu2,
                    c * count_gate(ws0 - 1.0, neps), tau, kr, amax, 1.0 / hi, G[i])
                dets[i] = det
                strength[i] = f
                anisotropy[i] = aniso
            # only the move along the normal: the layer's mean height, not its lateral mean
            sn *= lam * min(1.0, f / SMOOTHING_RAMP) / ws
            centres[i, 0] = xi0 + sn * n0
            centres[i, 1] = xi1 + sn * n1
            centres[i, 2] = xi2 + sn * n2
