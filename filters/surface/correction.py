"""Volume correction of a reconstructed liquid surface: every closed piece encloses its particles.

A surface reconstructed from particles encloses a volume that depends on how the kernels sum
near the surface: small drops come out larger or smaller than their particles, and particles
that the solver packs closer to the walls than half a spacing leave a settled pool's surface
below its true height. :func:`correct_volume` moves each connected component of the mesh along
its vertex normals by one offset, found by Newton steps on its enclosed volume, until it
encloses the volume of the particles inside it (as in the volume-preserving offset of
Desbrun et al. 1999, one scalar per component):

* components: the connected pieces of the triangle mesh; their enclosed volume is the
  divergence-theorem sum ``sum_t p0 . (p1 x p2) / 6`` (negative for cavities, which are left
  alone);
* particles: each belongs to the component of its nearest vertex among the components that
  enclose a positive volume; the target of a component is the sum of its particles' volumes;
* directions: area-weighted vertex normals; where a ``shape`` bounds the liquid (the liquid
  scenes intersect their field with the tank's inner box), vertices within ``wall_band`` of its
  boundary and facing it (normal within 60 degrees of the wall's) are put on the wall (mesh
  smoothing moves them off it; at an edge of a box-shaped tank, on both walls: the chamfer
  that the voxel lattice cuts across the edge closes) and move only tangentially to it, and
  vertices moved outside are projected back onto it, so the surface lies flat against the
  walls and the water rises or sinks along them;
* offset: ``delta_c = (T_c - V_c) / (dV_c / d delta)``, Newton steps with the measured slope
  (secants after the first) until every volume is within ``tolerance`` of its target, within
  ``[-max_shrink, max_offset]``: a piece that encloses more than its particles (a splash
  whose particles are strewn within a kernel's reach of each other: the field fills the gaps)
  is shrunk a little at most, so that its thin sheets and ligaments are not eaten away.

The result depends on the mesh and the particles only (no state from earlier frames): a static
particle set gives the same surface in every frame.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from ..geometry import Box, Shape
from ..neighbors import NeighborSearch
from ..validation import check_int, check_points, check_range
from .clip import WALL_TOLERANCE, wall_constraints

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["correct_volume", "CorrectionInfo", "vertex_components", "FACING"]

#: A vertex within ``wall_band`` of a wall is put on it if its normal is within 60 degrees of
#: the wall's (cosine above this): the faces along a wall and the chamfers that sampling cuts
#: across the tank's edges (45 degrees to both walls: put on the edge).
FACING = 0.5


class CorrectionInfo(NamedTuple):
    """What :func:`correct_volume` did, per connected component (K components)."""

    #: (K,) float64: offsets along the normals (m), positive outwards.
    offsets: np.ndarray
    #: (K,) float64: enclosed volumes before (m^3).
    before: np.ndarray
    #: (K,) float64: enclosed volumes after (m^3).
    after: np.ndarray
    #: (K,) float64: the particles' volumes (m^3).
    target: np.ndarray
    #: (P,) int64: the component of every vertex (-1 for vertices of no triangle).
    labels: np.ndarray


@njit(cache=True)
def _find(parent, x):
    while parent[x] != x:
        parent[x] = parent[parent[x]]
        x = parent[x]
    return x


@njit(cache=True)
def _labels(tris, nverts):
    """Connected components of the vertices through the triangles: labels 0..K-1 in order of
    the components' smallest vertex, -1 for vertices of no triangle; returns (labels, K)."""
    parent = np.arange(nverts)
    used = np.zeros(nverts, np.bool_)
    for f in range(tris.shape[0]):
        a = _find(parent, tris[f, 0])
        used[tris[f, 0]] = True
        for c in range(1, 3):
            used[tris[f, c]] = True
            b = _find(parent, tris[f, c])
            if a != b:
                lo = min(a, b)
                parent[max(a, b)] = lo
                a = lo
    labels = np.full(nverts, -1, np.int64)
    k = 0
    for v in range(nverts):
        if used[v]:
            r = _find(parent, v)
            if r == v:
                labels[v] = k
                k += 1
    for v in range(nverts):
        if used[v]:
            labels[v] = labels[_find(parent, v)]
    return labels, k


def vertex_components(triangles: np.ndarray, nverts: int) -> tuple[NDArray[np.int64], int]:
    """Connected components of a triangle mesh's vertices.

    Parameters
    ----------
    triangles : (T, 3) int
        Vertex indices.
    nverts : int
        Number of vertices.

    Returns
    -------
    labels : (nverts,) int64
        Component of every vertex, numbered by its smallest vertex; -1 for unused vertices.
    count : int
        Number of components.
    """
    tris = np.ascontiguousarray(triangles, dtype=np.int64)
    if tris.size and (tris.min() < 0 or tris.max() >= nverts):
        raise ValueError(f"triangles must index vertices 0..{nverts - 1}")
    return _labels(tris.reshape(-1, 3), int(nverts))


@njit(cache=True)
def _votes(vertex_particle, vertex_distance, labels, solid, n):
    """Component of each particle from the vertices whose nearest particle it is: that of the
    nearest such vertex on a solid component (-1 where no vertex votes)."""
    comp = np.full(n, -1, np.int64)
    best = np.full(n, np.inf)
    for v in range(vertex_particle.shape[0]):
        c = labels[v]
        if c < 0 or not solid[c]:
            continue
        j = vertex_particle[v]
        if vertex_distance[v] < best[j]:
            best[j] = vertex_distance[v]
            comp[j] = c
    return comp


@njit(cache=True)
def _clusters(n, offsets, indices):
    """Connected components of particles linked by the CSR neighbour lists (root per particle)."""
    parent = np.arange(n)
    for i in range(n):
        for k in range(offsets[i], offsets[i + 1]):
            a = _find(parent, i)
            b = _find(parent, indices[k])
            if a != b:
                parent[max(a, b)] = min(a, b)
    for i in range(n):
        parent[i] = _find(parent, i)
    return parent


def _particle_components(points, labels, enclosed, particles, link):
    """Component + 1 of every particle (0: none). A vertex votes for its nearest particle; a
    particle takes the component of its nearest voting vertex on a solid component (positive
    volume); the others (inside the liquid, away from the surface) take the component most
    voted for among the particles linked to them by chains of neighbours closer than
    ``link``."""
    n = particles.shape[0]
    out = np.zeros(n, np.int64)
    used = labels >= 0
    solid = np.flatnonzero(enclosed > 0.0)
    if n == 0 or not solid.size:
        return out
    if solid.size == 1:
        return out + solid[0] + 1
    dist, nearest = cKDTree(particles).query(points[used], workers=-1)
    comp = _votes(nearest.astype(np.int64), dist, labels[used], enclosed > 0.0, n)
    voted = comp >= 0
    if not voted.all():
        offsets, indices = NeighborSearch(link, "auto").build(particles).query(half=True)
        root = _clusters(n, offsets, indices.astype(np.int64))
        # per cluster, the component with the most voters (ties: the lowest component)
        key = root[voted] * (labels.max() + 2) + comp[voted]
        uniq, counts = np.unique(key, return_counts=True)
        cl, cp = uniq // (labels.max() + 2), uniq % (labels.max() + 2)
        order = np.lexsort((-counts, cl))
        first = np.r_[True, cl[order][1:] != cl[order][:-1]]
        best = np.full(n, -1, np.int64)
        best[cl[order][first]] = cp[order][first]
        comp = np.where(voted, comp, best[root])
    return comp + 1


@njit(cache=True)
def _normals_and_areas(p, tris, normals, areas):
    """Area-weighted vertex normals (unit) and a third of the adjacent triangles' areas."""
    normals[:] = 0.0
    areas[:] = 0.0
    for f in range(tris.shape[0]):
        i = tris[f, 0]
        j = tris[f, 1]
        k = tris[f, 2]
        e0 = p[j, 0] - p[i, 0]
        e1 = p[j, 1] - p[i, 1]
        e2 = p[j, 2] - p[i, 2]
        g0 = p[k, 0] - p[i, 0]
        g1 = p[k, 1] - p[i, 1]
        g2 = p[k, 2] - p[i, 2]
        n0 = e1 * g2 - e2 * g1
        n1 = e2 * g0 - e0 * g2
        n2 = e0 * g1 - e1 * g0
        a = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2) / 6.0
        for v in (i, j, k):
            normals[v, 0] += n0
            normals[v, 1] += n1
            normals[v, 2] += n2
            areas[v] += a
    for v in range(p.shape[0]):
        m = math.sqrt(normals[v, 0] ** 2 + normals[v, 1] ** 2 + normals[v, 2] ** 2)
        if m > 0.0:
            normals[v, 0] /= m
            normals[v, 1] /= m
            normals[v, 2] /= m


@njit(cache=True)
def _volumes(p, tris, labels, k):
    """Enclosed volume of every component (divergence theorem)."""
    out = np.zeros(k)
    for f in range(tris.shape[0]):
        a = tris[f, 0]
        b = tris[f, 1]
        c = tris[f, 2]
        out[labels[a]] += (p[a, 0] * (p[b, 1] * p[c, 2] - p[b, 2] * p[c, 1])
                           + p[a, 1] * (p[b, 2] * p[c, 0] - p[b, 0] * p[c, 2])
                           + p[a, 2] * (p[b, 0] * p[c, 1] - p[b, 1] * p[c, 0])) / 6.0
    return out


@njit(cache=True)
def _box_walls(points, normals, lo, hi, reach, band, facing, tol):
    """For an axis-aligned box: the points within ``reach`` of its boundary (or outside it);
    for each, its position put on every face within ``band`` of it that its normal faces
    (``n . g > facing``, ``g`` the face's outward normal) or within ``tol`` of it whatever its
    normal (a cut face's vertices), and its normal with the components along those faces'
    normals removed (it slides along them: along a face, or along the edge where two meet).
    Returns (indices, positions, directions)."""
    n = points.shape[0]
    keep = np.empty(n, np.int64)
    base = np.empty((n, 3))
    direction = np.empty((n, 3))
    m = 0
    for i in range(n):
        best = -np.inf
        for a in range(3):
            best = max(best, lo[a] - points[i, a], points[i, a] - hi[a])
        if not best > -reach:
            continue
        keep[m] = i
        for a in range(3):
            base[m, a] = points[i, a]
            direction[m, a] = normals[i, a]
        for a in range(3):
            dlo = lo[a] - points[i, a]
            dhi = points[i, a] - hi[a]
            if (dlo > -band and -normals[i, a] > facing) or abs(dlo) <= tol:
                base[m, a] = lo[a]
                direction[m, a] = 0.0
            elif (dhi > -band and normals[i, a] > facing) or abs(dhi) <= tol:
                base[m, a] = hi[a]
                direction[m, a] = 0.0
        m += 1
    return keep[:m].copy(), base[:m].copy(), direction[:m].copy()


def _gradient(shape, points, eps):
    """Unit gradient of a shape's distance at ``points`` (central differences)."""
    g = np.empty_like(points)
    for a in range(3):
        d = np.zeros(3)
        d[a] = eps
        g[:, a] = shape.evaluate(points + d) - shape.evaluate(points - d)
    norm = np.linalg.norm(g, axis=1)
    return g / np.where(norm > 0.0, norm, 1.0)[:, None]


def _check(points, triangles, particles, volumes, shape, wall_band, max_offset, max_shrink,
           iterations, tolerance):
    points = check_points("points", points)
    try:
        tris = np.ascontiguousarray(triangles, dtype=np.int64).reshape(-1, 3)
    except (TypeError, ValueError):
        raise TypeError("triangles must be a (T, 3) array of vertex indices") from None
    if tris.size and (tris.min() < 0 or tris.max() >= points.shape[0]):
        raise ValueError(f"triangles must index vertices 0..{points.shape[0] - 1}")
    particles = check_points("particles", particles)
    n = particles.shape[0]
    try:
        volumes = np.ascontiguousarray(np.broadcast_to(volumes, (n,)), dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"volumes must be a number or have shape ({n},)") from None
    if n and not (np.isfinite(volumes).all() and volumes.min() > 0.0):
        raise ValueError("volumes must be finite and > 0 (m^3)")
    if shape is not None and not isinstance(shape, Shape):
        raise TypeError(f"shape must be a filters.geometry.Shape or None, got "
                        f"{type(shape).__name__}")
    wall_band = check_range("wall_band", wall_band, 0.0, math.inf)
    max_offset = check_range("max_offset", max_offset, 0.0, math.inf)
    max_shrink = max_offset if max_shrink is None else check_range("max_shrink", max_shrink,
                                                                   0.0, math.inf)
    iterations = check_int("iterations", iterations, 1, 100)
    tolerance = check_range("tolerance", tolerance, 0.0, 1.0)
    return (points, tris, particles, volumes, wall_band, max_offset, max_shrink, iterations,
            tolerance)


def correct_volume(points: np.ndarray, triangles: np.ndarray, particles: np.ndarray,
                   volumes: ArrayLike, *, shape: Shape | None = None, wall_band: float = 0.0,
                   max_offset: float = math.inf, max_shrink: float | None = None,
                   link: float | None = None, iterations: int = 10,
                   tolerance: float = 1e-9) -> tuple[NDArray[np.float64], CorrectionInfo]:
    """Offset every connected component of a closed surface so it encloses its particles' volume.

    Parameters
    ----------
    points : (P, 3) float
        Vertices (m) of a closed, consistently oriented triangle mesh (outward normals).
    triangles : (T, 3) int
        Vertex indices.
    particles : (N, 3) float64
        Particle positions (m).
    volumes : float or (N,) float64
        The particles' volumes (m^3), > 0 (for a liquid of spacing ``s``: ``s^3``).
    shape : filters.geometry.Shape, optional
        The region the liquid is confined to (negative inside, e.g. the tank's inner box):
        vertices within ``wall_band`` of its boundary move only tangentially to it, and moved
        vertices end inside it.
    wall_band : float
        Distance (m) from the shape's boundary within which vertices count as on it, >= 0.
    max_offset : float
        Largest outward offset (m) of a component, >= 0.
    max_shrink : float, optional
        Largest inward offset (m), >= 0; default ``max_offset``.
    link : float, optional
        Particles closer than this (m) belong to the same piece unless the surface says
        otherwise (those inside the liquid, far from any vertex); default 1.5 times the cube
        root of the largest particle volume (1.5 spacings), > 0.
    iterations : int
        Most Newton steps, in [1, 100].
    tolerance : float
        Newton stops once every component's volume is within this fraction of its target,
        in [0, 1].

    Returns
    -------
    points : (P, 3) float64
        The corrected vertices.
    info : CorrectionInfo
        Offsets, volumes before and after, targets and vertex labels per component.

    Raises
    ------
    ValueError, TypeError
        For bad inputs, naming the argument.
    """
    (points, tris, particles, volumes, wall_band, max_offset, max_shrink, iterations,
     tolerance) = _check(points, triangles, particles, volumes, shape, wall_band, max_offset,
                         max_shrink, iterations, tolerance)
    if link is None:
        link = 1.5 * float(volumes.max()) ** (1.0 / 3.0) if volumes.size else 1.0
    link = check_range("link", link, 0.0, math.inf, low_inclusive=False)
    labels, k = _labels(tris, points.shape[0])
    zeros = np.zeros(k)
    if k == 0:
        return points.copy(), CorrectionInfo(zeros, zeros, zeros, zeros, labels)
    normals = np.empty_like(points)
    areas = np.empty(points.shape[0])
    # the flat faces on a box's walls (a surface cut at them) do not tilt the normals of the
    # vertices along their edges: those slide along the walls with the surface next to them
    faces = (wall_constraints(points, tris, shape.lower, shape.upper)[1]
             if isinstance(shape, Box) else np.zeros(tris.shape[0], bool))
    _normals_and_areas(points, np.ascontiguousarray(tris[~faces]), normals, areas)
    before = _volumes(points, tris, labels, k)
    target = np.bincount(_particle_components(points, labels, before, particles, link),
                         weights=volumes, minlength=k + 1)[1:]
    direction = normals
    near = None
    base = points
    current = before.copy()
    if shape is not None:
        # vertices on the walls (within wall_band, facing them) are put on them and slide along
        # them; only those that could reach a wall need a shape test afterwards
        reach = wall_band + min(max(max_offset, max_shrink), 1e300)
        if isinstance(shape, Box):
            lo = np.asarray(shape.lower, float)
            hi = np.asarray(shape.upper, float)
            near, on_wall, slide = _box_walls(points, normals, lo, hi, reach, wall_band, FACING,
                                              WALL_TOLERANCE * float(np.max(hi - lo)))
        else:
            s0 = shape.evaluate(points)
            near = np.flatnonzero(s0 > -reach)
            dist = s0[near]
            g = np.zeros((near.size, 3))
            wall = dist > -wall_band
            g[wall] = _gradient(shape, points[near[wall]], max(wall_band, 1e-12) * 1e-3)
            d = normals[near]
            facing = np.sum(d * g, axis=1)
            snap = facing > FACING
            on_wall = points[near] - np.where(snap, dist, 0.0)[:, None] * g
            slide = d - np.where(snap, facing, 0.0)[:, None] * g
        direction = normals.copy()
        direction[near] = slide
        if not np.array_equal(on_wall, points[near]):
            base = points.copy()
            base[near] = on_wall
            current = _volumes(base, tris, labels, k)
    active = (target > 0.0) & (before > 0.0)
    lab = np.maximum(labels, 0)
    used = labels >= 0
    offsets = np.zeros(k)
    slope = np.bincount(lab[used], weights=(areas * np.sum(direction * normals, 1))[used],
                        minlength=k)
    moved = base
    for _ in range(iterations):
        if not np.any(active & (np.abs(target - current) > tolerance * target)
                      & (offsets < max_offset) & (offsets > -max_shrink)):
            break
        ok = active & (slope > 0.0)
        step = np.where(ok, (target - current) / np.where(ok, slope, 1.0), 0.0)
        new = np.clip(offsets + step, -max_shrink, max_offset)
        moved = base + (new[lab] * used)[:, None] * direction
        if near is not None and near.size:
            if isinstance(shape, Box):
                moved[near] = np.clip(moved[near], shape.lower, shape.upper)
            else:
                moved[near] = _project_inside(shape, moved[near], wall_band)
        volume = _volumes(moved, tris, labels, k)
        change = new - offsets
        moving = np.abs(change) > 0.0
        measured = np.where(moving, (volume - current) / np.where(moving, change, 1.0), slope)
        slope = np.where(measured > 0.0, measured, slope)
        offsets, current = new, volume
    return moved, CorrectionInfo(offsets, before, current, target, labels)


def _project_inside(shape, points, scale):
    """Points outside ``shape`` moved back onto its boundary along its gradient."""
    s = shape.evaluate(points)
    out = s > 0.0
    if not out.any():
        return points
    result = points.copy()
    g = _gradient(shape, points[out], max(scale, 1e-12) * 1e-3)
    result[out] -= s[out][:, None] * g
    return result
