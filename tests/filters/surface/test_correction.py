"""filters.surface.correction (volume correction), filters.surface.walls (ghost particles) and
filters.surface.clip (cutting a closed mesh at the walls of a box)."""

import numpy as np
import pytest

from filters.geometry import Box
from filters.surface.clip import cap_loops, clip_half_space, refill_runs, wall_constraints
from filters.surface.correction import correct_volume, vertex_components
from filters.surface.csg import combine_sparse
from filters.surface.mesh import mesh_stats
from filters.surface.splat import splat_sparse, splat_sparse_anisotropic
from filters.surface.walls import check_walls, mirror_ghosts, mirror_matrices
from pipeline.surface.contour import contour_sparse

S = 0.02
R = 0.01


def _icosphere(radius, centre=(0.0, 0.0, 0.0), subdivisions=4):
    """A closed, outward-oriented triangulated sphere."""
    t = (1.0 + 5 ** 0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]],
                 float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9],
                  [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2],
                  [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
                  [8, 6, 7], [9, 8, 1]])
    for _ in range(subdivisions):
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        uniq, inv = np.unique(edges, axis=0, return_inverse=True)
        mid = len(v) + inv.reshape(3, -1).T
        v = np.vstack([v, 0.5 * (v[uniq[:, 0]] + v[uniq[:, 1]])])
        a, b, c = f.T
        ab, bc, ca = mid.T
        f = np.concatenate([np.stack([a, ab, ca], 1), np.stack([b, bc, ab], 1),
                            np.stack([c, ca, bc], 1), np.stack([ab, bc, ca], 1)])
    v = v / np.linalg.norm(v, axis=1)[:, None]
    return v * radius + np.asarray(centre), f


def test_a_sphere_grows_to_its_particles_volume():
    pts, tris = _icosphere(1.0)
    v0 = mesh_stats(pts, tris).volume
    particles = np.random.default_rng(0).uniform(-0.5, 0.5, (100, 3))
    moved, info = correct_volume(pts, tris, particles, 1.3 * v0 / 100)
    st = mesh_stats(moved, tris)
    assert st.closed and st.manifold
    assert abs(st.volume / (1.3 * v0) - 1) < 1e-9
    one, _ = correct_volume(pts, tris, particles, 1.3 * v0 / 100, iterations=1)
    assert 1e-4 < abs(mesh_stats(one, tris).volume / (1.3 * v0) - 1) < 0.05  # one step: close
    # a uniform offset along the normals: the sphere stays a sphere of the grown radius (up to
    # the directions of the vertex normals, ~1e-7 off the radii)
    r = np.linalg.norm(moved, axis=1)
    assert np.ptp(r) < 1e-5
    assert abs(info.offsets[0] - (r[0] - 1.0)) < 1e-9
    assert info.offsets[0] == pytest.approx(1.3 ** (1 / 3) - 1, rel=0.01)


def test_each_piece_gets_the_volume_of_its_own_particles():
    a, ta = _icosphere(1.0)
    b, tb = _icosphere(0.5, centre=(5.0, 0.0, 0.0))
    pts = np.vstack([a, b])
    tris = np.vstack([ta, tb + len(a)])
    labels, k = vertex_components(tris, len(pts))
    assert k == 2 and set(labels[:len(a)]) == {0} and set(labels[len(a):]) == {1}
    rng = np.random.default_rng(1)
    # particles of the big piece deep inside it and near its surface, and of the small one
    pa = rng.normal(size=(400, 3))
    pa *= (rng.uniform(0, 0.95, 400) / np.linalg.norm(pa, axis=1))[:, None]
    pb = np.array([5.0, 0.0, 0.0]) + rng.uniform(-0.2, 0.2, (10, 3))
    vol_a, vol_b = 4.0, 0.4
    moved, info = correct_volume(pts, tris, np.vstack([pa, pb]),
                                 np.r_[np.full(400, vol_a / 400), np.full(10, vol_b / 10)])
    assert info.target == pytest.approx([vol_a, vol_b])
    assert mesh_stats(moved[:len(a)], ta).volume == pytest.approx(vol_a, rel=1e-6)
    assert mesh_stats(moved[len(a):], tb).volume == pytest.approx(vol_b, rel=1e-6)


def test_a_cavity_is_left_alone_and_max_offset_holds():
    outer, to = _icosphere(2.0)
    inner, ti = _icosphere(0.5)
    pts = np.vstack([outer, inner])
    tris = np.vstack([to, ti[:, ::-1] + len(outer)])  # inward-facing: a bubble
    particles = np.random.default_rng(2).uniform(0.8, 1.2, (50, 3))
    moved, info = correct_volume(pts, tris, particles, 1.0, max_offset=0.1)
    assert info.before[1] < 0 and info.offsets[1] == 0
    assert np.array_equal(moved[len(outer):], inner)
    assert info.offsets[0] == pytest.approx(0.1)  # 50 m^3 would need more than 0.1 m


def test_walls_keep_the_flat_faces_on_the_walls():
    # a half ball resting on the floor of a tank, the floor closing it
    x = np.array([g for g in np.ndindex(13, 13, 7)], float) * S - np.array([6, 6, 0]) * S
    x = x[np.linalg.norm(x, axis=1) < 6 * S] + np.array([0.3, 0.3, 0.5 * S])
    tank = Box((0.0, 0.0, 0.0), (0.6, 0.6, 0.5))
    grid = splat_sparse(x, R, 0.25 * S, walls=tank)
    pts, tris = contour_sparse(combine_sparse(grid, tank))
    target = len(x) * S ** 3
    moved, info = correct_volume(pts, tris, x, S ** 3, shape=tank, wall_band=0.125 * S)
    st = mesh_stats(moved, tris)
    assert st.closed and abs(st.volume / target - 1) < 1e-3
    floor = pts[:, 2] < 1e-9
    assert floor.sum() > 100
    assert np.array_equal(moved[floor, 2], pts[floor, 2])  # the floor face stays on the floor
    assert (moved[:, 2] >= 0.0).all()


def test_correct_volume_rejects_bad_input():
    pts, tris = _icosphere(1.0, subdivisions=1)
    x = np.zeros((3, 3))
    with pytest.raises(ValueError, match="triangles must index"):
        correct_volume(pts, tris + len(pts), x, 1.0)
    with pytest.raises(ValueError, match="volumes must be finite and > 0"):
        correct_volume(pts, tris, x, -1.0)
    with pytest.raises(ValueError, match="volumes must be a number or have shape"):
        correct_volume(pts, tris, x, np.ones(4))
    with pytest.raises(TypeError, match="shape must be a filters.geometry.Shape"):
        correct_volume(pts, tris, x, 1.0, shape="box")
    with pytest.raises(ValueError, match="iterations"):
        correct_volume(pts, tris, x, 1.0, iterations=0)
    with pytest.raises(ValueError, match="tolerance"):
        correct_volume(pts, tris, x, 1.0, tolerance=2.0)
    with pytest.raises(ValueError, match="link"):
        correct_volume(pts, tris, x, 1.0, link=0.0)
    with pytest.raises(ValueError, match="positions|particles"):
        correct_volume(pts, tris, np.full((2, 3), np.nan), 1.0)
    empty, info = correct_volume(np.zeros((0, 3)), np.zeros((0, 3), int), x, 1.0)
    assert empty.shape == (0, 3) and info.offsets.size == 0


def test_ghosts_mirror_particles_near_walls_edges_and_corners():
    lo, hi = np.zeros(3), np.ones(3)
    x = np.array([[0.5, 0.5, 0.5],     # far from every wall: no ghost
                  [0.05, 0.5, 0.5],    # one wall: one ghost
                  [0.05, 0.95, 0.5],   # an edge: three ghosts
                  [0.05, 0.05, 0.05],  # a corner: seven
                  [1.5, 0.5, 0.5]])    # outside the box: none
    g, src, signs, shifts = mirror_ghosts(x, lo, hi, 0.1)
    assert np.bincount(src, minlength=5).tolist() == [0, 1, 3, 7, 0]
    assert np.allclose(g, x[src] * signs + shifts)
    assert np.all(np.any((g < lo) | (g > hi), axis=1))  # every ghost is beyond a wall
    corner = g[src == 3]
    assert {tuple(np.round(c, 9)) for c in corner} == {
        (sx * 0.05, sy * 0.05, sz * 0.05) for sx in (-1, 1) for sy in (-1, 1)
        for sz in (-1, 1)} - {(0.05, 0.05, 0.05)}
    G = np.random.default_rng(0).normal(size=(len(g), 3, 3))
    G = G + G.transpose(0, 2, 1)
    M = mirror_matrices(G, signs)
    S_ = np.einsum("ij,jk->ijk", signs, np.eye(3))
    assert np.allclose(M, S_ @ G @ S_)
    with pytest.raises(ValueError, match="upper > lower"):
        check_walls(((0, 0, 0), (1, -1, 1)))
    with pytest.raises(TypeError, match="walls must be"):
        check_walls("tank")


@pytest.mark.parametrize("anisotropic", [False, True])
def test_ghosts_fill_the_tank_edges_and_corners(anisotropic):
    """A lattice pool half a spacing from the walls of its tank: with ghosts the surface
    clipped by the tank encloses the lattice's cells (no gap along the bottom edges and in the
    corners), without them it loses volume there."""
    n = (10, 10, 5)
    x = np.array(list(np.ndindex(*n)), float) * S + 0.5 * S
    tank = Box((0.0, 0.0, 0.0), (n[0] * S, n[1] * S, 0.3))
    splat = splat_sparse_anisotropic if anisotropic else splat_sparse
    target = len(x) * S ** 3
    with_ghosts = mesh_stats(*contour_sparse(combine_sparse(splat(x, R, 0.25 * S, walls=tank),
                                                            tank))).volume / target - 1
    without = mesh_stats(*contour_sparse(combine_sparse(splat(x, R, 0.25 * S), tank))).volume \
        / target - 1
    assert abs(with_ghosts) < 0.01
    assert without < with_ghosts - 0.01


def _cap_fan(points, edges, axis, lower, upper):
    """A test triangulation of a convex cap: a fan over its simplified loop, runs refilled."""
    loops, runs = cap_loops(points, edges, axis, lower, upper)
    assert len(loops) == 1
    loop = loops[0]
    fan = np.stack([np.full(loop.size - 2, loop[0]), loop[1:-1], loop[2:]], axis=1)
    return refill_runs(fan, runs)


def test_a_cap_loop_out_along_two_box_edges_and_back_is_kept_whole():
    """A cut loop that leaves a corner of the wall along one box edge, turns back, and does
    the same along the other edge (liquid pressed into a corner of a tank's ceiling, measured
    in a splash): reduced to its two corner vertices it left nothing to triangulate and the
    liquid surface stage raised "a cap triangle along a box edge is missing"; kept whole, its
    fan covers every edge."""
    corner = [1.0, 1.0, 1.0]
    points = np.array([corner, [1.0, 0.8, 1.0], [1.0, 0.6, 1.0], [1.0, 0.9, 1.0], corner,
                       [0.8, 1.0, 1.0], [0.6, 1.0, 1.0], [0.9, 1.0, 1.0]])
    edges = np.stack([np.arange(8), np.roll(np.arange(8), -1)], axis=1)
    loops, runs = cap_loops(points, edges, 2, np.zeros(3), np.ones(3))
    assert [list(loop) for loop in loops] == [list(range(8))] and not runs
    tris = _cap_fan(points, edges, 2, np.zeros(3), np.ones(3))
    directed = {(t[k], t[(k + 1) % 3]) for t in tris for k in range(3)}
    assert all((u, w) in directed for u, w in edges)


def test_a_sphere_cut_by_the_walls_of_a_box_stays_closed_and_flat_on_them():
    """A sphere cut by three walls of a box (the corner of a tank): the kept part closed by
    flat faces on the walls is a closed, consistently oriented mesh whose volume is the
    analytic volume of the ball's octant-like piece, and whose faces lie on the walls."""
    pts, tris = _icosphere(1.0, subdivisions=5)
    lower = np.array([-0.3, -0.2, 0.0])
    upper = np.array([2.0, 2.0, 2.0])
    data = pts[:, :1].copy()  # a point array: x, interpolated at the cuts
    for axis in range(3):
        for value, keep in ((lower[axis], 1), (upper[axis], -1)):
            pts, tris, data, cap = clip_half_space(pts, tris, axis, value, keep, data=data)
            if cap.size:
                tris = np.concatenate([tris, _cap_fan(pts, cap, axis, lower, upper)])
    used = np.unique(tris)
    st = mesh_stats(pts, tris)
    assert st.closed and st.manifold and st.euler == 2
    # Monte Carlo volume of the ball inside the box, against the mesh's
    rng = np.random.default_rng(0)
    q = rng.uniform(-1, 1, (400_000, 3))
    inside = (np.linalg.norm(q, axis=1) < 1) & np.all((q >= lower) & (q <= upper), axis=1)
    assert st.volume == pytest.approx(8.0 * inside.mean(), rel=0.01)
    assert np.allclose(data[used, 0], pts[used, 0])  # linear data interpolate exactly
    free, faces = wall_constraints(pts, tris, lower, upper)
    assert faces.sum() > 0 and (free[used] == 0).any()
    # the faces on the walls cover the discs' areas the walls cut out of the ball
    for axis, value in ((0, -0.3), (1, -0.2), (2, 0.0)):
        on = (np.abs(pts[tris][:, :, axis] - value) < 1e-12).all(axis=1)
        p = pts[tris[on]]
        area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
        assert area > 0.5


def test_clip_half_space_rejects_bad_arguments():
    pts, tris = _icosphere(1.0, subdivisions=1)
    with pytest.raises(ValueError, match="axis"):
        clip_half_space(pts, tris, 3, 0.0, 1)
    with pytest.raises(ValueError, match="keep"):
        clip_half_space(pts, tris, 0, 0.0, 0)
    with pytest.raises(ValueError, match="eps"):
        clip_half_space(pts, tris, 0, 0.0, 1, eps=-1.0)
    # a plane missing the mesh: everything kept, no cut
    p2, t2, _, cap = clip_half_space(pts, tris, 0, -5.0, 1)
    assert np.array_equal(t2, tris) and cap.size == 0


def _octahedron(centre):
    c = np.asarray(centre, float)
    pts = c + np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]],
                       float)
    tris = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                     [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]], np.int64)
    return pts, tris


def test_a_cut_through_a_point_where_two_pieces_touch_is_closed():
    """Two octahedra touching at one vertex that lies on a wall (as the liquid's surface can
    touch a tank wall at one point): the cut's boundary passes that vertex twice, two loops
    share it; both are capped and the result is closed with the exact half volumes."""
    from vtkmodules.util import numpy_support

    from pipeline.algorithm import run_chain
    from pipeline.surface.contour import mesh_to_polydata
    from pipeline.surface.liquid import ClipBox

    pa, ta = _octahedron((0.0, -1.0, 0.0))
    pb, tb = _octahedron((0.0, 1.0, 0.0))
    # the vertex (0, 0, 0) is pa[2] and pb[3]: make it one point
    pts = np.concatenate([pa, np.delete(pb, 3, axis=0)])
    remap = np.array([6, 7, 8, 2, 9, 10])  # pb's indices in pts
    tris = np.concatenate([ta, remap[tb]])
    edges = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [3, 4], [4, 0]])
    loops, runs = cap_loops(np.zeros((5, 3)), edges, 0, (-9.0, -9, -9), (9.0, 9, 9))
    assert sorted(len(loop) for loop in loops) == [3, 3] and not runs
    assert all(0 in loop for loop in loops)
    out = run_chain([ClipBox(Box((0.0, -5.0, -5.0), (5.0, 5.0, 5.0)))],
                    mesh_to_polydata(pts, tris))
    p = numpy_support.vtk_to_numpy(out.GetPoints().GetData()).astype(np.float64)
    t = numpy_support.vtk_to_numpy(out.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    st = mesh_stats(p, t)
    assert st.closed
    assert st.volume == pytest.approx(2 * (4.0 / 3.0) / 2, rel=1e-12)
