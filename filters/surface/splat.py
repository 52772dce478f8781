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
from typing import TYPE_CHECKING

import numpy as np

from ..kernels import SPLAT_DEFAULTS, SPLAT_KERNELS
from ..validation import check_bool, check_choice, check_int, check_points, check_radii, check_range
from .anisotropy import check_anisotropy, kernel_matrices
from .covariance import SMOOTHING_RAMP
from .crowding import check_crowding
from .ellipsoids import ANISOTROPIC_ISO, ANISOTROPIC_KERNELS, ellipsoid_grid, splat_ellipsoids_dense
from .grid import (
    DEFAULT_MAX_BYTES,
    DenseField,
    GridTooLargeError,
    SparseGrid,
    check_block_range,
    check_budget,
)
from .spheres import sphere_grid
from .volumes import ellipsoid_volumes, stretched_gain
from .walls import WALL_MARGIN_R, check_walls, grow_walls, mirror_ghosts, mirror_matrices

if TYPE_CHECKING:
    from collections.abc import Collection
    from typing import Any

    from numpy.typing import ArrayLike

    from ..geometry import Box

__all__ = [
    "GridTooLargeError",
    "splat_sparse",
    "splat_dense",
    "splat_sparse_anisotropic",
    "splat_dense_anisotropic",
    "check_splat_args",
]


def check_splat_args(positions: ArrayLike, radius: ArrayLike, cell_size: float, kernel: str,
                     support_r: float | None, iso: float | None, block_size: int, blobbiness: float,
                     max_bytes: int, kernels: Collection[str] = SPLAT_KERNELS,
                     iso_defaults: dict[str, float] | None = None) -> tuple:
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
    if positions.shape[0]:  # quadratic work refused before it starts (filters.surface.crowding)
        check_crowding(positions, support_r * float(radii.max()))
    return positions, radii, kernel, cell_size, support_r, iso, block_size, blobbiness, max_bytes


def splat_sparse(positions: np.ndarray, radius: ArrayLike, cell_size: float, *, kernel: str = "sph",
                 support_r: float | None = None, iso: float | None = None, block_size: int = 8,
                 blobbiness: float = 4.0, skip_interior: bool = True,
                 max_bytes: int = DEFAULT_MAX_BYTES,
                 walls: Box | tuple[ArrayLike, ArrayLike] | None = None) -> SparseGrid:
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
    walls : filters.geometry.Box or (lower, upper), optional
        The liquid's box-shaped container (m): particles within a kernel support of its walls
        are mirrored across them (ghost particles, :mod:`filters.surface.walls`), so that the
        field near a wall is the interior's, and only blocks that meet the box grown by
        :data:`filters.surface.walls.WALL_MARGIN_R` radii are computed (the others count as
        outside): the surface continues through the walls, to be cut at them.

    Returns
    -------
    SparseGrid
        Implicit values (negative inside) on the evaluated blocks.
    """
    (positions, radii, kernel, cell_size, support_r, iso, block_size, blobbiness,
     max_bytes) = check_splat_args(positions, radius, cell_size, kernel, support_r, iso,
                                   block_size, blobbiness, max_bytes)
    skip_interior = check_bool("skip_interior", skip_interior)
    walls = check_walls(walls)
    # before any key is computed: far-apart points must not wrap past 2^20 blocks
    check_block_range("positions", positions, cell_size, block_size)
    positions, radii, domain = _with_ghosts(positions, radii, walls, support_r)
    return sphere_grid(positions, radii, cell_size, kernel=kernel, support_r=support_r, iso=iso,
                       block_size=block_size, blobbiness=blobbiness, max_bytes=max_bytes,
                       skip_interior=skip_interior, domain=domain)


def _check_dense_budget(positions, cell_size, block_size, max_bytes, extent_m):
    """Refuse a dense box larger than ``max_bytes`` before any work (4 bytes per voxel)."""
    if positions.shape[0]:
        check_block_range("positions", positions, cell_size, block_size)
        ext = (positions.max(axis=0) - positions.min(axis=0) + 2 * extent_m) / cell_size + 3
        check_budget(int(4 * np.prod(ext)), int(max_bytes),
                     f"a dense grid of about {ext.astype(int).tolist()} voxels")


def splat_dense(positions: np.ndarray, radius: ArrayLike, cell_size: float, *, kernel: str = "sph",
                support_r: float | None = None, iso: float | None = None, block_size: int = 8,
                blobbiness: float = 4.0, max_bytes: int = DEFAULT_MAX_BYTES,
                walls: Box | tuple[ArrayLike, ArrayLike] | None = None) -> DenseField:
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
    walls = check_walls(walls)
    rmax = float(radii.max()) if radii.size else 0.0
    _check_dense_budget(positions, cell_size, block_size, max_bytes, support_r * rmax)
    positions, radii, domain = _with_ghosts(positions, radii, walls, support_r)
    grid = sphere_grid(positions, radii, cell_size, kernel=kernel, support_r=support_r, iso=iso,
                       block_size=block_size, blobbiness=blobbiness, max_bytes=max_bytes,
                       evaluate_all=True, domain=domain)
    return grid.to_dense(max_bytes=max_bytes)


def _domain(walls, radii):
    """The box of the blocks computed with ``walls``: the walls grown by WALL_MARGIN_R radii."""
    if walls is None:
        return None
    return grow_walls(walls, WALL_MARGIN_R * (float(radii.max()) if radii.size else 0.0))


def _with_ghosts(positions, radii, walls, reach_r):
    """The particles and their ghosts across ``walls`` (those within ``reach_r`` radii of a
    wall); positions, radii and the domain of the blocks to compute."""
    if walls is None or not positions.shape[0]:
        return positions, radii, _domain(walls, radii)
    ghosts, source, _, _ = mirror_ghosts(positions, *walls, reach_r * float(radii.max()))
    return (np.ascontiguousarray(np.concatenate([positions, ghosts])),
            np.concatenate([radii, radii[source]]), _domain(walls, radii))


# --------------------------------------------------------------------------------------------
# Anisotropic kernels (Yu & Turk 2013)
# --------------------------------------------------------------------------------------------


def _anisotropic_inputs(positions, radii, kernel, support_r, options, walls=None):
    """Kernel centres, matrices and amplitudes of the anisotropic splat (with the ghosts across
    ``walls`` appended, whose kernels mirror their particles')."""
    n = positions.shape[0]
    opts = check_anisotropy(support_r, **options)
    if walls is not None and n:
        reach = max(opts["neighbor_radius_r"], opts["max_axis_h"] * support_r) * radii.max()
        ghosts, source, signs, shifts = mirror_ghosts(positions, *walls, reach)
        positions = np.ascontiguousarray(np.concatenate([positions, ghosts]))
        radii = np.concatenate([radii, radii[source]])
    k = kernel_matrices(positions, radii, support_r=support_r, targets=n, **options)
    if positions.shape[0] > n:
        # a ghost's kernel is its particle's, mirrored
        k.centres[n:] = k.centres[source] * signs + shifts
        k.G[n:] = mirror_matrices(k.G[source], signs)
        for field in (k.volumes, k.dets, k.strength, k.anisotropy):
            field[n:] = field[source]
    if kernel != "sph":
        return k.centres, k.G, k.dets * (support_r * radii) ** 3
    # the ellipsoids' volumes under the ellipsoids themselves (anisotropic_volumes), faded in
    # with the strength of the anisotropy; the spherical kernels keep their SPH volumes
    volumes = k.volumes
    aniso = k.strength > 0.0
    if aniso[:n].any():
        hs = support_r * radii
        # no semi-axis is longer than max_axis_h * h (anisotropic_kernels)
        need = aniso.copy()
        need[n:] = False
        consistent = ellipsoid_volumes(k.centres, k.G, k.dets, (radii / radii.max()) ** 3,
                                       need, opts["max_axis_h"] * float(hs.max()))
        if positions.shape[0] > n:
            consistent[n:] = consistent[source]
        fade = np.minimum(k.strength / SMOOTHING_RAMP, 1.0)
        volumes = np.where(aniso, volumes + fade * (consistent - volumes), volumes)
    amplitude = volumes * (8.0 / math.pi) * k.dets * stretched_gain(k.anisotropy)
    return k.centres, k.G, amplitude


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


def splat_sparse_anisotropic(positions: np.ndarray, radius: ArrayLike, cell_size: float, *,
                             kernel: str = "sph", support_r: float | None = None,
                             iso: float | None = None, block_size: int = 8, blobbiness: float = 4.0,
                             skip_interior: bool = True, max_bytes: int = DEFAULT_MAX_BYTES,
                             walls: Box | tuple[ArrayLike, ArrayLike] | None = None,
                             **anisotropy: Any) -> SparseGrid:
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
    walls : filters.geometry.Box or (lower, upper), optional
        As in :func:`splat_sparse`; the ghosts reach as far as the neighbourhoods, and each
        mirrors its particle's kernel.
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
    walls = check_walls(walls)
    centres, G, amplitude = _anisotropic_inputs(positions, radii, kernel, support_r, anisotropy,
                                                walls)
    return ellipsoid_grid(centres, G, amplitude, cell_size, kernel=kernel, iso=iso,
                          block_size=block_size, blobbiness=blobbiness, max_bytes=max_bytes,
                          skip_interior=skip_interior, trusted=True,
                          domain=_domain(walls, radii))


def splat_dense_anisotropic(positions: np.ndarray, radius: ArrayLike, cell_size: float, *,
                            kernel: str = "sph", support_r: float | None = None,
                            iso: float | None = None, block_size: int = 8, blobbiness: float = 4.0,
                            max_bytes: int = DEFAULT_MAX_BYTES,
                            walls: Box | tuple[ArrayLike, ArrayLike] | None = None,
                            **anisotropy: Any) -> DenseField:
    """Dense counterpart of :func:`splat_sparse_anisotropic` (a drop-in for
    :func:`splat_dense`); same parameters, returns a
    :class:`filters.surface.grid.DenseField`."""
    (positions, radii, kernel, cell_size, support_r, iso, block_size, blobbiness,
     max_bytes) = _check_anisotropic(positions, radius, cell_size, kernel, support_r, iso,
                                     block_size, blobbiness, max_bytes, anisotropy)
    walls = check_walls(walls)
    centres, G, amplitude = _anisotropic_inputs(positions, radii, kernel, support_r, anisotropy,
                                                walls)
    return splat_ellipsoids_dense(centres, G, amplitude, cell_size, kernel=kernel, iso=iso,
                                  block_size=block_size, blobbiness=blobbiness,
                                  max_bytes=max_bytes, domain=_domain(walls, radii))
