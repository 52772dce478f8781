"""Marching tetrahedra: the zero level set of a voxel field through the Kuhn split of its cubes.

Every cube of the voxel lattice is cut into the six tetrahedra of the Kuhn (Freudenthal) split
(:mod:`filters.simplices`), the same in every cube, so neighbouring cubes cut their shared face
along the same diagonal; each tetrahedron is contoured on its own (Doi & Koide 1991, "An
efficient method of triangulating equi-valued surfaces by using tetrahedral cells"; Treece,
Prager & Gee 1999, "Regularised marching tetrahedra").  The field is linear on every
tetrahedron, so the surface has no ambiguous cases: it is watertight and, away from voxels that
hold exactly the iso value, a 2-manifold, with every vertex on one lattice edge (an axis, a
face diagonal or the cube's main diagonal), linearly interpolated between the edge's two
voxel values and shared by all the triangles that use it.  A voxel is inside when its value is
below ``iso`` (negative inside, as the splats write), and triangles face outward.

Fields come as *tiles*: boxes of cells of one or more arrays in voxel-index coordinates, like
the bricks of a :class:`filters.surface.grid.SparseGrid` (or a dense box cut into tiles).  Each
tile is contoured independently and in parallel; a vertex on a tile's boundary plane is
computed by the same arithmetic from the same two voxel values in every tile that has it, so
the pieces stitch exactly (:func:`filters.surface.mesh.stitch`), as the flying-edges bricks
do.  Compared with marching cubes the mesh has about twice the triangles (and thinner ones).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..simplices import CORNER_OFFSETS, KUHN_DIRECTIONS, KUHN_TETS
from ..validation import check_int
from .mesh import piece_flags, stitch

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from .grid import SparseGrid

__all__ = ["tile_boxes", "contour_tiles", "stitch_tiles", "TetraPieces", "contour_grid",
           "contour_array"]


def _tables():
    """Triangles of the 16 sign cases of a positively oriented tetrahedron, and the lattice
    edge (lower corner, direction) of every pair of cube corners."""
    # reference tetrahedron, positively oriented
    ref = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    tri_count = np.zeros(16, np.int64)
    tri_edges = np.zeros((16, 2, 3, 2), np.int64)
    for case in range(16):
        inside = [v for v in range(4) if case >> v & 1]
        outside = [v for v in range(4) if not case >> v & 1]
        if len(inside) in (0, 4):
            continue
        if len(inside) == 1 or len(outside) == 1:
            apex = inside[0] if len(inside) == 1 else outside[0]
            others = [v for v in range(4) if v != apex]
            tris = [[(apex, others[0]), (apex, others[1]), (apex, others[2])]]
        else:
            a, b = inside
            c, d = outside
            # the quad a-c, a-d, b-d, b-c, split along (a, c)-(b, d)
            tris = [[(a, c), (a, d), (b, d)], [(a, c), (b, d), (b, c)]]
        grow = ref[outside].mean(axis=0) - ref[inside].mean(axis=0)
        for n, tri in enumerate(tris):
            p = np.array([0.5 * (ref[e[0]] + ref[e[1]]) for e in tri])
            normal = np.cross(p[1] - p[0], p[2] - p[0])
            if normal @ grow < 0.0:
                tri = [tri[0], tri[2], tri[1]]
            tri_edges[case, n] = tri
        tri_count[case] = len(tris)
    edge_lower = np.full((8, 8), -1, np.int64)
    edge_dir = np.full((8, 8), -1, np.int64)
    for p in range(8):
        for q in range(8):
            d = CORNER_OFFSETS[q] - CORNER_OFFSETS[p]
            for lo, step in ((p, d), (q, -d)):
                for k in range(7):
                    if np.array_equal(step, KUHN_DIRECTIONS[k]):
                        edge_lower[p, q] = lo
                        edge_dir[p, q] = k
    return tri_count, tri_edges, edge_lower, edge_dir


TRI_COUNT, TRI_EDGES, EDGE_LOWER, EDGE_DIR = _tables()


#: Cube corner at the end of every edge direction from corner 0 (``KUHN_DIRECTIONS``).
DIR_CORNER = np.array([int(d[0] + 2 * d[1] + 4 * d[2]) for d in KUHN_DIRECTIONS], np.int64)


@njit(cache=True, inline="always")
def _cube_mask(v, k, j, i, iso):
    m = 0
    for c in range(8):
        if v[k + (c >> 2), j + ((c >> 1) & 1), i + (c & 1)] < iso:
            m |= 1 << c
    return m


@njit(cache=True, inline="always")
def _on_high_face(box, k, j):
    """Whether the row ``(j, k)`` of a tile lies on its high y or z face (else only its last
    point, on the high x face, has no cube of its own)."""
    return k == box[6] or j == box[5]


@njit(cache=True)
def _count_tile(values, box, iso, tets, dirs, dir_corner, tri_count, masks, moff):
    """Sign masks of a tile's cubes into ``masks[moff:]``; returns (vertices, triangles).

    Every vertex lies on an edge leaving a lattice point towards higher indices, inside the
    cube whose lowest corner is that point; points on the tile's high faces have no such cube
    and their edges are looked at one by one.
    """
    v = values[box[0]]
    i0, j0, k0, i1, j1, k1 = box[1], box[2], box[3], box[4], box[5], box[6]
    nv = 0
    nt = 0
    idx = moff
    for k in range(k0, k1):
        for j in range(j0, j1):
            for i in range(i0, i1):
                m = _cube_mask(v, k, j, i, iso)
                masks[idx] = m
                idx += 1
                if m == 0 or m == 255:
                    continue
                b0 = m & 1
                for d in range(7):
                    if (m >> dir_corner[d]) & 1 != b0:
                        nv += 1
                for n in range(6):
                    case = 0
                    for c in range(4):
                        case |= ((m >> tets[n, c]) & 1) << c
                    nt += tri_count[case]
    for k in range(k0, k1 + 1):
        for j in range(j0, j1 + 1):
            start = i0 if _on_high_face(box, k, j) else i1
            for i in range(start, i1 + 1):
                ina = v[k, j, i] < iso
                for d in range(7):
                    di, dj, dk = dirs[d, 0], dirs[d, 1], dirs[d, 2]
                    if i + di > i1 or j + dj > j1 or k + dk > k1:
                        continue
                    if ina != (v[k + dk, j + dj, i + di] < iso):
                        nv += 1
    return nv, nt


@njit(cache=True, inline="always")
def _vertex(v, origin, iso, points, index, k, j, i, dk, dj, di):
    a = v[k, j, i]
    b = v[k + dk, j + dj, i + di]
    t = (iso - a) / (b - a)
    points[index, 0] = np.float32(origin[0] + i + t * di)
    points[index, 1] = np.float32(origin[1] + j + t * dj)
    points[index, 2] = np.float32(origin[2] + k + t * dk)


@njit(cache=True)
def _fill_tile(values, box, origin, iso, tets, dirs, dir_corner, tri_count, tri_edges,
               edge_lower, edge_dir, masks, moff, points, p0, tris, t0, vid):
    """Write a tile's vertices (from ``p0``) and triangles (from ``t0``), with the cube masks
    :func:`_count_tile` stored; ``vid`` (nk + 1, nj + 1, ni + 1, 7) is scratch."""
    v = values[box[0]]
    i0, j0, k0, i1, j1, k1 = box[1], box[2], box[3], box[4], box[5], box[6]
    nv = p0
    idx = moff
    for k in range(k0, k1):
        for j in range(j0, j1):
            for i in range(i0, i1):
                m = masks[idx]
                idx += 1
                if m == 0 or m == 255:
                    continue
                b0 = m & 1
                for d in range(7):
                    if (m >> dir_corner[d]) & 1 != b0:
                        _vertex(v, origin, iso, points, nv, k, j, i, dirs[d, 2], dirs[d, 1],
                                dirs[d, 0])
                        vid[k - k0, j - j0, i - i0, d] = nv
                        nv += 1
    for k in range(k0, k1 + 1):
        for j in range(j0, j1 + 1):
            start = i0 if _on_high_face(box, k, j) else i1
            for i in range(start, i1 + 1):
                ina = v[k, j, i] < iso
                for d in range(7):
                    di, dj, dk = dirs[d, 0], dirs[d, 1], dirs[d, 2]
                    if i + di > i1 or j + dj > j1 or k + dk > k1:
                        continue
                    if ina != (v[k + dk, j + dj, i + di] < iso):
                        _vertex(v, origin, iso, points, nv, k, j, i, dk, dj, di)
                        vid[k - k0, j - j0, i - i0, d] = nv
                        nv += 1
    nt = t0
    idx = moff
    for k in range(k0, k1):
        for j in range(j0, j1):
            for i in range(i0, i1):
                m = masks[idx]
                idx += 1
                if m == 0 or m == 255:
                    continue
                for n in range(6):
                    case = 0
                    for c in range(4):
                        case |= ((m >> tets[n, c]) & 1) << c
                    for r in range(tri_count[case]):
                        for s in range(3):
                            ca = tets[n, tri_edges[case, r, s, 0]]
                            cb = tets[n, tri_edges[case, r, s, 1]]
                            lo = edge_lower[ca, cb]
                            tris[nt, s] = vid[k - k0 + (lo >> 2), j - j0 + ((lo >> 1) & 1),
                                              i - i0 + (lo & 1), edge_dir[ca, cb]]
                        nt += 1


@njit(parallel=True, cache=True)
def _count_tiles(values, boxes, iso, tets, dirs, dir_corner, tri_count, masks, moffs, counts):
    for b in prange(boxes.shape[0]):
        nv, nt = _count_tile(values, boxes[b], iso, tets, dirs, dir_corner, tri_count, masks,
                             moffs[b])
        counts[b, 0] = nv
        counts[b, 1] = nt


@njit(parallel=True, cache=True)
def _fill_tiles(values, boxes, origins, iso, tets, dirs, dir_corner, tri_count, tri_edges,
                edge_lower, edge_dir, masks, moffs, pstart, tstart, points, tris):
    for b in prange(boxes.shape[0]):
        if pstart[b + 1] == pstart[b]:
            continue
        box = boxes[b]
        vid = np.empty((box[6] - box[3] + 1, box[5] - box[2] + 1, box[4] - box[1] + 1, 7),
                       np.int64)
        _fill_tile(values, box, origins[b], iso, tets, dirs, dir_corner, tri_count, tri_edges,
                   edge_lower, edge_dir, masks, moffs[b], points, pstart[b], tris, tstart[b],
                   vid)


def tile_boxes(shape: tuple[int, int, int], tile: int = 32, which: int = 0) -> NDArray[np.int64]:
    """Cut the cells of an array of voxel ``shape = (nz, ny, nx)`` into tiles of at most
    ``tile`` cells per edge.

    Returns
    -------
    (B, 7) int64
        ``(which, i0, j0, k0, i1, j1, k1)`` per tile (cells ``[i0, i1)`` etc.).
    """
    nz, ny, nx = (int(s) for s in shape)
    if min(nx, ny, nz) < 2:
        return np.zeros((0, 7), np.int64)
    cuts = [np.unique(np.r_[np.arange(0, n - 1, tile), n - 1]) for n in (nx, ny, nz)]
    boxes = [(which, i0, j0, k0, i1, j1, k1)
             for k0, k1 in zip(cuts[2][:-1], cuts[2][1:], strict=False)
             for j0, j1 in zip(cuts[1][:-1], cuts[1][1:], strict=False)
             for i0, i1 in zip(cuts[0][:-1], cuts[0][1:], strict=False)]
    return np.array(boxes, np.int64).reshape(-1, 7)


def contour_tiles(values: np.ndarray, boxes: np.ndarray, origins: np.ndarray,
                  iso: float = 0.0) -> tuple[NDArray[np.float32], NDArray[np.int64],
                                             NDArray[np.int64]]:
    """Marching tetrahedra over tiles, unstitched (vertices in global voxel-index units).

    Parameters
    ----------
    values : (K, nz, ny, nx) float32 array
        Voxel values of ``K`` arrays.
    boxes : (B, 7) int64 array
        Tiles ``(which, i0, j0, k0, i1, j1, k1)``: cells ``[i0, i1) x [j0, j1) x [k0, k1)`` of
        ``values[which]``.
    origins : (B, 3) int64 array
        Global voxel index of ``values[which][0, 0, 0]``, per tile.
    iso : float
        Iso value; voxels below it are inside.

    Returns
    -------
    points : (P, 3) float32
        Vertices in global voxel-index coordinates, tile after tile.
    triangles : (T, 3) int64
        Outward-oriented triangles.
    starts : (B + 1,) int64
        Tile ``b`` owns the points ``starts[b]:starts[b + 1]``.
    """
    values = np.ascontiguousarray(values, dtype=np.float32)
    boxes = np.ascontiguousarray(boxes, dtype=np.int64).reshape(-1, 7)
    origins = np.ascontiguousarray(origins, dtype=np.int64).reshape(-1, 3)
    iso = np.float32(iso)
    cells = (boxes[:, 4] - boxes[:, 1]) * (boxes[:, 5] - boxes[:, 2]) * (boxes[:, 6] - boxes[:, 3])
    moffs = np.zeros(boxes.shape[0] + 1, np.int64)
    np.cumsum(cells, out=moffs[1:])
    masks = np.empty(moffs[-1], np.uint8)
    counts = np.zeros((boxes.shape[0], 2), np.int64)
    _count_tiles(values, boxes, iso, KUHN_TETS, KUHN_DIRECTIONS, DIR_CORNER, TRI_COUNT, masks,
                 moffs, counts)
    pstart = np.zeros(boxes.shape[0] + 1, np.int64)
    tstart = np.zeros(boxes.shape[0] + 1, np.int64)
    np.cumsum(counts[:, 0], out=pstart[1:])
    np.cumsum(counts[:, 1], out=tstart[1:])
    points = np.empty((pstart[-1], 3), np.float32)
    tris = np.empty((tstart[-1], 3), np.int64)
    _fill_tiles(values, boxes, origins, iso, KUHN_TETS, KUHN_DIRECTIONS, DIR_CORNER, TRI_COUNT,
                TRI_EDGES, EDGE_LOWER, EDGE_DIR, masks, moffs, pstart, tstart, points, tris)
    return points, tris, pstart


def stitch_tiles(points: np.ndarray, tris: np.ndarray, starts: np.ndarray, boxes: np.ndarray,
                 origins: np.ndarray, cell_size: float) -> tuple[NDArray[np.float32], np.ndarray]:
    """Merge the vertices tiles share and scale to metres: one watertight mesh.

    Returns
    -------
    points : (P', 3) float32
        Vertices (m).
    triangles : (T', 3) int32 or int64
        Outward-oriented triangles (those collapsed by the merge dropped).
    """
    boxes = np.asarray(boxes, np.int64).reshape(-1, 7)
    origins = np.asarray(origins, np.int64).reshape(-1, 3)
    lo = (origins + boxes[:, 1:4]).astype(np.float32)
    hi = (origins + boxes[:, 4:7]).astype(np.float32)
    flags = piece_flags(points, np.asarray(starts, np.int64), lo, hi)
    dtype = np.int32 if points.shape[0] < 2**31 else np.int64
    tris = np.ascontiguousarray(tris, dtype=dtype)
    pts, tris = stitch(points, tris, flags, reverse=False)
    pts = pts * np.float32(cell_size)
    return pts, tris


class TetraPieces:
    """Collects the marching-tetrahedra pieces (:func:`contour_tiles`) of arrays in voxel-index
    coordinates, and stitches them into one mesh (:meth:`mesh`).

    Parameters
    ----------
    iso : float
        Iso value; voxels below it are inside.
    """

    def __init__(self, iso: float = 0.0):
        self.iso = float(iso)
        self.points, self.tris, self.boxes, self.origins, self.starts = [], [], [], [], [0]
        self.count = 0

    def add(self, values: np.ndarray, index_origin: ArrayLike, tile: int = 32) -> None:
        """Contour ``values`` (nz, ny, nx) whose voxel ``[0, 0, 0]`` has global index
        ``index_origin`` (cut into tiles of ``tile`` cells)."""
        boxes = tile_boxes(values.shape, tile)
        if boxes.shape[0]:
            origins = np.repeat(np.asarray(index_origin, np.int64).reshape(1, 3),
                                boxes.shape[0], axis=0)
            self.add_tiles(values[None], boxes, origins)

    def add_tiles(self, values: np.ndarray, boxes: np.ndarray, origins: np.ndarray) -> None:
        """Contour the tiles ``boxes`` of ``values`` (K, nz, ny, nx) (see
        :func:`filters.surface.tetra.contour_tiles`)."""
        pts, tris, starts = contour_tiles(values, boxes, origins, self.iso)
        if tris.shape[0] == 0:
            return
        self.points.append(pts)
        self.tris.append(tris + self.count)
        self.boxes.append(boxes)
        self.origins.append(origins)
        self.starts.append(starts[1:] + self.count)
        self.count += pts.shape[0]

    def mesh(self, cell_size: float) -> tuple[NDArray[np.float32], np.ndarray]:
        """The stitched mesh of every piece added: points (P, 3) float32 (m) and outward
        triangles (T, 3); the pieces are released."""
        if not self.points:
            return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32)
        pts = np.concatenate(self.points)
        tris = np.concatenate(self.tris)
        starts = np.concatenate([np.zeros(1, np.int64)] + self.starts[1:])
        self.points, self.tris = [], []
        return stitch_tiles(pts, tris, starts, np.concatenate(self.boxes),
                            np.concatenate(self.origins), cell_size)


def contour_grid(grid: SparseGrid, group: int = 4,
                 chunk: int = 64) -> tuple[NDArray[np.float32], np.ndarray]:
    """Marching tetrahedra on a :class:`filters.surface.grid.SparseGrid`, brick by brick.

    The grid's bricks of ``group ** 3`` blocks (one voxel of overlap with their neighbours,
    :meth:`~filters.surface.grid.SparseGrid.bricks`) are filled ``chunk`` at a time and those
    that hold a sign change are contoured in parallel, then all pieces are stitched.

    Returns
    -------
    points : (P, 3) float32
        Vertices (m).
    triangles : (T, 3) int
        Outward-oriented triangles.
    """
    group = check_int("group", group, 1, 64)
    chunk = check_int("chunk", chunk, 1)
    pieces = TetraPieces()
    if grid.empty:
        return pieces.mesh(grid.cell_size)
    bricks = grid.bricks(group)
    table = grid.block_table()
    span = group * grid.block_size
    buffer = np.empty((min(chunk, bricks.shape[0]),) + (span + 1,) * 3, np.float32)
    for s in range(0, bricks.shape[0], chunk):
        part = bricks[s:s + chunk]
        vals, crossing = grid.fill_bricks(part, group, table, crossing=True, out=buffer)
        which = np.flatnonzero(crossing)
        if which.size == 0:
            continue
        boxes = np.zeros((which.size, 7), np.int64)
        boxes[:, 0] = which
        boxes[:, 4:] = span
        pieces.add_tiles(vals, boxes, part[which] * span)
    return pieces.mesh(grid.cell_size)


def contour_array(values: np.ndarray, index_origin: ArrayLike, cell_size: float, iso: float = 0.0,
                  tile: int = 32) -> tuple[NDArray[np.float32], np.ndarray]:
    """Marching tetrahedra on one dense array: tiles contoured in parallel, then stitched.

    Parameters
    ----------
    values : (nz, ny, nx) float array
        Voxel values, voxel ``(i, j, k)`` at ``values[k, j, i]``.
    index_origin : (3,) int
        Global voxel index of ``values[0, 0, 0]``.
    cell_size : float
        Voxel edge (m).
    iso : float
        Iso value; voxels below it are inside.
    tile : int
        Cells per tile edge.

    Returns
    -------
    points : (P, 3) float32
        Vertices (m).
    triangles : (T, 3) int
        Outward-oriented triangles.
    """
    values = np.ascontiguousarray(values, dtype=np.float32)
    boxes = tile_boxes(values.shape, tile)
    origins = np.repeat(np.asarray(index_origin, np.int64).reshape(1, 3), boxes.shape[0], axis=0)
    pts, tris, starts = contour_tiles(values[None], boxes, origins, iso)
    return stitch_tiles(pts, tris, starts, boxes, origins, cell_size)
