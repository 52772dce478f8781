"""Spring topologies for hair, cloth and jello (arrays in, arrays out).

* :func:`hair_strands` — chains of particles with stretch springs ``i, i+1`` and a quadratic
  bending energy on every three consecutive particles (Bergou et al. 2006,
  :func:`filters.elastic.springs.bending_springs`), roots pinned (and optionally clamped).
* :func:`cloth_grid` — a rectangular grid with structural, shear and bend springs (Provot 1995).
* :func:`cloth_from_mesh` — any triangle mesh: edge springs plus a bending spring joining the two
  vertices opposite every shared (manifold) edge.
* :func:`jello_from_mesh` — a closed, consistently oriented triangle mesh: its interior is
  voxelised into a lattice of particles with structural, face-diagonal and body-diagonal springs,
  and the mesh vertices are embedded in the lattice with trilinear weights, so the simulation's
  output is the user's mesh, deformed (free-form deformation, Sederberg & Parry 1986).
* :func:`icosphere` — a closed test mesh.

All builders return a :class:`SpringTopology`; spring kinds are :data:`STRETCH`, :data:`SHEAR`,
:data:`BEND`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..memory import check_memory
from ..validation import check_finite_vector, check_int, check_points, check_range
from .surfaces import BYTES_PER_NODE, check_triangles, mesh_volume
from .voxelize import voxelize_mesh

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = [
    "STRETCH",
    "SHEAR",
    "BEND",
    "SpringTopology",
    "Embedding",
    "hair_strands",
    "cloth_grid",
    "cloth_from_mesh",
    "jello_from_mesh",
    "icosphere",
    "mesh_volume",
    "check_triangles",
]

STRETCH, SHEAR, BEND = 0, 1, 2



@dataclass(frozen=True)
class Embedding:
    """A surface mesh embedded in a particle lattice by interpolation weights.

    Attributes
    ----------
    nodes : (M, K) int64 array
        Particles of the lattice cell that holds each mesh vertex (``K = 8``: the corners of a
        cube, trilinear weights; ``K = 4``: the corners of a tetrahedron, barycentric weights).
    weights : (M, K) float64 array
        Weights (sum to 1); vertex ``j`` is at ``sum_k weights[j, k] x[nodes[j, k]]``.
    triangles : (T, 3) int64 array
        The mesh's triangles.
    rest_points : (M, 3) float64 array
        The mesh vertices at rest (m).
    """

    nodes: np.ndarray
    weights: np.ndarray
    triangles: np.ndarray
    rest_points: np.ndarray

    def points(self, positions: np.ndarray) -> NDArray[np.float64]:
        """Mesh vertices (M, 3) for lattice ``positions`` (N, 3)."""
        return np.einsum("mk,mkj->mj", self.weights, positions[self.nodes])


@dataclass(frozen=True)
class SpringTopology:
    """Particles and springs built from a geometry.

    Attributes
    ----------
    positions : (N, 3) float64 array
        Rest positions (m).
    springs : (S, 2) int64 array
        Particle pairs.
    kinds : (S,) int8 array
        :data:`STRETCH`, :data:`SHEAR` or :data:`BEND` per spring.
    masses : (N,) float64 array
        Lumped particle masses (kg).
    pinned : (N,) bool array
        Particles held fixed (hair roots); cloth and jello start with none.
    topology : {"lines", "polys"}
        Output cell type: hair strands are lines, cloth and jello surfaces are polygons.
    offsets, indices : int64 arrays
        Output cells in CSR form (over particles, or over the embedded mesh's vertices).
    embedding : Embedding or None
        For jello: the user's mesh embedded in the lattice.
    bend_triples : (B, 3) int64 array or None
        For hair: consecutive particles ``(a, b, c)`` of the strands, bent with the quadratic
        energy of :func:`filters.elastic.springs.bending_springs`.
    bend_scale : (B,) float64 array or None
        Per triple, the factor that turns a bending rigidity ``EI`` (N m^2) into its
        stiffness ``EI / l^3`` (N/m), ``l`` the segment length (m).
    """

    positions: np.ndarray
    springs: np.ndarray
    kinds: np.ndarray
    masses: np.ndarray
    pinned: np.ndarray
    topology: str
    offsets: np.ndarray
    indices: np.ndarray
    embedding: Embedding | None = field(default=None)
    bend_triples: np.ndarray | None = field(default=None)
    bend_scale: np.ndarray | None = field(default=None)

    @property
    def rest_lengths(self) -> NDArray[np.float64]:
        """Rest lengths (S,) (m) of the springs at the rest positions."""
        d = self.positions[self.springs[:, 0]] - self.positions[self.springs[:, 1]]
        return np.sqrt(np.einsum("ij,ij->i", d, d))

    def with_pins(self, pinned: ArrayLike) -> SpringTopology:
        """A copy with ``pinned`` (indices or an (N,) bool mask) held fixed."""
        mask = np.zeros(self.positions.shape[0], dtype=bool)
        p = np.asarray(pinned)
        if p.dtype == bool:
            if p.shape != mask.shape:
                raise ValueError(f"pinned mask must have shape {mask.shape}, got {p.shape}")
            mask |= p
        else:
            idx = p.astype(np.int64).ravel()
            if idx.size and (idx.min() < 0 or idx.max() >= mask.size):
                raise ValueError(f"pinned indices must be in [0, {mask.size - 1}]")
            mask[idx] = True
        return SpringTopology(self.positions, self.springs, self.kinds, self.masses, mask,
                              self.topology, self.offsets, self.indices, self.embedding,
                              self.bend_triples, self.bend_scale)


def _cells(cells):
    cells = np.asarray(cells, dtype=np.int64)
    offsets = np.arange(0, cells.size + 1, cells.shape[1], dtype=np.int64)
    return offsets, cells.ravel().copy()


def _unique_pairs(pairs):
    pairs = np.sort(np.asarray(pairs, dtype=np.int64), axis=1)
    return np.unique(pairs, axis=0)


# ---------------------------------------------------------------------------------------------
def hair_strands(roots: ArrayLike, directions: ArrayLike, *, segments: int = 16,
                 length: float = 0.3, linear_density: float = 1e-3, cells: str = "polylines",
                 clamped: bool = False) -> SpringTopology:
    """Straight strands of particles, roots pinned.

    Parameters
    ----------
    roots : (R, 3) array_like
        Root positions (m).
    directions : (R, 3) array_like or (3,)
        Growth directions (normalised here).
    segments : int
        Springs per strand, >= 2 (``segments + 1`` particles).
    length : float
        Strand length (m), > 0.
    linear_density : float
        Mass per length (kg/m), > 0.
    cells : {"polylines", "segments"}
        Output cells: one polyline per strand, or one two-point line per stretch spring (for
        exporters without polylines, such as XDMF).
    clamped : bool
        Also pin each strand's second particle, so that the strand leaves its root in the
        given direction (a follicle holds a hair's direction at the scalp).

    Returns
    -------
    SpringTopology
        Stretch springs ``i, i+1`` and bending triples ``(i-1, i, i+1)`` at every interior
        particle (``bend_triples``, ``bend_scale = 1 / l^3``): the hair's bending stiffness
        is a bending rigidity (N m^2) and its shape does not depend on ``segments``.
    """
    if cells not in ("polylines", "segments"):
        raise ValueError(f"cells must be 'polylines' or 'segments', got {cells!r}")
    roots = check_points("roots", roots)
    segments = check_int("segments", segments, 2)
    length = check_range("length", length, 0.0, math.inf, low_inclusive=False)
    linear_density = check_range("linear_density", linear_density, 0.0, math.inf,
                                 low_inclusive=False)
    dirs = np.asarray(directions, dtype=np.float64)
    if dirs.shape == (3,):
        dirs = np.broadcast_to(dirs, roots.shape)
    dirs = check_points("directions", dirs)
    if dirs.shape != roots.shape:
        raise ValueError("directions must be (3,) or have the shape of roots")
    norms = np.linalg.norm(dirs, axis=1)
    if np.any(norms == 0.0):
        raise ValueError("directions must be non-zero vectors")
    dirs = dirs / norms[:, None]
    r = roots.shape[0]
    if r == 0:
        raise ValueError("roots must hold at least one strand")
    n_per = segments + 1
    check_memory(f"{r:,} strands of {segments} segments ({r * n_per:,} particles)",
                 r * n_per * BYTES_PER_NODE, "use fewer strands or segments")
    t = np.linspace(0.0, length, n_per)
    pos = (roots[:, None, :] + t[None, :, None] * dirs[:, None, :]).reshape(-1, 3)
    base = (np.arange(r) * n_per)[:, None]
    stretch = np.stack([base + np.arange(segments), base + np.arange(1, n_per)], -1).reshape(-1, 2)
    triples = np.stack([base + np.arange(segments - 1), base + np.arange(1, segments),
                        base + np.arange(2, n_per)], -1).reshape(-1, 3).astype(np.int64)
    springs = stretch.astype(np.int64)
    kinds = np.full(len(stretch), STRETCH, dtype=np.int8)
    seg = length / segments
    m = np.full(n_per, linear_density * seg)
    m[0] = m[-1] = 0.5 * linear_density * seg
    masses = np.tile(m, r)
    pinned = np.zeros(r * n_per, dtype=bool)
    pinned[::n_per] = True
    if clamped:
        pinned[1::n_per] = True
    if cells == "polylines":
        offsets, indices = _cells(np.arange(r * n_per).reshape(r, n_per))
    else:
        offsets, indices = _cells(stretch)
    scale = np.full(triples.shape[0], 1.0 / seg ** 3)
    return SpringTopology(pos, springs, kinds, masses, pinned, "lines", offsets, indices,
                          bend_triples=triples, bend_scale=scale)


def cloth_grid(nx: int, ny: int, *, size: ArrayLike = (1.0, 1.0),
               origin: ArrayLike = (0.0, 0.0, 0.0), plane: str = "xy",
               areal_density: float = 0.2) -> SpringTopology:
    """A rectangular cloth of ``nx`` x ``ny`` particles.

    Parameters
    ----------
    nx, ny : int
        Particles along the two sides, >= 2.
    size : (float, float)
        Side lengths (m), > 0.
    origin : sequence of 3 float
        Position of particle 0 (m).
    plane : {"xy", "xz"}
        ``"xy"``: horizontal cloth; ``"xz"``: vertical (hanging) cloth, rows going down in z.
    areal_density : float
        Mass per area (kg/m^2), > 0.

    Returns
    -------
    SpringTopology
        Particle ``i + nx * j``; structural springs between grid neighbours, shear springs on both
        diagonals of every cell, bend springs between particles two apart; two triangles per cell.
    """
    nx = check_int("nx", nx, 2)
    ny = check_int("ny", ny, 2)
    sx, sy = (check_range("size", float(s), 0.0, math.inf, low_inclusive=False) for s in size)
    origin = check_finite_vector("origin", origin, 3)
    if plane not in ("xy", "xz"):
        raise ValueError(f"plane must be 'xy' or 'xz', got {plane!r}")
    areal_density = check_range("areal_density", areal_density, 0.0, math.inf,
                                low_inclusive=False)
    check_memory(f"a {nx} x {ny} cloth ({nx * ny:,} particles)", nx * ny * BYTES_PER_NODE,
                 "use fewer particles")
    u = np.linspace(0.0, sx, nx)
    w = np.linspace(0.0, sy, ny)
    uu, ww = np.meshgrid(u, w)  # (ny, nx)
    pos = np.zeros((ny * nx, 3))
    pos[:, 0] = uu.ravel()
    if plane == "xy":
        pos[:, 1] = ww.ravel()
    else:
        pos[:, 2] = -ww.ravel()
    pos += origin
    idx = np.arange(nx * ny).reshape(ny, nx)
    structural = np.concatenate([
        np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], 1),
        np.stack([idx[:-1, :].ravel(), idx[1:, :].ravel()], 1)])
    shear = np.concatenate([
        np.stack([idx[:-1, :-1].ravel(), idx[1:, 1:].ravel()], 1),
        np.stack([idx[:-1, 1:].ravel(), idx[1:, :-1].ravel()], 1)])
    bend = np.concatenate([
        np.stack([idx[:, :-2].ravel(), idx[:, 2:].ravel()], 1),
        np.stack([idx[:-2, :].ravel(), idx[2:, :].ravel()], 1)])
    springs = np.concatenate([structural, shear, bend]).astype(np.int64)
    kinds = np.concatenate([np.full(len(structural), STRETCH), np.full(len(shear), SHEAR),
                            np.full(len(bend), BEND)]).astype(np.int8)
    wu = np.full(nx, sx / (nx - 1))
    wu[[0, -1]] *= 0.5
    wv = np.full(ny, sy / (ny - 1))
    wv[[0, -1]] *= 0.5
    masses = areal_density * np.outer(wv, wu).ravel()
    a = idx[:-1, :-1].ravel()
    b = idx[:-1, 1:].ravel()
    c = idx[1:, 1:].ravel()
    d = idx[1:, :-1].ravel()
    tris = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    offsets, indices = _cells(tris)
    return SpringTopology(pos, springs, kinds, masses, np.zeros(nx * ny, dtype=bool), "polys",
                          offsets, indices)


def _edges(tris):
    """Directed edges (3T, 2) and, per undirected edge, its triangles."""
    directed = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    owner = np.tile(np.arange(tris.shape[0]), 3)
    opposite = np.concatenate([tris[:, 2], tris[:, 0], tris[:, 1]])
    return directed, owner, opposite


def cloth_from_mesh(points: ArrayLike, triangles: ArrayLike, *,
                    areal_density: float = 0.2) -> SpringTopology:
    """Cloth springs from any triangle mesh.

    Parameters
    ----------
    points : (N, 3) array_like
        Vertices (m).
    triangles : (T, 3) int array_like
        Triangles.
    areal_density : float
        Mass per area (kg/m^2), > 0; each vertex gets a third of its triangles' mass.

    Returns
    -------
    SpringTopology
        A stretch spring per edge and a bend spring between the two vertices opposite every edge
        shared by exactly two triangles; output cells are the triangles.
    """
    pts = check_points("points", points)
    tris = check_triangles("triangles", triangles, pts.shape[0])
    areal_density = check_range("areal_density", areal_density, 0.0, math.inf,
                                low_inclusive=False)
    directed, owner, opposite = _edges(tris)
    und = np.sort(directed, axis=1)
    keys = und[:, 0] * pts.shape[0] + und[:, 1]
    order = np.argsort(keys, kind="stable")
    ks = keys[order]
    uniq, start, counts = np.unique(ks, return_index=True, return_counts=True)
    stretch = np.stack([uniq // pts.shape[0], uniq % pts.shape[0]], 1)
    two = counts == 2
    first = order[start[two]]
    second = order[start[two] + 1]
    bend = np.stack([opposite[first], opposite[second]], 1)
    bend = bend[bend[:, 0] != bend[:, 1]]
    bend = _unique_pairs(bend) if len(bend) else bend.reshape(0, 2)
    springs = np.concatenate([stretch, bend]).astype(np.int64)
    kinds = np.concatenate([np.full(len(stretch), STRETCH),
                            np.full(len(bend), BEND)]).astype(np.int8)
    area = 0.5 * np.linalg.norm(np.cross(pts[tris[:, 1]] - pts[tris[:, 0]],
                                         pts[tris[:, 2]] - pts[tris[:, 0]]), axis=1)
    masses = np.zeros(pts.shape[0])
    np.add.at(masses, tris.ravel(), np.repeat(area / 3.0, 3) * areal_density)
    if np.any(masses <= 0.0):
        raise ValueError("every vertex must belong to a triangle of non-zero area "
                         "(unused or isolated vertices found)")
    offsets, indices = _cells(tris)
    return SpringTopology(pts.copy(), springs, kinds, masses, np.zeros(pts.shape[0], bool),
                          "polys", offsets, indices)


def jello_from_mesh(points: ArrayLike, triangles: ArrayLike, *, spacing: float,
                    density: float = 1000.0) -> SpringTopology:
    """Voxelise a closed mesh into a spring lattice and embed the mesh in it.

    Parameters
    ----------
    points : (M, 3) array_like
        Mesh vertices (m).
    triangles : (T, 3) int array_like
        Triangles of a closed, consistently oriented 2-manifold.
    spacing : float
        Lattice spacing (m), > 0.
    density : float
        Mass density (kg/m^3), > 0; the lattice's total mass is ``density`` times the mesh's
        volume, spread evenly over the corners of the lattice cells.

    Returns
    -------
    SpringTopology
        Lattice particles; springs along cell edges (:data:`STRETCH`), face diagonals and body
        diagonals (:data:`SHEAR`); output cells are the mesh's triangles over the embedded
        vertices (``embedding``).

    Raises
    ------
    ValueError
        If the mesh is not a closed consistently oriented manifold, encloses no volume, or no
        lattice cell centre falls inside it (reduce ``spacing``).
    """
    pts = check_points("points", points)
    tris = check_triangles("triangles", triangles, pts.shape[0])
    spacing = check_range("spacing", spacing, 0.0, math.inf, low_inclusive=False)
    density = check_range("density", density, 0.0, math.inf, low_inclusive=False)
    vox = voxelize_mesh(pts, tris, spacing)
    tris, volume, origin, dims = vox.triangles, vox.volume, vox.origin, vox.dims
    cells, cell = vox.cells, vox.vertex_cells
    corner_offsets = np.array([[i, j, k] for k in (0, 1) for j in (0, 1) for i in (0, 1)])
    corners = cells[:, None, :] + corner_offsets[None, :, :]  # (C, 8, 3)
    nd = dims + 1
    lin = (corners[..., 0] * nd[1] + corners[..., 1]) * nd[2] + corners[..., 2]
    node_ids, local = np.unique(lin.ravel(), return_inverse=True)
    local = local.reshape(-1, 8)
    ijk = np.stack([node_ids // (nd[1] * nd[2]), (node_ids // nd[2]) % nd[1], node_ids % nd[2]], 1)
    positions = origin + ijk * spacing
    # Springs inside every cell: corner c = i + 2 j + 4 k.
    pairs_edge, pairs_diag = [], []
    for a in range(8):
        for b in range(a + 1, 8):
            dist = bin(a ^ b).count("1")
            (pairs_edge if dist == 1 else pairs_diag).append((a, b))
    pe = np.array(pairs_edge)
    pdg = np.array(pairs_diag)
    edge_springs = _unique_pairs(np.stack([local[:, pe[:, 0]].ravel(),
                                           local[:, pe[:, 1]].ravel()], 1))
    diag_springs = _unique_pairs(np.stack([local[:, pdg[:, 0]].ravel(),
                                           local[:, pdg[:, 1]].ravel()], 1))
    springs = np.concatenate([edge_springs, diag_springs]).astype(np.int64)
    kinds = np.concatenate([np.full(len(edge_springs), STRETCH),
                            np.full(len(diag_springs), SHEAR)]).astype(np.int8)
    masses = np.zeros(positions.shape[0])
    np.add.at(masses, local.ravel(), 1.0)
    masses *= density * volume / masses.sum()
    # Trilinear embedding of the mesh vertices in their cells.
    cell_index = {tuple(c): i for i, c in enumerate(cells.tolist())}
    rows = np.array([cell_index[tuple(c)] for c in cell.tolist()], dtype=np.int64)
    t = np.clip((pts - origin) / spacing - cell, 0.0, 1.0)
    wx = np.stack([1.0 - t[:, 0], t[:, 0]], 1)
    wy = np.stack([1.0 - t[:, 1], t[:, 1]], 1)
    wz = np.stack([1.0 - t[:, 2], t[:, 2]], 1)
    weights = np.empty((pts.shape[0], 8))
    for c in range(8):
        i, j, k = corner_offsets[c]
        weights[:, c] = wx[:, i] * wy[:, j] * wz[:, k]
    embedding = Embedding(local[rows].copy(), weights, tris.copy(), pts.copy())
    offsets, indices = _cells(tris)
    return SpringTopology(positions, springs, kinds, masses, np.zeros(positions.shape[0], bool),
                          "polys", offsets, indices, embedding)


def icosphere(radius: float = 1.0, subdivisions: int = 2,
              center: ArrayLike = (0.0, 0.0, 0.0)) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """A closed, outward-oriented triangulated sphere.

    Parameters
    ----------
    radius : float
        Radius (m), > 0.
    subdivisions : int
        Loop subdivisions of the icosahedron, in [0, 6] (``20 * 4**s`` triangles).
    center : sequence of 3 float
        Centre (m).

    Returns
    -------
    points : (M, 3) float64 array
    triangles : (T, 3) int64 array
    """
    radius = check_range("radius", radius, 0.0, math.inf, low_inclusive=False)
    subdivisions = check_int("subdivisions", subdivisions, 0, 6)
    center = check_finite_vector("center", center, 3)
    p = (1.0 + 5 ** 0.5) / 2.0
    verts = [(-1, p, 0), (1, p, 0), (-1, -p, 0), (1, -p, 0), (0, -1, p), (0, 1, p),
             (0, -1, -p), (0, 1, -p), (p, 0, -1), (p, 0, 1), (-p, 0, -1), (-p, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
             (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
             (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    pts = [np.array(v, dtype=np.float64) / np.linalg.norm(v) for v in verts]
    for _ in range(subdivisions):
        cache = {}
        new_faces = []

        def mid(a, b, cache=cache):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = pts[a] + pts[b]
                pts.append(m / np.linalg.norm(m))
                cache[key] = len(pts) - 1
            return cache[key]

        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new_faces += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new_faces
    points = np.array(pts) * radius + center
    return points, np.array(faces, dtype=np.int64)
