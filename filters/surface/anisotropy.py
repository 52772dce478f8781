"""Per-particle anisotropic kernels for flat liquid surfaces (Yu & Turk 2013), in Numba.

Yu & Turk (2013), "Reconstructing surfaces of particle-based fluids using anisotropic
kernels", ACM Transactions on Graphics 32(1):5. For every particle ``i`` with neighbours
``j`` within the neighbourhood radius ``n_i = neighbor_radius_r * r_i`` (the particle itself
included):

* weights ``w_ij = 1 - (|x_i - x_j| / n_i)^3`` for ``|x_i - x_j| < n_i``, else 0 (their Eq. 11);
* weighted mean ``xw_i = sum_j w_ij x_j / sum_j w_ij`` and weighted covariance
  ``C_i = sum_j w_ij (x_j - xw_i)(x_j - xw_i)^T / sum_j w_ij`` (Eqs. 9-10);
* the strength of the anisotropy ``f = g(n_w) max(0, 1 - tau m / |D|_F)`` with
  ``m = tr(C) / 3``, the deviatoric part ``D = C - m I`` (a dead zone for sampling noise) and
  a gate ``g`` of the weighted neighbour count ``n_w = sum_{j != i} w_ij`` that fades the
  anisotropy out between ``N_eps`` and ``N_eps / 2`` (isolated particles, splashes); then
  ``C' = m I + f D``: continuous in the positions, so a kernel never jumps between two frames,
  and particles inside the liquid (``f = 0``) need no eigen-decomposition and keep
  ``G = I / h`` (:mod:`filters.surface.covariance`);
* eigen-decomposition ``C' = R diag(s_1, s_2, s_3) R^T`` with ``s_1 >= s_2 >= s_3`` (cyclic
  Jacobi rotations, Golub & Van Loan 2013, deterministic);
* clamped stretch: ``t_k = max(s_k, s_1 / k_r)`` (Eq. 15), so no axis is more than ``k_r``
  times shorter than the longest;
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

Smoothed centres (Laplacian smoothing, their Eq. 6, ``xbar_i = (1 - lambda) x_i + lambda
xw_i``) remove the jitter of surface particles. The plain weighted mean of a particle on a free
surface lies inside the liquid (its neighbourhood is a half ball), and on a small drop it pulls
every surface particle inwards (a drop of radius 2 spacings lost a fifth of its volume to it).
Here the mean is taken over the slab ``|(x_j - x_i) . n_i| < layer_band_r * r_i`` about the
particle's tangent plane (``n_i`` the axis of least variance, weights ``w_ij (1 - (d_n /
band)^2)``): the particle's own layer, whose mean height is the surface's, without the layers
below; the centre moves only along ``n_i``, by ``lambda min(1, f / f_0)`` of that mean height
(``f_0`` = :data:`filters.surface.covariance.SMOOTHING_RAMP`), so that it fades out with the
anisotropy; isotropic particles (``f = 0``) keep their positions.

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
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numba import njit, prange

from ..binning import MAX_CELLS, cell_window, sort_into_cells
from ..kernels import spline_row
from ..neighbors import NeighborSearch
from ..validation import check_choice, check_int, check_points, check_radii, check_range
from .covariance import (
    SMOOTHING_RAMP,
    anisotropy_on_lists,
    count_gate,
    curvature_gate,
    kernel_frame,
)

if TYPE_CHECKING:
    from typing import Any

    from numpy.typing import ArrayLike, NDArray

__all__ = ["anisotropic_kernels", "kernel_matrices", "KernelSet", "kernel_axes", "DEFAULTS",
           "MAX_AXIS_H",
           "check_anisotropy"]

#: Defaults of :func:`anisotropic_kernels` (see its docstring); lengths are multiples of the
#: particle radius ``r`` (suffix ``_r``).
DEFAULTS = {
    "neighbor_radius_r": 7.0,  # neighbourhood radius / r (3.5 particle spacings)
    "stretch": 2.0,            # k_r
    "min_neighbors": 8,        # N_eps, weighted neighbours (self excluded)
    "smoothing": 0.9,          # lambda
    "layer_band_r": 1.25,      # slab half-width of the centre smoothing / r
    "max_axis_r": None,        # longest semi-axis / r; None: MAX_AXIS_H * support_r
    "isotropy": 0.12,          # tau, dead zone of the covariance's anisotropy
}

#: Default cap of the longest semi-axis over the kernel's support radius ``h`` (``k_r^(1/3)``).
MAX_AXIS_H = 1.26


@njit(parallel=True, cache=True, fastmath=True)
def _anisotropy_cells(sx, order, start, origin, cell, dims, reach, rn, hs, band, mass, uniform,
                      kr, neps, lam, amax, tau, ntargets, centres, G, volumes, dets, strength,
                      anisotropy):
    """The same on points sorted into the cells of a uniform grid
    (:func:`filters.binning.sort_into_cells`) as wide
    as the search radius: every non-empty cell gathers the points of its 27 neighbour
    cells once (float32, relative to the cell's corner) and each of its points sums over them
    in branch-free loops the compiler vectorises (weights, SPH density and the first and second
    moments in one pass; the slab mean in a second pass only for anisotropic points). Inputs
    ``rn, hs, band, mass`` are in sorted order; outputs go to the original indices, for the
    points of index below ``ntargets`` only (the others are neighbours only). With ``uniform``
    all radii are equal and ``mass`` is ignored (all 1)."""
    nx = dims[0]
    ny = dims[1]
    nz = dims[2]
    zero = np.float32(0.0)
    one = np.float32(1.0)
    half = np.float32(0.5)
    for cidx in prange(nx * ny * nz):
        s0 = start[cidx]
        s1 = start[cidx + 1]
        wanted = False
        for t in range(s0, s1):
            wanted = wanted or order[t] < ntargets
        if not wanted:
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
            if order[t] >= ntargets:
                continue
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
            centres[i, 0] = sx[t, 0]
            centres[i, 1] = sx[t, 1]
            centres[i, 2] = sx[t, 2]
            det, n0, n1, n2, f, aniso = kernel_frame(
                np.float64(c00) / W - mu0 * mu0, np.float64(c01) / W - mu0 * mu1,
                np.float64(c02) / W - mu0 * mu2, np.float64(c11) / W - mu1 * mu1,
                np.float64(c12) / W - mu1 * mu2, np.float64(c22) / W - mu2 * mu2,
                count_gate(W - 1.0, neps), tau, kr, amax, 1.0 / hi, G[i])
            dets[i] = det
            strength[i] = f
            anisotropy[i] = aniso
            if f > 0.0 and band[t] > 0.0 and lam > 0.0:
                # the slab about the tangent plane: the layer's mean height (the smoothed
                # centre) and its mean squared lateral distance (with it, the curvature)
                m0 = np.float32(n0)
                m1 = np.float32(n1)
                m2 = np.float32(n2)
                inv_b2 = np.float32(1.0 / (band[t] * band[t]))
                ws = zero
                sn = zero
                st = zero
                for k in range(total):
                    d0 = cx[k] - px
                    d1 = cy[k] - py
                    d2 = cz[k] - pz
                    dd = d0 * d0 + d1 * d1 + d2 * d2
                    d = np.sqrt(dd) * inv_r
                    dn = d0 * m0 + d1 * m1 + d2 * m2
                    w = max(one - d * d * d, zero) * max(one - dn * dn * inv_b2, zero)
                    ws += w
                    sn += w * dn
                    st += w * (dd - dn * dn)
                mean_dn = np.float64(sn) / np.float64(ws)
                c = curvature_gate(mean_dn, np.float64(st) / np.float64(ws), amax * hi)
                if c < 1.0:
                    det, n0, n1, n2, f, aniso = kernel_frame(
                        np.float64(c00) / W - mu0 * mu0, np.float64(c01) / W - mu0 * mu1,
                        np.float64(c02) / W - mu0 * mu2, np.float64(c11) / W - mu1 * mu1,
                        np.float64(c12) / W - mu1 * mu2, np.float64(c22) / W - mu2 * mu2,
                        c * count_gate(W - 1.0, neps), tau, kr, amax, 1.0 / hi, G[i])
                    dets[i] = det
                    strength[i] = f
                    anisotropy[i] = aniso
                move = lam * min(1.0, f / SMOOTHING_RAMP) * mean_dn
                centres[i, 0] = sx[t, 0] + move * n0
                centres[i, 1] = sx[t, 1] + move * n1
                centres[i, 2] = sx[t, 2] + move * n2


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


def check_anisotropy(support_r: float, *, neighbor_radius_r: float = DEFAULTS["neighbor_radius_r"],
                     stretch: float = DEFAULTS["stretch"],
                     min_neighbors: int = DEFAULTS["min_neighbors"],
                     smoothing: float = DEFAULTS["smoothing"],
                     layer_band_r: float = DEFAULTS["layer_band_r"],
                     max_axis_r: float | None = DEFAULTS["max_axis_r"],
                     isotropy: float = DEFAULTS["isotropy"]) -> dict:
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


class KernelSet(NamedTuple):
    """The anisotropic kernels of a particle set (:func:`kernel_matrices`), N particles."""

    #: (N, 3) float64: smoothed kernel centres (m).
    centres: np.ndarray
    #: (N, 3, 3) float64: symmetric kernel matrices ``G`` (1/m).
    G: np.ndarray
    #: (N,) float64: SPH volumes of the isotropic kernels (m^3 per unit mass, times ``pi / 8``).
    volumes: np.ndarray
    #: (N,) float64: ``det(G)`` (1/m^3).
    dets: np.ndarray
    #: (N,) float64: strength ``f`` of the anisotropy in [0, 1] (0: the isotropic kernel).
    strength: np.ndarray
    #: (N,) float64: anisotropy ``a`` in [0, 1] (0: a sphere; 1: stretched to ``k_r``).
    anisotropy: np.ndarray


def kernel_matrices(positions: np.ndarray, radius: ArrayLike, *, support_r: float = 4.0,
                    backend: str = "auto", targets: int | None = None, **options: Any) -> KernelSet:
    """:func:`anisotropic_kernels` with everything the splat needs (:class:`KernelSet`).

    Same parameters as :func:`anisotropic_kernels` (``return_volumes`` aside); the volumes are
    always computed; ``strength`` and ``anisotropy`` are those of
    :func:`filters.surface.covariance.kernel_frame`. With ``targets`` only the first
    ``targets`` particles get kernels (the rest are their neighbours only, e.g. ghosts; their
    rows of the outputs are left undefined).
    """
    positions = check_points("positions", positions)
    n = positions.shape[0]
    radii = check_radii("radius", radius, n)
    opts = check_anisotropy(support_r, **options)
    support_r = float(support_r)
    backend = check_choice("backend", backend, ("auto", "grid", "hash", "kdtree"))
    stretch, min_neighbors = opts["stretch"], float(opts["min_neighbors"])
    smoothing, max_axis, isotropy = opts["smoothing"], opts["max_axis_h"], opts["isotropy"]
    hs = radii * support_r
    rn = radii * opts["neighbor_radius_r"]
    targets = n if targets is None else check_int("targets", targets, 0, n)
    out = KernelSet(np.empty((n, 3)), np.empty((n, 3, 3)), np.empty(n), np.empty(n),
                    np.empty(n), np.empty(n))
    if n == 0:
        return out
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
                          uniform, stretch, min_neighbors, smoothing, max_axis, isotropy, targets,
                          *out)
    else:
        ns = NeighborSearch(search, "hash" if backend == "auto" else backend).build(positions)
        offsets, indices = ns.query()
        anisotropy_on_lists(positions, offsets, indices, rn, hs, band, mass, stretch,
                            min_neighbors, smoothing, max_axis, isotropy, targets, *out)
    return out


def anisotropic_kernels(positions: np.ndarray, radius: ArrayLike, *, support_r: float = 4.0,
                        return_volumes: bool = False, backend: str = "auto",
                        **options: Any) -> tuple[NDArray[np.float64], ...]:
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
        ``N_eps``, in weighted neighbours ``n_w = sum_{j != i} w_ij`` (self excluded), >= 0:
        the anisotropy fades out linearly from ``n_w = N_eps`` down to ``N_eps / 2``, below
        which particles keep the spherical kernel ``I / h`` (Yu & Turk switch at a count of
        25). Default 8 (about 15 neighbours): a single sheet of particles 1.6 spacings apart
        (about 15 neighbours within 3.5 spacings, ``n_w`` about 9) stays anisotropic, hence
        connected.
    smoothing : float
        ``lambda`` of the smoothing of the centres, in [0, 1]; 0 keeps the positions. Particles
        move along their normal only, anisotropic ones only (see the module docstring).
    layer_band_r : float
        Half-width over ``r`` of the slab about the particle's tangent plane over which the
        centres of anisotropic particles are smoothed, in [0, 100]; 0 keeps every centre. The
        default 1.25 (0.63 particle spacings) keeps a particle's own layer and drops the layers
        below it.
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
        isotropic kernel (and keep their position) without an eigen-decomposition. The
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
    k = kernel_matrices(positions, radius, support_r=support_r, backend=backend, **options)
    return (k.centres, k.G, k.volumes) if return_volumes else (k.centres, k.G)


def kernel_axes(G: np.ndarray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
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

