"""Block-sparse voxel grids: storage that scales with the surface, not with the bounding box.

The voxel lattice is global: voxel ``(i, j, k)`` sits at ``(i, j, k) * cell_size`` (m), so two
frames of an animation sample the same lattice and a translation by a whole number of cells
translates the field exactly. Voxels are grouped in cubic *blocks* of ``block_size ** 3``;
block ``(bx, by, bz)`` owns voxels ``[bx * B, (bx + 1) * B)`` along x (and likewise y, z).

A :class:`SparseGrid` stores the implicit values (negative inside, zero on the surface, positive
outside) only for the blocks the surface passes near ("evaluated" blocks). Blocks found to lie
wholly inside the liquid are listed without values; every other block is outside. Contouring
reads the grid in *bricks* (cubes of ``G ** 3`` blocks plus one overlapping voxel layer on the
high side), each a small dense array that a marching-cubes routine can process independently;
since bricks share their boundary voxels bit for bit, the pieces stitch without cracks.

The dense equivalent of a sparse grid (:meth:`SparseGrid.to_dense`) is exactly the array that
evaluating every voxel would give wherever the surface is; this is what the tests compare.

A byte budget guards every allocation that grows with the grid: :class:`GridTooLargeError`
(a :class:`ValueError`) says how much was needed and how to get under the budget.

Extent. A block key packs the three block coordinates, 21 bits each, into one int64, so
block coordinates live in ``[-2**20, 2**20)``: positions within about ``2**20 * block_size *
cell_size`` of the origin (42 km at the default 8 voxels of 5 mm). The splats refuse points
beyond that up front (:func:`check_block_range`, a ValueError naming the extent and the
limit) instead of letting the keys wrap. The keys stay absolute rather than relative to the
cloud: relative keys would reach at most twice as far (a span of ``2**21`` blocks, still short
of two clusters 100 km apart at 5 mm voxels, which need 2.5 million blocks) but change what a
key means for every consumer of :attr:`SparseGrid.keys`. Two clusters anywhere inside the range
are handled: the grid holds only their own blocks, whatever the distance between them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..binning import EMPTY_KEY, index_keys, insert_key, lookup

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = [
    "DEFAULT_MAX_BYTES",
    "BLOCK_LIMIT",
    "GridTooLargeError",
    "check_block_range",
    "format_bytes",
    "SparseGrid",
    "DenseField",
    "check_budget",
    "pack_keys",
    "unpack_keys",
    "pack_key",
    "unpack_key",
    "block_keys",
    "dilate_keys",
    "corner_index",
]

#: Default memory budget for a grid (bytes): 4 GiB.
DEFAULT_MAX_BYTES = 4 * 1024**3

_OFF = 1 << 20  # block coordinates live in [-2**20, 2**20)
_BITS = 21
_M21 = (1 << 21) - 1

#: Block coordinates a key holds: ``[-BLOCK_LIMIT, BLOCK_LIMIT)`` along each axis.
BLOCK_LIMIT = _OFF

#: Blocks kept free between the points' home blocks and the ends of the key range: the
#: kernels' reach (at most 65 blocks: the splats refuse supports above 64 blocks), corner
#: samples and the dense box's outer voxel layer (1), contouring bricks (up to 64 blocks wide),
#: and one for rounding. Lookups there must not wrap onto another block's key.
_MARGIN = 65 + 1 + 64 + 1


class GridTooLargeError(ValueError):
    """A grid would need more memory than the configured budget ``max_bytes`` allows."""


def format_bytes(nbytes: float) -> str:
    """A byte count for messages: ``"512 bytes"``, ``"1.5 KiB"``, ``"3.052 MiB"``, ``"4 GiB"``
    (binary units, 4 significant digits; never rounds a non-zero size to 0)."""
    nbytes = float(nbytes)
    if abs(nbytes) < 1024:
        return f"{nbytes:.0f} byte" + ("" if nbytes == 1 else "s")
    for unit in ("KiB", "MiB", "GiB", "TiB", "PiB"):
        nbytes /= 1024.0
        if abs(nbytes) < 1024 or unit == "PiB":
            return f"{nbytes:.4g} {unit}"
    raise AssertionError  # unreachable


def check_block_range(name: str, points: np.ndarray, cell_size: float, block_size: int) -> None:
    """Raise ValueError unless every block holding a point has a key (see the module docstring).

    Block ``floor(x / (block_size * cell_size))`` of every coordinate, with a margin of
    ``_MARGIN`` blocks for the kernels' reach and contouring, must lie in
    ``[-BLOCK_LIMIT, BLOCK_LIMIT)``. Vectorised (a min and a max over the points); call it
    before computing any key.

    Parameters
    ----------
    name : str
        The parameter holding the points, for the message.
    points : (N, 3) float64
        Finite positions (m).
    cell_size : float
        Voxel edge (m).
    block_size : int
        Voxels per block edge.

    Raises
    ------
    ValueError
        Naming ``name``, the axis, the points' extent (m and blocks) and the limit: "span N
        blocks, more than the index holds" when no translation could fit the points, otherwise
        "outside ..., translate the points nearer the origin".
    """
    if points.shape[0] == 0:
        return
    inv = 1.0 / cell_size
    lo_m = points.min(axis=0)
    hi_m = points.max(axis=0)
    with np.errstate(over="ignore", invalid="ignore"):
        lo = np.floor(lo_m * inv / block_size)  # as the kernels compute home blocks
        hi = np.floor(hi_m * inv / block_size)
    first = -_OFF + _MARGIN
    last = _OFF - 1 - _MARGIN
    bad = np.flatnonzero(~((lo >= first) & (hi <= last)))
    if bad.size == 0:
        return
    a = int(bad[0])
    axis = "xyz"[a]
    edge = block_size * cell_size
    span = hi[a] - lo[a] + 1.0
    capacity = last - first + 1
    where = (f"{name} lie between {lo_m[a]:.6g} and {hi_m[a]:.6g} m along {axis}: {span:.6g} "
             f"blocks of block_size * cell_size = {block_size} * {cell_size:g} = {edge:g} m")
    if not span <= capacity:
        raise ValueError(
            f"{where}, more than the {capacity} (2^21 less {2 * _MARGIN} for the kernels' reach "
            f"and contouring) that the block index holds per axis; split the cloud or increase "
            f"cell_size (or block_size)")
    raise ValueError(
        f"{where}, reaching block {lo[a] if lo[a] < first else hi[a]:.6g}; the block index "
        f"holds blocks {first} to {last} per axis (|{axis}| up to about {last * edge:.6g} m "
        f"from the origin at this cell_size and block_size); translate the points nearer the "
        f"origin (the lattice is global), or increase cell_size (or block_size)")


def check_budget(nbytes: int, max_bytes: int, what: str) -> None:
    """Raise :class:`GridTooLargeError` if ``nbytes`` exceeds ``max_bytes``.

    Parameters
    ----------
    nbytes : int
        Bytes the allocation would take.
    max_bytes : int
        The budget (bytes).
    what : str
        What is being allocated, for the message.
    """
    if nbytes > max_bytes:
        need = format_bytes(nbytes)
        limit = format_bytes(max_bytes)
        if need == limit:  # too close to tell apart at 4 digits
            need = f"{need} ({int(nbytes):,} bytes)"
            limit = f"{limit} ({int(max_bytes):,} bytes)"
        raise GridTooLargeError(
            f"{what} needs {need}, above max_bytes = {limit}; increase cell_size (memory falls "
            f"as its cube), use the sparse grid, or raise max_bytes"
        )


# --------------------------------------------------------------------------------------------
# Block keys (hashed with the index of filters.binning)
# --------------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def pack_key(bx, by, bz):
    """Key of block ``(bx, by, bz)`` (block coordinates in ``[-2**20, 2**20)``), 21 bits each."""
    return ((bx + _OFF) << 42) | ((by + _OFF) << 21) | (bz + _OFF)


@njit(cache=True, inline="always")
def unpack_key(key):
    """Block coordinates ``(bx, by, bz)`` of a key (inverse of :func:`pack_key`)."""
    return ((key >> 42) & _M21) - _OFF, ((key >> 21) & _M21) - _OFF, (key & _M21) - _OFF


@njit(cache=True)
def block_keys(positions, inv_cell, block_size):
    """Key of the block holding each point: ``floor(x * inv_cell / block_size)`` per axis.

    Parameters
    ----------
    positions : (N, 3) float64
        Points (m), within the range of :func:`check_block_range`.
    inv_cell : float
        Inverse voxel edge (1/m).
    block_size : int
        Voxels per block edge.

    Returns
    -------
    (N,) int64
    """
    n = positions.shape[0]
    keys = np.empty(n, np.int64)
    for p in range(n):
        bx = np.int64(math.floor(positions[p, 0] * inv_cell / block_size))
        by = np.int64(math.floor(positions[p, 1] * inv_cell / block_size))
        bz = np.int64(math.floor(positions[p, 2] * inv_cell / block_size))
        keys[p] = pack_key(bx, by, bz)
    return keys


@njit(cache=True)
def _dilate(unique, reach):
    """Distinct keys of all blocks within ``reach`` blocks (Chebyshev) of those in ``unique``."""
    table = np.full(1024, EMPTY_KEY, np.int64)
    values = np.empty(1024, np.int64)
    out = np.empty(1024, np.int64)
    count = 0
    for u in range(unique.size):
        bx, by, bz = unpack_key(unique[u])
        for dz in range(-reach, reach + 1):
            for dy in range(-reach, reach + 1):
                for dx in range(-reach, reach + 1):
                    table, values, out, count, _ = insert_key(table, values, out, count,
                                                           pack_key(bx + dx, by + dy, bz + dz))
    return out[:count].copy()


@njit(cache=True)
def corner_index(keys):
    """Distinct corner points of blocks ``keys`` (as block-lattice keys) and, per block, the
    ranks of its 8 corners ``(M, 8)`` (x fastest)."""
    table = np.full(1024, EMPTY_KEY, np.int64)
    values = np.empty(1024, np.int64)
    out = np.empty(1024, np.int64)
    count = 0
    ranks = np.empty((keys.size, 8), np.int32)
    for m in range(keys.size):
        bx, by, bz = unpack_key(keys[m])
        c = 0
        for dz in range(2):
            for dy in range(2):
                for dx in range(2):
                    table, values, out, count, r = insert_key(table, values, out, count,
                                                           pack_key(bx + dx, by + dy, bz + dz))
                    ranks[m, c] = r
                    c += 1
    return out[:count].copy(), ranks


def pack_keys(coords: np.ndarray) -> np.ndarray:
    """Pack block coordinates ``(M, 3) int64`` into sortable ``(M,) int64`` keys."""
    coords = np.asarray(coords, dtype=np.int64)
    if coords.size and (coords.min() < -_OFF or coords.max() >= _OFF):
        raise ValueError(f"block coordinates must be in [{-_OFF}, {_OFF}); reduce the domain")
    return ((coords[:, 0] + _OFF) << 42) | ((coords[:, 1] + _OFF) << 21) | (coords[:, 2] + _OFF)


def unpack_keys(keys: np.ndarray) -> np.ndarray:
    """Inverse of :func:`pack_keys`: ``(M,) int64`` keys -> ``(M, 3) int64`` coordinates."""
    keys = np.asarray(keys, dtype=np.int64)
    out = np.empty((keys.size, 3), np.int64)
    out[:, 0] = ((keys >> 42) & _M21) - _OFF
    out[:, 1] = ((keys >> 21) & _M21) - _OFF
    out[:, 2] = (keys & _M21) - _OFF
    return out


def dilate_keys(unique: np.ndarray, reach: int) -> np.ndarray:
    """Distinct keys of the blocks within ``reach`` blocks of those in ``unique`` (sorted).

    Marked on a dense bitmap of the blocks' box when it holds at most 64 cells per block
    marked (a liquid's blocks fill their box), else collected in a hash set (far-apart
    clusters); the same keys either way."""
    unique = np.ascontiguousarray(unique, dtype=np.int64)
    reach = int(reach)
    if unique.size:
        coords = unpack_keys(unique)
        lo = coords.min(axis=0) - reach
        dims = coords.max(axis=0) + reach + 1 - lo
        if float(np.prod(dims.astype(np.float64))) <= 64.0 * unique.size * (2 * reach + 1) ** 3:
            return _dilate_dense(coords - lo, lo, dims, reach)
    out = _dilate(unique, reach)
    out.sort()
    return out


@njit(cache=True)
def _dilate_dense(rel, lo, dims, reach):
    """:func:`_dilate` on a bitmap of the box ``lo + [0, dims)``: keys in sorted order (x, then
    y, then z: the order of :func:`pack_key`)."""
    nx, ny, nz = dims[0], dims[1], dims[2]
    mark = np.zeros((nx, ny, nz), np.bool_)
    for u in range(rel.shape[0]):
        x, y, z = rel[u, 0], rel[u, 1], rel[u, 2]
        for a in range(x - reach, x + reach + 1):
            for b in range(y - reach, y + reach + 1):
                for c in range(z - reach, z + reach + 1):
                    mark[a, b, c] = True
    count = 0
    for a in range(nx):
        for b in range(ny):
            for c in range(nz):
                count += mark[a, b, c]
    out = np.empty(count, np.int64)
    k = 0
    for a in range(nx):
        for b in range(ny):
            for c in range(nz):
                if mark[a, b, c]:
                    out[k] = pack_key(lo[0] + a, lo[1] + b, lo[2] + c)
                    k += 1
    return out


# --------------------------------------------------------------------------------------------
# The grid
# --------------------------------------------------------------------------------------------


@dataclass
class DenseField:
    """Implicit values on a dense box of the global voxel lattice.

    Attributes
    ----------
    values : (nz, ny, nx) float32
        Implicit values: negative inside, zero on the surface, positive outside. C order with x
        fastest, which is VTK's point order for image data.
    index_origin : (3,) int64
        Global voxel index ``(i, j, k)`` of ``values[0, 0, 0]``.
    cell_size : float
        Voxel edge (m).
    """

    values: np.ndarray
    index_origin: np.ndarray
    cell_size: float

    @property
    def origin(self) -> np.ndarray:
        """World position of ``values[0, 0, 0]`` (m), shape (3,)."""
        return self.index_origin.astype(np.float64) * self.cell_size

    @property
    def dimensions(self) -> tuple:
        """Number of voxels along x, y, z."""
        nz, ny, nx = self.values.shape
        return (nx, ny, nz)


@dataclass
class SparseGrid:
    """Implicit values on the blocks of the global voxel lattice that the surface passes near.

    Attributes
    ----------
    cell_size : float
        Voxel edge (m).
    block_size : int
        Voxels per block edge ``B``.
    keys : (M,) int64
        Packed coordinates of the evaluated blocks (see :func:`pack_keys`), in evaluation order.
    data : (M, B, B, B) float32
        Their implicit values, ``data[m, k, j, i]`` for voxel ``(i, j, k)`` within the block.
    inside_keys : (I,) int64
        Packed coordinates of blocks wholly inside (sorted); no values are stored for them.
    inside_value, outside_value : float
        Constants standing for the values in inside and outside blocks (signs are what matter:
        no surface passes through these blocks or their faces).
    """

    cell_size: float
    block_size: int
    keys: np.ndarray
    data: np.ndarray
    inside_keys: np.ndarray
    inside_value: float
    outside_value: float

    @property
    def block_coords(self) -> np.ndarray:
        """Block coordinates of the evaluated blocks, ``(M, 3) int64``."""
        return unpack_keys(self.keys)

    @property
    def inside_coords(self) -> np.ndarray:
        """Block coordinates of the inside blocks, ``(I, 3) int64``."""
        return unpack_keys(self.inside_keys)

    @property
    def nbytes(self) -> int:
        """Bytes held by the grid's arrays."""
        return int(self.keys.nbytes + self.data.nbytes + self.inside_keys.nbytes)

    @property
    def empty(self) -> bool:
        """True when no block is evaluated (there is no surface)."""
        return self.keys.size == 0

    def block_table(self) -> tuple[np.ndarray, np.ndarray]:
        """Hash index of the blocks (see :func:`filters.binning.lookup`): the rank of an
        evaluated block, -2 for an inside block, -1 (absent) for an outside one."""
        keys = np.concatenate([self.keys, self.inside_keys])
        table, values, _, _ = index_keys(keys)
        # ranks >= M are inside blocks: map them to -2 (inside); absent -> -1 (outside)
        m = self.keys.size
        values = np.where(values >= m, -2, values)
        return table, values

    def bricks(self, group: int = 4) -> NDArray[np.int64]:
        """Brick coordinates that together cover every cell the surface can cross.

        Parameters
        ----------
        group : int
            Blocks per brick edge ``G``; a brick covers voxels ``[b G B, (b + 1) G B]``
            (inclusive: one voxel of overlap with the next brick).

        Returns
        -------
        (K, 3) int64
            Brick coordinates, sorted.
        """
        if self.empty:
            return np.zeros((0, 3), np.int64)
        coords = self.block_coords
        # a cell whose lower corner lies in block b - d (d in {0, 1}^3) may touch block b
        shifts = np.array([[a, b, c] for c in (0, 1) for b in (0, 1) for a in (0, 1)], np.int64)
        candidates = (coords[:, None, :] - shifts[None, :, :]).reshape(-1, 3)
        bricks = np.floor_divide(candidates, group)
        keys = np.unique(pack_keys(bricks))
        return unpack_keys(keys)

    def may_cross(self, bricks: np.ndarray, group: int = 4,
                  table: tuple | None = None) -> np.ndarray:
        """Which bricks may hold a sign change, decided from their blocks without filling them.

        A brick's voxels lie in the ``(group + 1)^3`` blocks it touches; where those hold only
        negative values (inside blocks, evaluated blocks wholly negative) or only values
        ``>= 0`` (outside blocks, evaluated blocks wholly non-negative), the brick holds no
        sign change. The test is conservative: a brick it keeps may still turn out to hold
        none (:meth:`fill_bricks` with ``crossing`` tells), a brick it drops never holds one.

        Parameters
        ----------
        bricks : (K, 3) int64
            Brick coordinates (see :meth:`bricks`).
        group : int
            Blocks per brick edge.
        table : tuple, optional
            :meth:`block_table`, from a previous call.

        Returns
        -------
        (K,) bool
        """
        if table is None:
            table = self.block_table()
        bricks = np.ascontiguousarray(bricks, dtype=np.int64)
        out = np.zeros(bricks.shape[0], np.bool_)
        if bricks.shape[0]:
            signs = _block_signs(self.data)
            _bricks_with_both_signs(out, bricks, group, self.block_size, table[0], table[1],
                                    signs, self.inside_value < 0.0, self.outside_value < 0.0)
        return out

    def fill_bricks(self, bricks: np.ndarray, group: int = 4,
                    table: tuple[np.ndarray, np.ndarray] | None = None, crossing: bool = False,
                    out: np.ndarray | None = None
                    ) -> NDArray[np.float32] | tuple[NDArray[np.float32], NDArray[np.bool_]]:
        """Dense values of the given bricks.

        Parameters
        ----------
        bricks : (K, 3) int64
            Brick coordinates (see :meth:`bricks`).
        group : int
            Blocks per brick edge.
        table : tuple, optional
            :meth:`block_table`, from a previous call (speeds up repeated calls).

        crossing : bool
            Also return, per brick, whether it holds both signs (a surface).
        out : (K', n, n, n) float32, optional
            A buffer to fill (``K' >= K``; reusing one avoids page faults); its first ``K``
            bricks are returned.

        Returns
        -------
        (K, n, n, n) float32
            Values with ``n = group * block_size + 1``; brick ``b`` starts at global voxel index
            ``b * group * block_size``.
        (K,) bool
            Only with ``crossing``.
        """
        if table is None:
            table = self.block_table()
        bricks = np.ascontiguousarray(bricks, dtype=np.int64)
        n = group * self.block_size + 1
        if out is None:
            out = np.empty((bricks.shape[0], n, n, n), np.float32)
        else:
            out = out[:bricks.shape[0]]
        cross = np.zeros(bricks.shape[0], np.bool_)
        _fill_bricks(out, cross, bricks, group, self.block_size, table[0], table[1], self.data,
                     np.float32(self.inside_value), np.float32(self.outside_value))
        return (out, cross) if crossing else out

    def to_dense(self, index_lo: np.ndarray | None = None, index_hi: np.ndarray | None = None,
                 max_bytes: int = DEFAULT_MAX_BYTES) -> DenseField:
        """The dense equivalent of the grid over a box of the voxel lattice.

        Parameters
        ----------
        index_lo, index_hi : (3,) int, optional
            Voxel index box ``[lo, hi)``; default: the evaluated and inside blocks plus one
            outside voxel layer on every side.
        max_bytes : int
            Memory budget (bytes) for the dense array.

        Returns
        -------
        DenseField
        """
        bsz = self.block_size
        all_coords = np.concatenate([self.block_coords, self.inside_coords])
        if index_lo is None or index_hi is None:
            if all_coords.shape[0] == 0:
                lo = np.zeros(3, np.int64)
                hi = np.ones(3, np.int64) * 2
            else:
                lo = all_coords.min(axis=0) * bsz - 1
                hi = (all_coords.max(axis=0) + 1) * bsz + 2
            index_lo = lo if index_lo is None else np.asarray(index_lo, np.int64)
            index_hi = hi if index_hi is None else np.asarray(index_hi, np.int64)
        index_lo = np.asarray(index_lo, np.int64)
        index_hi = np.asarray(index_hi, np.int64)
        shape = tuple(int(s) for s in (index_hi - index_lo)[::-1])
        check_budget(4 * int(np.prod(shape)), max_bytes, f"a dense grid of {shape} voxels")
        values = np.empty(shape, np.float32)
        table = self.block_table()
        _fill_box(values, index_lo, bsz, table[0], table[1], self.data,
                  np.float32(self.inside_value), np.float32(self.outside_value))
        return DenseField(values=values, index_origin=index_lo, cell_size=self.cell_size)


@njit(parallel=True, cache=True)
def _fill_box(values, lo, bsz, table, ranks, data, inside, outside):
    nz, ny, nx = values.shape
    for k in prange(nz):
        gk = lo[2] + k
        bz = gk // bsz
        lz = gk - bz * bsz
        for j in range(ny):
            gj = lo[1] + j
            by = gj // bsz
            ly = gj - by * bsz
            i = 0
            while i < nx:
                gi = lo[0] + i
                bx = gi // bsz
                lx = gi - bx * bsz
                run = min(bsz - lx, nx - i)
                r = lookup(table, ranks, pack_key(bx, by, bz))
                if r >= 0:
                    for t in range(run):
                        values[k, j, i + t] = data[r, lz, ly, lx + t]
                elif r == -2:
                    for t in range(run):
                        values[k, j, i + t] = inside
                else:
                    for t in range(run):
                        values[k, j, i + t] = outside
                i += run


@njit(parallel=True, cache=True, fastmath=True)
def _fill_bricks(out, cross, bricks, group, bsz, table, ranks, data, inside, outside):
    n = out.shape[1]
    nb = (n + bsz - 1) // bsz  # blocks a brick's voxels touch per axis (group + 1)
    for b in prange(bricks.shape[0]):
        # the brick's blocks looked up once (not once per run of voxels)
        rank = np.empty((nb, nb, nb), np.int64)
        for c in range(nb):
            for bj in range(nb):
                for a in range(nb):
                    rank[c, bj, a] = lookup(table, ranks, pack_key(bricks[b, 0] * group + a,
                                                                 bricks[b, 1] * group + bj,
                                                                 bricks[b, 2] * group + c))
        for k in range(n):
            c = k // bsz
            lz = k - c * bsz
            for j in range(n):
                bj = j // bsz
                ly = j - bj * bsz
                for a in range(nb):
                    i0 = a * bsz
                    run = min(bsz, n - i0)
                    r = rank[c, bj, a]
                    if r >= 0:
                        for t in range(run):
                            out[b, k, j, i0 + t] = data[r, lz, ly, t]
                    elif r == -2:
                        for t in range(run):
                            out[b, k, j, i0 + t] = inside
                    else:
                        for t in range(run):
                            out[b, k, j, i0 + t] = outside
        flat = out[b].ravel()
        lo = flat[0]
        hi = flat[0]
        for t in range(flat.size):
            lo = min(lo, flat[t])
            hi = max(hi, flat[t])
        cross[b] = lo < 0 and hi >= 0


@njit(parallel=True, cache=True)
def _block_signs(data):
    """Per evaluated block: bit 1 if it holds a value < 0, bit 2 if one >= 0 (NaN: neither)."""
    signs = np.zeros(data.shape[0], np.int8)
    for m in prange(data.shape[0]):
        flat = data[m].ravel()
        neg = False
        pos = False
        for t in range(flat.size):
            neg = neg or flat[t] < 0
            pos = pos or flat[t] >= 0
        signs[m] = (1 if neg else 0) + (2 if pos else 0)
    return signs


@njit(parallel=True, cache=True)
def _bricks_with_both_signs(out, bricks, group, bsz, table, ranks, signs, inside_negative,
                            outside_negative):
    """``out[b]``: the blocks brick ``b`` touches hold values of both signs."""
    n = group * bsz + 1
    nb = (n + bsz - 1) // bsz  # blocks a brick's voxels touch per axis (group + 1)
    inside = 1 if inside_negative else 2
    outside = 1 if outside_negative else 2
    for b in prange(bricks.shape[0]):
        s = 0
        for c in range(nb):
            for bj in range(nb):
                for a in range(nb):
                    r = lookup(table, ranks, pack_key(bricks[b, 0] * group + a,
                                                      bricks[b, 1] * group + bj,
                                                      bricks[b, 2] * group + c))
                    if r >= 0:
                        s |= signs[r]
                    elif r == -2:
                        s |= inside
                    else:
                        s |= outside
        out[b] = s == 3
