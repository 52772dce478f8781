"""SPH volumes of ellipsoidal kernels: the amplitudes of the anisotropic ``sph`` splat.

``V_j = m_j / rho_j`` with the density at each kernel centre from the ellipsoidal kernels
themselves (Yu & Turk 2013 use the isotropic kernels' volumes instead; see
:func:`anisotropic_volumes`). Centres are sorted into cells as wide as the longest kernel reach
(:mod:`filters.binning`); every cell gathers its neighbour cells' kernels once, in float32
relative to the cell, and sums them in a branch-free loop in a fixed order (bitwise identical
for any number of threads).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..binning import cell_window, fitting_cells, sort_into_cells
from ..kernels import spline_row
from ..validation import check_points

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = ["anisotropic_volumes", "ellipsoid_volumes", "stretched_gain", "STRETCHED_GAIN",
           "GAIN_EXPONENT"]

#: Amplitude factor of an ``sph`` kernel stretched to the clamp ``k_r`` (anisotropy 1),
#: calibrated once (default kernel options and volumes) so that the flat top of an unjittered
#: lattice pool lies on the true plane, half a spacing above the top layer
#: (``benchmarks/results/surface_notes.md``). The flattened top-layer kernels of a flat surface
#: overlap within their layer, so their volumes (:func:`filters.surface.volumes.
#: anisotropic_volumes`) are small and the field half a spacing above the top layer is weak:
#: with a single iso for all kernels it reached 0.367 there, against 0.6 for spherical ones.
STRETCHED_GAIN = 1.635
#: Exponent of the anisotropy in :func:`stretched_gain`.
GAIN_EXPONENT = 1.0


def stretched_gain(anisotropy: np.ndarray) -> NDArray[np.float64]:
    """Amplitude factors ``1 + (STRETCHED_GAIN - 1) a^p`` (``p`` = :data:`GAIN_EXPONENT`) of
    ``sph`` kernels of anisotropy ``a`` ((N,) in [0, 1], :func:`filters.surface.anisotropy.
    kernel_matrices`): 1 for a sphere, continuous in ``a``.

    Parameters
    ----------
    anisotropy : (N,) float64

    Returns
    -------
    (N,) float64
    """
    a = np.clip(np.asarray(anisotropy, np.float64), 0.0, 1.0)
    return 1.0 + (STRETCHED_GAIN - 1.0) * a ** GAIN_EXPONENT


@njit(parallel=True, cache=True, fastmath=True)
def _volumes_cells(sc, order, start, origin, cell, dims, reach, sg, smd, need, volumes,
                   exact=False):
    """SPH volumes under the anisotropic kernels themselves, on centres sorted into cells
    (:func:`filters.binning.sort_into_cells`) ``reach`` of which span the longest kernel reach:
    ``V_j = m_j /
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
        ox, oy, oz, xa, xb, ya, yb, za, zb, total = cell_window(cidx, dims, reach, start,
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
                                rho64 += smd[k] * spline_row(math.sqrt(q2))
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
                rho += md[k] * spline_row(np.sqrt(u0 * u0 + u1 * u1 + u2 * u2))
            volumes[order[t]] = (math.pi / 8.0) / np.float64(rho)


def anisotropic_volumes(centres: np.ndarray, G: np.ndarray, masses: np.ndarray | None = None, *,
                        only: np.ndarray | None = None) -> NDArray[np.float64]:
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
    is packed; these volumes give flatter SPH-settled pools and are smaller on a flat surface's
    top layer, which is why the amplitudes of stretched kernels are raised
    (:func:`stretched_gain`; measurements in
    ``benchmarks/results/surface_notes.md``). The splat computes these volumes for the
    anisotropic kernels only (``only``) and fades them in with the strength of the anisotropy;
    the spherical kernels inside the liquid keep their isotropic SPH volumes, the same to
    sampling noise and cheaper.

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
    return ellipsoid_volumes(centres, G, dets, m, need, reach)


def ellipsoid_volumes(centres: np.ndarray, G: np.ndarray, dets: np.ndarray, m: np.ndarray,
                      need: np.ndarray, reach: float) -> NDArray[np.float64]:
    """:func:`anisotropic_volumes` on checked inputs, with ``det(G)`` and a bound ``reach``
    (m) on every kernel's longest semi-axis given.

    Parameters
    ----------
    centres : (N, 3) float64
        Kernel centres (m).
    G : (N, 3, 3) float64
        Symmetric positive-definite kernel matrices (1/m).
    dets : (N,) float64
        ``det(G)``.
    m : (N,) float64
        Masses (> 0).
    need : (N,) bool
        Which volumes to compute (the others are NaN).
    reach : float
        Longest semi-axis of any kernel (m), > 0.

    Returns
    -------
    (N,) float64
    """
    n = centres.shape[0]
    volumes = np.full(n, np.nan)
    # cells as wide as the reach: each holds ~16 centres, which amortises gathering its 27
    # neighbour cells (half-width cells were slower here: 0.105 against 0.070 s at 100k)
    lo, cell, dims = fitting_cells(centres, reach)
    o, start, sc = sort_into_cells(centres, lo, 1.0 / cell, dims)
    g6 = G[:, [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]]
    # float32 offsets from a cell's corner resolve the kernels to ~1e-5 while cells are at most
    # 64 reaches wide (grown over a sparse domain, see filters.binning.fitting_cells); wider ones (a
    # domain
    # ~10^4 reaches across, up to 1e293 m cells for a 1e300 m spread) sum in float64 about
    # each target, slower but exact
    grown = cell > 64.0 * reach
    _volumes_cells(sc, o, start, lo, cell, dims, 1, np.ascontiguousarray(g6[o]),
                   (m * dets)[o], need[o], volumes, grown)
    return volumes * m
