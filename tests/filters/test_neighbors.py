"""Tests of filters.neighbors: all backends return identical neighbour sets."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from filters.neighbors import NeighborSearch

BACKENDS = ["grid", "hash", "kdtree"]


def brute_force(q, p, r, self_query):
    d2 = ((q[:, None, :] - p[None, :, :]) ** 2)
    d2 = d2[..., 0] + d2[..., 1] + d2[..., 2]  # same evaluation order as the backends
    rows = []
    for i in range(q.shape[0]):
        js = np.nonzero(d2[i] <= r * r)[0]
        if self_query:
            js = js[js != i]
        rows.append(js)
    return rows


def as_rows(offsets, indices):
    return [indices[offsets[i]:offsets[i + 1]] for i in range(offsets.shape[0] - 1)]


def tricky_points(r):
    """Random points plus lattices exactly on cell boundaries and pairs exactly r apart."""
    rng = np.random.default_rng(7)
    pts = [rng.uniform(-0.3, 1.1, size=(600, 3))]
    g = np.arange(0, 6) * r  # multiples of the radius: on cell faces for any cells_per_radius
    pts.append(np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3))
    g2 = np.arange(0, 9) * (r / 2) + 0.1
    pts.append(np.stack(np.meshgrid(g2, g2, g2[:3], indexing="ij"), -1).reshape(-1, 3))
    base = rng.uniform(0, 1, size=(50, 3))
    pts.append(base + np.array([r, 0.0, 0.0]))
    pts.append(base)
    return np.ascontiguousarray(np.concatenate(pts))


@pytest.mark.parametrize("cells_per_radius", [1, 2, 3])
def test_backends_identical_including_cell_boundaries(cells_per_radius):
    r = 0.125  # exactly representable: lattice distances equal r exactly
    pts = tricky_points(r)
    ref = brute_force(pts, pts, r, True)
    exact_pairs = 0
    for backend in BACKENDS:
        ns = NeighborSearch(r, backend, cells_per_radius=cells_per_radius).build(pts)
        offsets, indices = ns.query(sort=True)
        rows = as_rows(offsets, indices)
        assert len(rows) == len(ref)
        for a, b in zip(rows, ref, strict=False):
            np.testing.assert_array_equal(a, b)
    d = np.linalg.norm(pts[ns.pairs()[:, 0]] - pts[ns.pairs()[:, 1]], axis=1)
    exact_pairs = int((d == r).sum())
    assert exact_pairs > 100  # the test really contains pairs exactly on the radius


def test_external_queries_identical_across_backends():
    r = 0.1
    pts = tricky_points(r)
    q = np.random.default_rng(3).uniform(-0.5, 1.5, size=(400, 3))
    q = np.concatenate([q, pts[::7] + np.array([0.0, 0.0, r])])  # queries exactly r above points
    ref = brute_force(q, pts, r, False)
    for backend in BACKENDS:
        offsets, indices = NeighborSearch(r, backend).build(pts).query(q, sort=True)
        for a, b in zip(as_rows(offsets, indices), ref, strict=False):
            np.testing.assert_array_equal(a, b)


def test_pairs_equal_ckdtree_query_pairs():
    rng = np.random.default_rng(11)
    pts = rng.uniform(0, 1, size=(3000, 3))
    r = 0.08
    expected = cKDTree(pts).query_pairs(r, output_type="ndarray")
    expected = expected[np.lexsort((expected[:, 1], expected[:, 0]))]
    for backend in BACKENDS:
        np.testing.assert_array_equal(NeighborSearch(r, backend).build(pts).pairs(), expected)


def test_unbounded_domain_uses_hash():
    rng = np.random.default_rng(5)
    pts = np.concatenate([rng.uniform(0, 1, (200, 3)), rng.uniform(0, 1, (200, 3)) + 1e5])
    with pytest.raises(ValueError, match="hash"):
        NeighborSearch(0.05, "grid", max_cells=10_000).build(pts)
    auto = NeighborSearch(0.05, "auto", max_cells=10_000).build(pts)
    assert auto.backend == "hash"
    o1, i1 = auto.query(sort=True)
    o2, i2 = NeighborSearch(0.05, "kdtree").build(pts).query(sort=True)
    np.testing.assert_array_equal(o1, o2)
    np.testing.assert_array_equal(i1, i2)


def test_half_lists_and_empty_inputs():
    pts = np.array([[0.0, 0, 0], [0.5, 0, 0], [2.0, 0, 0]])
    for backend in BACKENDS:
        ns = NeighborSearch(0.5, backend).build(pts)
        off, idx = ns.query(half=True, sort=True)
        assert off.tolist() == [0, 1, 1, 1] and idx.tolist() == [1]
        off, idx = ns.query(np.zeros((0, 3)))
        assert off.tolist() == [0] and idx.size == 0


def test_bad_arguments():
    with pytest.raises(ValueError, match="radius"):
        NeighborSearch(0.0)
    with pytest.raises(TypeError, match="radius"):
        NeighborSearch("1")
    with pytest.raises(ValueError, match="backend"):
        NeighborSearch(1.0, "octree")
    with pytest.raises(ValueError, match="points"):
        NeighborSearch(1.0).build(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="NaN"):
        NeighborSearch(1.0).build(np.array([[0.0, np.nan, 0.0]]))
    with pytest.raises(ValueError, match="build"):
        NeighborSearch(1.0).query()
    with pytest.raises(ValueError, match="half"):
        NeighborSearch(1.0).build(np.zeros((2, 3))).query(np.zeros((1, 3)), half=True)
