"""Particles to implicit fields on a voxel lattice (metaball splatting): the entry points.

``h_j = support_r * r_j`` is particle ``j``'s support radius (m), ``r_j`` its radius; the
profiles are those of :mod:`filters.kernels` (``blobby``, ``metaball``, ``sph``, ``zhu_bridson``).
Spherical kernels are evaluated by :mod:`filters.surface.spheres`; with ``anisotropic``
variants, each particle's kernel is an ellipsoid stretched along the local particle distribution
(Yu & Turk 2013; :mod:`filters.surface.anisotropy` for the matrices,
:mod:`filters.surface.volumes` for the ``sph`` amplitudes, :mod:`filters.surface.ellipsoids`
for the evaluation).

The output is an *implicit value* ``g``: negative inside, zero on the surface, positive outside.
For the summed kernels ``g = iso - f``; for ``zhu_bridson`` ``g = phi`` in voxel units. The
sparse grid (:class:`filters.surface.grid.SparseGrid`) holds only the blocks the surface passes
near (:mod:`filters.surface.blocks`); its contour is the contour of the dense field. Values are
bitwise identical for any number of threads.
"""

from __future__ import annotations

import math

import numpy as np

from ..kernels import SPLAT_DEFAULTS, SPLAT_KERNELS
from ..validation import check_bool, check_choice, check_int, check_points, check_radii, check_range
from .anisotropy import check_anisotropy, kernel_matrices
from .ellipsoids import ANISOTROPIC_ISO, ANISOTROPIC_KERNELS, ellipsoid_grid, splat_ellipsoids_dense
from .grid import (DEFAULT_MAX_BYTES, DenseField, GridTooLargeError, SparseGrid, check_block_range,
                   check_budget)
from .spheres import sphere_grid
from .volumes import ellipsoid_volumes

__all__ = [
    "GridTooLargeError",
    "splat_sparse",
    "splat_dense",
    "splat_sparse_anisotropic",
    "splat_dense_anisotropic",
    "check_splat_args",
]


def check_splat_args(positions, radius, cell_size, kernel, support_r, iso, block_size,
                     blobbiness, max_bytes, kernels=SPLAT_KERNELS, iso_defaults=None):
    """Validate the common arguments of the splats; defaults filled in per kernel.

    Returns
    -------
    tuple
        ``(positions (N, 3) float64, radii (N,) float64, kernel, cell_size, support_r, iso,
        block_size, blobbiness, max_bytes)``.

    Raises
    ------
    TypeError, ValueError
        Naming the argument and its valid range.
    """
    positions = check_points("positions", positions)
    kernel = check_choice("kernel", kernel, kernels)
    cell_size = check_range("cell_size", cell_size, 0.0, math.inf, low_inclusive=False)
    if not math.isfinite(cell_size):
        raise ValueError(f"cell_size must be finite, got {cell_size!r}")
    support_r = SPLAT_DEFAULTS[kernel]["support"] if support_r is None else support_r
    support_r = check_range("support_r", support_r, 0.0, 1e3, low_inclusive=False)
    iso = (iso_defaults or {k: v["iso"] for k, v in SPLAT_DEFAULTS.items()})[kernel] \
        if iso is None else iso
    if kernel == "zhu_bridson":
        iso = check_range("iso", iso, 0.0, 0.0)
    else:
        iso = check_range("iso", iso, 0.0, math.inf, low_inclusive=False)
    block_size = check_int("block_size", block_size, 4, 64)
    blobbiness = check_range("blobbiness", blobbiness, 0.0, 100.0, low_inclusive=False)
    max_bytes = check_int("max_bytes", max_bytes, 1)
    radii = check_radii("radius", radius, positions.shape[0])
    return positions, radii, kernel, cell_size, support_r, iso, block_size, blobbiness, max_bytes


def splat_sparse(positions, radius, cell_size, *, kernel: str = "sph", support_r=None, iso=None,
                 block_size: int = 8, blobbiness: float = 4.0, skip_interior: bool = True,
                 max_bytes: int = DEFAULT_MAX_BYTES) -> SparseGrid:
    """Splat particles onto the blocks of the voxel lattice that the surface passes near.

    Parameters
    ----------
    positions : (N, 3) float64
        Particle centres (m). NaN or infinite values raise ValueError, and so do points
        whose blocks the 64-bit block keys cannot hold (21 bits per axis: within about
        ``2**20 * block_size * cell_size`` of the origin, 42 km at 8 voxels of 5 mm; see
        :func:`filters.surface.grid.check_block_range`). Far-apart clusters inside that range
        are splatted in full: the grid holds only the blocks near each.
    radius : float or (N,) float64
        Particle radii ``r`` (m), > 0.
    cell_size : float
        Voxel edge (m), > 0.
    kernel : {"blobby", "metaball", "sph", "zhu_bridson"}
        Profile (see :mod:`filters.kernels`).
    support_r : float, optional
        Support radius over particle radius, ``h = support_r * r``, in (0, 1000]; default per
        kernel in :data:`filters.kernels.SPLAT_DEFAULTS` (sph: 4, i.e. splashsurf's smoothing
        length 2 r times 2).
    iso : float, optional
        Iso value of the summed field (sph 0.6, metaball and blobby 0.5), > 0; must be 0 for
        ``zhu_bridson``.
    block_size : int
        Voxels per block edge, in [4, 64].
    blobbiness : float
        ``a`` of the blobby kernel, in (0, 100].
    skip_interior : bool
        Mark blocks whose corner samples are clearly inside without evaluating them (a bubble
        smaller than a block inside such a block would be lost; see
        :mod:`filters.surface.blocks`).
    max_bytes : int
        Memory budget (bytes), >= 1; :class:`GridTooLargeError` if the grid would need more.

    Returns
    -------
    SparseGrid
        Implicit values (negative inside) on the evaluated blocks.
    """
    (positions, radii, kernel, cell_size, support_r, iso, block_size, blobbiness,
     max_bytes) = check_splat_args(positions, radius, cell_size, kernel, support_r, iso,
                                   block_size, blobbiness, max_bytes)
    skip_interior = check_bool("skip_interior", skip_interior)
    # before any key is computed: far-apart points must not wrap past 2^20 blocks
    check_block_range("positions", positions, cell_size, block_size)
    return sphere_grid(positions, radii, cell_size, kernel=kernel, support_r=support_r, iso=iso,
                       block_size=block_size, blobbiness=blobbiness, max_bytes=max_bytes,
                       skip_interior=skip_interior)


def _check_dense_budget(positions, cell_size, block_size, max_bytes, extent_m):
    """Refuse a dense box larger than ``max_bytes`` before any work (4 bytes per voxel)."""
    if positions.shape[0]:
        check_block_range("positions", positions, cell_size, block_size)
        ext = (positions.max(axis=0) - positions.min(axis=0) + 2 * extent_m) / cell_size + 3
        check_budget(int(4 * np.prod(ext)), int(max_bytes),
                     f"a dense grid of about {ext.astype(int).tolist()} voxels")


def splat_dense(positions, radius, cell_size, *, kernel: str = "sph", support_r=None, iso=None,
                block_size: int = 8, blobbiness: float = 4.0,
                max_bytes: int = DEFAULT_MAX_BYTES) -> DenseField:
    """Splat particles onto a dense box of the voxel lattice: every reachable voxel evaluated.

    Same parameters as :func:`splat_sparse`. The box covers every voxel within the particles'
    supports plus one outside layer; voxels no particle reaches hold ``iso`` (``g`` of a zero
    field). The memory guard applies to the whole box (4 bytes per voxel).

    Returns
    -------
    DenseField
    """
    (positions, radii, kernel, cell_size, support_r, iso, block_size, blobbiness,
     max_bytes) = check_splat_args(positions, radius, cell_size, kernel, support_r, iso,
                                   block_size, blobbiness, max_bytes)
    rmax = float(radii.max()) if radii.size else 0.0
    _check_dense_budget(positions, cell_size, block_size, max_bytes, support_r * rmax)
    grid = sphere_grid(positions, radii, cell_size, kernel=kernel, support_r=support_r, iso=iso,
                       block_size=block_size, blobbiness=blobbiness, max_bytes=max_bytes,
                       evaluate_all=True)
    return grid.to_dense(max_bytes=max_bytes)


# --------------------------------------------------------------------------------------------
# Anisotropic kernels (Yu & Turk 2013)
# --------------------------------------------------------------------------------------------


def _anisotropic_inputs(positions, radii, kernel, support_r, options):
    """Kernel centres, matrices and amplitudes of the anisotropic splat."""
    centres, G, volumes, det = kernel_matrices(positions, radii, support_r=support_r,
                                               **options)
    if kernel == "sph":
        # the ellipsoids' volumes under the ellipsoids themselves (anisotropic_volumes); the
        # spherical kernels inside the liquid keep their SPH volumes
        hs = support_r * radii
        aniso = ~np.all(G == np.eye(3) / hs[:, None, None], axis=(1, 2))
        if aniso.any():
            # no semi-axis is longer than max_axis_h * h (anisotropic_kernels)
            max_axis_h = check_anisotropy(support_r, **options)["max_axis_h"]
            consistent = ellipsoid_volumes(centres, G, det, (radii / radii.max()) ** 3, aniso,
                                           max_axis_h * float(hs.max()))
            volumes = np.where(aniso, consistent, volumes)
        amplitude = volumes * (8.0 / math.pi) * det
    else:
        amplitude = det * (support_r * radii) ** 3
    return centres, G, amplitude


def _check_anisotropic(positions, radius, cell_size, kernel, support_r, iso, block_size,
                       blobbiness, max_bytes, options):
    """Validate everything, and the extent of the positions, before the kernels are computed
    (points the block keys cannot hold are refused before the neighbour search)."""
    args = check_splat_args(positions, radius, cell_size, kernel, support_r, iso, block_size,
                            blobbiness, max_bytes, kernels=ANISOTROPIC_KERNELS,
                            iso_defaults=ANISOTROPIC_ISO)
    check_anisotropy(args[4], **options)
    check_block_range("positions", args[0], args[3], args[6])
    return args


def splat_sparse_anisotropic(positions, radius, cell_size, *, kernel: str = "sph",
                             support_r=None, iso=None, block_size: int = 8,
                             blobbiness: float = 4.0, skip_interior: bool = True,
                             max_bytes: int = DEFAULT_MAX_BYTES, **anisotropy) -> SparseGrid:
    """Particles -> implicit field with anisotropic kernels (Yu & Turk 2013), sparse grid.

    A drop-in for :func:`splat_sparse` (same first parameters, same output):
    :func:`filters.surface.anisotropy.anisotropic_kernels` gives smoothed centres and kernel
    matrices (support ``h = support_r * r``), then the ellipsoids are splatted
    (:mod:`filters.surface.ellipsoids`).

    Parameters
    ----------
    positions, radius, cell_size
        As in :func:`splat_sparse`; points the block keys cannot hold raise ValueError before
        any kernel is computed.
    kernel : {"sph", "metaball", "blobby"}
        Profile; ``sph`` splats ``sum_j V_j W(G_j (x - xbar_j)) det(G_j)`` with the SPH volumes
        ``V_j`` of the ellipsoids (:func:`filters.surface.volumes.anisotropic_volumes`).
    support_r : float, optional
        ``h / r`` (default per kernel as in :data:`filters.kernels.SPLAT_DEFAULTS`: sph 4).
    iso : float, optional
        Iso value (default :data:`filters.surface.ellipsoids.ANISOTROPIC_ISO`).
    block_size, blobbiness, skip_interior, max_bytes
        As in :func:`splat_sparse`.
    **anisotropy
        Options of :func:`filters.surface.anisotropy.anisotropic_kernels`
        (``neighbor_radius_r``, ``stretch``, ``min_neighbors``, ``smoothing``,
        ``layer_band_r``, ``max_axis_r``, ``isotropy``).

    Returns
    -------
    SparseGrid
    """
    (positions, radii, kernel, cell_size, support_r, iso, block_size, blobbiness,
     max_bytes) = _check_anisotropic(positions, radius, cell_size, kernel, support_r, iso,
                                     block_size, blobbiness, max_bytes, anisotropy)
    skip_interior = check_bool("skip_interior", skip_interior)
    centres, G, amplitude = _anisotropic_inputs(positions, radii, kernel, support_r, anisotropy)
    return ellipsoid_grid(centres, G, amplitude, cell_size, kernel=kernel, iso=iso,
                          block_size=block_size, blobbiness=blobbiness, max_bytes=max_bytes,
                          skip_interior=skip_interior, trusted=True)


def splat_dense_anisotropic(positions, radius, cell_size, *, kernel: str = "sph",
                            support_r=None, iso=None, block_size: int = 8,
                            blobbiness: float = 4.0, max_bytes: int = DEFAULT_MAX_BYTES,
                            **anisotropy) -> DenseField:
    """Dense counterpart of :func:`splat_sparse_anisotropic` (a drop-in for
    :func:`splat_dense`); same parameters, returns a
    :class:`filters.surface.grid.DenseField`."""
    (positions, radii, kernel, cell_size, support_r, iso, block_size, blobbiness,
     max_bytes) = _check_anisotropic(positions, radius, cell_size, kernel, support_r, iso,
                                     block_size, blobbiness, max_bytes, anisotropy)
    centres, G, amplitude = _anisotropic_inputs(positions, radii, kernel, support_r, anisotropy)
    return splat_ellipsoids_dense(centres, G, amplitude, cell_size, kernel=kernel, iso=iso,
                                  block_size=block_size, blobbiness=blobbiness,
                                  max_bytes=max_bytes)
