"""filters.surface.splat / sparse_grid / implicit / surface_mesh on arrays (no VTK)."""

import math

import numba
import numpy as np
import pytest

from filters.geometry import Plane, Sphere
from filters.kernels import SPLAT_KERNELS as KERNELS
from filters.kernels import lone_particle_radius
from filters.surface.attributes import interpolate_attributes
from filters.surface.csg import combine_dense, combine_sparse
from filters.surface.grid import GridTooLargeError
from filters.surface.mesh import merge_coincident, mesh_stats
from filters.surface.splat import splat_dense, splat_sparse


def _cloud(n=600, seed=1):
    rng = np.random.default_rng(seed)
    return rng.normal(0.0, 0.05, (n, 3)) + np.array([0.3, -0.2, 1.0])


def test_kernel_values_at_known_points():
    # Wyvill's soft-object polynomial is 1/2 at q = 1/2; SPH spline W(r)/W(0) = 0.6 at q ~ 0.311
    assert lone_particle_radius("metaball", 1.0, support_r=1.0, iso=0.5) == pytest.approx(0.5)
    q = lone_particle_radius("sph", 1.0, support_r=1.0, iso=0.6)
    assert 1 - 6 * q**2 + 6 * q**3 == pytest.approx(0.6, abs=1e-12)
    a = 4.0
    q = lone_particle_radius("blobby", 1.0, support_r=1.0, iso=0.5, blobbiness=a)
    assert (math.exp(-a * q * q) - math.exp(-a)) / (1 - math.exp(-a)) == pytest.approx(0.5)
    assert lone_particle_radius("zhu_bridson", 0.3) == 0.3


@pytest.mark.parametrize("kernel", KERNELS)
def test_lone_particle_field_matches_kernel(kernel):
    # voxels inside the predicted sphere are inside, those outside are outside
    centre = np.array([[0.0123, -0.0071, 0.0049]])
    cell = 0.001
    grid = splat_sparse(centre, 0.01, cell, kernel=kernel)
    dense = grid.to_dense()
    nz, ny, nx = dense.values.shape
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    idx = np.stack([i, j, k], -1).reshape(-1, 3) + dense.index_origin
    dist = np.linalg.norm(idx * cell - centre, axis=1)
    radius = lone_particle_radius(kernel, 0.01)
    inside = dense.values.reshape(-1) < 0
    assert inside.any()
    assert dist[inside].max() <= radius + 1e-9
    assert dist[~inside].min() >= radius - 1e-6
    # inside voxel count ~ sphere volume
    assert inside.sum() * cell**3 == pytest.approx(4 / 3 * math.pi * radius**3, rel=0.05)


@pytest.mark.parametrize("kernel", ["sph", "metaball", "zhu_bridson"])
def test_bitwise_identical_for_any_thread_count(kernel):
    x = _cloud()
    radii = np.random.default_rng(4).uniform(0.008, 0.012, len(x))  # per-particle radius
    saved = numba.get_num_threads()
    try:
        grids = []
        for threads in (1, 2):
            numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
            grids.append(splat_sparse(x, radii, 0.004, kernel=kernel))
    finally:
        numba.set_num_threads(saved)
    a, b = grids
    assert a.keys.size > 0
    np.testing.assert_array_equal(a.keys, b.keys)
    np.testing.assert_array_equal(a.inside_keys, b.inside_keys)
    assert a.data.tobytes() == b.data.tobytes()


def test_sparse_grid_matches_dense_values_where_evaluated():
    x = _cloud()
    grid = splat_sparse(x, 0.01, 0.004)
    dense = splat_dense(x, 0.01, 0.004)
    from_sparse = grid.to_dense(dense.index_origin, dense.index_origin
                                + np.array(dense.dimensions))
    # same sign everywhere, same value on every evaluated voxel
    assert np.array_equal(from_sparse.values < 0, dense.values < 0)
    coords = grid.block_coords * grid.block_size - dense.index_origin
    for m in range(0, grid.keys.size, 7):
        x0, y0, z0 = coords[m]
        b = grid.block_size
        ref = dense.values[z0:z0 + b, y0:y0 + b, x0:x0 + b]
        np.testing.assert_array_equal(grid.data[m], ref)


def test_sparse_grid_skips_interior_and_empty_space():
    s = 0.02
    g = np.stack(np.meshgrid(*[np.arange(24)] * 3, indexing="ij"), -1).reshape(-1, 3) * s
    far = g + 10.0  # a second lump 10 m away: the box between them is never allocated
    grid = splat_sparse(np.concatenate([g, far]), 0.01, 0.005)
    assert grid.inside_keys.size > 0
    dense_bytes = 4 * (10.5 / 0.005) ** 3
    assert grid.nbytes < dense_bytes / 1000
    with pytest.raises(GridTooLargeError, match="max_bytes"):
        splat_dense(np.concatenate([g, far]), 0.01, 0.005, max_bytes=2**30)


def test_memory_guard_refuses_large_grid():
    x = _cloud()
    with pytest.raises(GridTooLargeError, match="max_bytes"):
        splat_sparse(x, 0.01, 0.0005, max_bytes=10_000_000)
    assert issubclass(GridTooLargeError, ValueError)


def test_empty_input_gives_empty_grid():
    grid = splat_sparse(np.zeros((0, 3)), 0.01, 0.005)
    assert grid.empty and grid.data.shape[0] == 0
    assert splat_dense(np.zeros((0, 3)), 0.01, 0.005).values.size >= 0


@pytest.mark.parametrize("bad, kwargs, exc", [
    (np.array([[0.0, np.nan, 0.0]]), {}, ValueError),
    (np.array([[0.0, np.inf, 0.0]]), {}, ValueError),
    (np.zeros((2, 2)), {}, ValueError),
    (np.zeros((2, 3)), {"kernel": "gauss"}, ValueError),
    (np.zeros((2, 3)), {"radius": -1.0}, ValueError),
    (np.zeros((2, 3)), {"radius": np.array([0.01, 0.0])}, ValueError),
    (np.zeros((2, 3)), {"cell_size": 0.0}, ValueError),
    (np.zeros((2, 3)), {"iso": -0.5}, ValueError),
])
def test_invalid_inputs_raise(bad, kwargs, exc):
    args = {"radius": 0.01, "cell_size": 0.005}
    args.update(kwargs)
    with pytest.raises(exc):
        splat_sparse(bad, args.pop("radius"), args.pop("cell_size"), **args)


def test_interpolate_attributes_reproduces_constants():
    x = _cloud(200)
    v = np.tile([1.0, -2.0, 0.5], (len(x), 1))
    pts = x[:50] + 0.003
    out = interpolate_attributes(pts, x, 0.01, v, cell_size=0.005)
    np.testing.assert_allclose(out, v[:50], rtol=1e-12)
    # beyond every support: the nearest particle's value
    two = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]])
    out = interpolate_attributes(np.array([[0.0, 0.0, 0.045]]), two, 0.01, np.array([1.0, 2.0]),
                                 cell_size=0.005)
    assert out[0] == 1.0


def test_csg_with_field_sparse_equals_dense():
    x = _cloud()
    cut = Plane((0.3, -0.2, 1.0), (0, 0, 1))  # keep the lower half of the liquid
    dense = combine_dense(splat_dense(x, 0.01, 0.004), cut, "intersection")
    sparse = combine_sparse(splat_sparse(x, 0.01, 0.004), cut, "intersection")
    full = splat_dense(x, 0.01, 0.004)
    inside_cut = (dense.values < 0).sum()
    assert 0.3 * (full.values < 0).sum() < inside_cut < 0.7 * (full.values < 0).sum()
    back = sparse.to_dense(dense.index_origin, dense.index_origin + np.array(dense.dimensions))
    assert np.array_equal(back.values < 0, dense.values < 0)
    blob = Sphere((0.3, -0.2, 1.3), 0.05)  # union with a solid ball outside the liquid
    sparse_u = combine_sparse(splat_sparse(x, 0.01, 0.004), blob, "union")
    lo = np.floor(np.array([0.1, -0.4, 0.8]) / 0.004).astype(int)
    hi = np.ceil(np.array([0.5, 0.0, 1.4]) / 0.004).astype(int)
    u = sparse_u.to_dense(lo, hi)
    assert (u.values < 0).sum() * 0.004**3 > 4 / 3 * math.pi * 0.05**3 * 0.9


def test_merge_and_mesh_stats_on_a_cube():
    # a unit cube as 12 triangles, given with every corner duplicated per face
    corners = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], np.float32)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    pts, tris = [], []
    for q in quads:
        base = len(pts)
        pts.extend(corners[list(q)])
        tris += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    p, t = merge_coincident(np.array(pts), np.array(tris))
    assert p.shape[0] == 8
    st = mesh_stats(p, t)
    assert st.closed and st.manifold and st.euler == 2 and st.components == 1
    assert st.area == pytest.approx(6.0) and abs(st.volume) == pytest.approx(1.0)
    open_stats = mesh_stats(p, t[:-1])
    assert not open_stats.closed and not open_stats.manifold


# --- far-apart points and the memory message (issue 16, item 7) -----------------------------
def _dyadic_cluster():
    """A jittered 4^3 cluster on dyadic coordinates (translations by powers of 2 are exact)."""
    rng = np.random.default_rng(3)
    g = np.stack(np.meshgrid(*[np.arange(4)] * 3, indexing="ij"), -1).reshape(-1, 3)
    return (g + np.round(rng.uniform(-8, 8, g.shape)) / 64) * 2.0**-6  # spacing 1/64 m


def _blocks_by_cluster(grid, split):
    """(coords, data) of the evaluated blocks below / above ``split`` blocks along x, sorted."""
    coords = grid.block_coords
    out = []
    for mask in (coords[:, 0] < split, coords[:, 0] >= split):
        c, d = coords[mask], grid.data[mask]
        order = np.lexsort(c.T[::-1])
        out.append((c[order], d[order]))
    return out


def test_far_apart_clusters_are_both_splatted():
    # Before: splat_sparse([[0,0,0],[1e5,0,0]], 0.01, 0.005) splatted one particle (block
    # coordinates wrapped past 2^20). Inside the key range two clusters 32 km apart are splatted
    # in full (the same field, bit for bit, as the cluster alone, translated); only their own
    # blocks are stored.
    cell = 2.0**-7
    a = _dyadic_cluster()
    shift = 2.0**15  # 32768 m = 2^19 blocks of 8 voxels
    both = splat_sparse(np.concatenate([a, a + [shift, 0.0, 0.0]]), 0.01, cell)
    alone = splat_sparse(a, 0.01, cell)
    near, far = _blocks_by_cluster(both, 2**18)
    ref = _blocks_by_cluster(alone, 2**18)[0]
    assert near[0].shape[0] == ref[0].shape[0] > 0
    np.testing.assert_array_equal(near[0], ref[0])
    np.testing.assert_array_equal(far[0], ref[0] + [2**19, 0, 0])
    np.testing.assert_array_equal(near[1], ref[1])
    np.testing.assert_array_equal(far[1], ref[1])
    assert near[1].min() < 0 and far[1].min() < 0  # each cluster's inside (peak of the field)
    assert both.keys.size == 2 * alone.keys.size
    # negative coordinates and the values at surface vertices, far away too
    both = splat_sparse(np.concatenate([a, a - [0.0, 0.0, shift]]), 0.01, cell)
    assert (both.block_coords[:, 2] < -2**18).sum() == alone.keys.size
    v = interpolate_attributes(np.concatenate([a, a + [shift, 0, 0], [[1e300, 0, 0]]]),
                               np.concatenate([a, a + [shift, 0, 0]]), 0.01,
                               np.r_[np.ones(len(a)), 2 * np.ones(len(a))], cell_size=cell)
    np.testing.assert_allclose(v, np.r_[np.ones(len(a)), 2 * np.ones(len(a)), 0.0])


@pytest.mark.timeout(60)
@pytest.mark.parametrize("spread", [1e5, 1e12, 1e20, 1e300])
@pytest.mark.parametrize("splat", [splat_sparse, splat_dense])
def test_points_beyond_the_block_keys_are_refused_up_front(splat, spread):
    # 1e5 m at 0.04 m blocks is 2.5 million blocks: more than the 2^21 that 21-bit block
    # coordinates hold, whatever the origin
    with pytest.raises(ValueError, match=r"positions lie between 0 and .* along x: .* blocks "
                                         r".*more than the .* block index holds.*split the cloud"):
        splat([[0, 0, 0], [spread, 0, 0]], 0.01, 0.005)
    with pytest.raises(ValueError, match="positions .* along y"):
        splat([[0, 0, 0], [0, -spread, 0]], 0.01, 0.005)
    # a small cloud far from the origin: fits if translated, and the message says so
    with pytest.raises(ValueError, match=r"along z.*translate the points nearer the origin"):
        splat(_cloud(20) + [0, 0, 5e4], 0.01, 0.005)
    with pytest.raises(ValueError, match="positions"):
        interpolate_attributes(np.zeros((1, 3)), [[0, 0, 0], [spread, 0, 0]], 0.01, [1.0, 2.0],
                               cell_size=0.005)


def test_budget_message_gives_sizes_in_sensible_units():
    from filters.surface.grid import check_budget, format_bytes

    # Before: "needs 0.0 MiB, above max_bytes = 0.0 MiB"
    with pytest.raises(GridTooLargeError) as info:
        splat_sparse(_cloud(10), 0.01, 0.005, max_bytes=100)
    msg = str(info.value)
    assert "0.0 MiB" not in msg and "needs 960 bytes, above max_bytes = 100 bytes" in msg
    assert [format_bytes(n) for n in (0, 1, 1023, 1536, 3 * 2**20 + 2**19, 2**32)] == [
        "0 bytes", "1 byte", "1023 bytes", "1.5 KiB", "3.5 MiB", "4 GiB"]
    with pytest.raises(GridTooLargeError, match=r"needs 4 GiB \(4,294,967,297 bytes\), above "
                                                r"max_bytes = 4 GiB \(4,294,967,296 bytes\)"):
        check_budget(2**32 + 1, 2**32, "a grid")
    with pytest.raises(GridTooLargeError, match=r"needs [1-9][0-9.]* (KiB|MiB|GiB)"):
        splat_sparse(_cloud(), 0.01, 0.0005, max_bytes=10_000)


@pytest.mark.parametrize("kernel", ["sph", "zhu_bridson"])
def test_may_cross_keeps_every_brick_with_a_sign_change(kernel):
    """The bricks SparseGrid.may_cross drops hold no sign change once filled; those it keeps
    include every brick that does (drops, a slab and a CSG cut: inside, outside and evaluated
    blocks side by side)."""
    rng = np.random.default_rng(3)
    balls = [c + rng.normal(0, 0.01, (150, 3)) for c in ([0, 0, 0], [0.08, 0.02, 0.0])]
    slab = np.stack(np.meshgrid(np.arange(40), np.arange(40), np.arange(12), indexing="ij"),
                    -1).reshape(-1, 3) * 0.008 + [0.0, 0.0, -0.2]
    x = np.concatenate(balls + [slab])
    grid = splat_sparse(x, 0.004, 0.002, kernel=kernel)
    grids = [grid]
    if kernel == "sph":
        grids.append(combine_sparse(grid, Plane((0.0, 0.0, -0.15), (0.0, 0.0, 1.0)),
                                    "intersection"))
    for g in grids:
        dropped = 0
        for group in (1, 2, 4):
            bricks = g.bricks(group)
            keep = g.may_cross(bricks, group)
            _, crossing = g.fill_bricks(bricks, group, crossing=True)
            assert crossing.any() and not crossing[~keep].any()
            dropped += int((~keep).sum())
        assert dropped  # it does drop bricks (else it tests nothing)


def test_dilated_blocks_are_the_same_from_the_bitmap_and_the_hash_set():
    """dilate_keys marks a dense bitmap where the blocks fill their box and a hash set where
    they are far apart: the same sorted keys as the hash set, every block within reach."""
    from filters.surface.grid import _dilate, dilate_keys, pack_keys, unpack_keys

    rng = np.random.default_rng(7)
    dense = pack_keys(np.unique(rng.integers(-6, 6, (300, 3)), axis=0))
    far = pack_keys(np.array([[0, 0, 0], [90000, 5, -90000], [3, 4, 5]]))
    for keys in (dense, far):
        for reach in (0, 1, 2):
            got = dilate_keys(keys, reach)
            assert np.array_equal(got, np.sort(_dilate(keys, reach)))
            coords = unpack_keys(keys)
            # brute force: every block within Chebyshev distance `reach` of a block, once
            steps = np.stack(np.meshgrid(*[np.arange(-reach, reach + 1)] * 3, indexing="ij"),
                             -1).reshape(-1, 3)
            want = np.unique(pack_keys((coords[:, None, :] + steps).reshape(-1, 3)))
            assert np.array_equal(got, want)
