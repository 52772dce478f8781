"""filters.binning: the one counting sort, cell index and hash index of the package."""

import numpy as np
import pytest

from filters.binning import (
    EMPTY_KEY,
    cell_keys,
    counting_sort,
    fitting_cells,
    index_keys,
    insert_key,
    lookup,
    sort_into_cells,
)


def test_counting_sort_is_stable_and_independent_of_the_chunks(rng):
    keys = rng.integers(0, 17, 1000)
    reference = np.argsort(keys, kind="stable")
    for nchunks in (1, 2, 7, 64):
        start, order = counting_sort(keys, 17, nchunks)
        np.testing.assert_array_equal(order, reference)
        np.testing.assert_array_equal(start, np.r_[0, np.cumsum(np.bincount(keys, minlength=17))])


def test_cell_keys_clamp_far_points_into_the_border_cells():
    dims = np.array([4, 3, 2])
    pts = np.array([[0.5, 0.5, 0.5], [3.5, 2.5, 1.5], [-1e308, 1e308, 0.2], [10.0, -5.0, 9.0]])
    keys = cell_keys(pts, np.zeros(3), 1.0, dims)
    np.testing.assert_array_equal(keys, [0, (1 * 3 + 2) * 4 + 3, (0 * 3 + 2) * 4 + 0,
                                         (1 * 3 + 0) * 4 + 3])


def test_sort_into_cells_and_fitting_cells(rng):
    pts = rng.uniform(0.0, 1.0, (500, 3))
    lo, cell, dims = fitting_cells(pts, 0.1)
    assert cell >= 0.1 and (lo == pts.min(axis=0)).all()
    order, start, sorted_pts = sort_into_cells(pts, lo, 1.0 / cell, dims)
    np.testing.assert_array_equal(sorted_pts, pts[order])
    keys = cell_keys(pts, lo, 1.0 / cell, dims)
    assert (np.diff(keys[order]) >= 0).all() and start[-1] == len(pts)
    # a sparse cloud gets larger cells instead of billions of them
    far = np.array([[0.0, 0.0, 0.0], [1e6, 1e6, 1e6]])
    _, cell, dims = fitting_cells(far, 0.1, max_cells=1000)
    assert np.prod(dims) <= 2000 and cell > 0.1


def test_hash_index_of_keys():
    keys = np.array([5, 9, 5, 2**40, 9, 7], dtype=np.int64)
    table, ranks, unique, inverse = index_keys(keys)
    np.testing.assert_array_equal(unique, [5, 9, 2**40, 7])
    np.testing.assert_array_equal(inverse, [0, 1, 0, 2, 1, 3])
    assert [lookup(table, ranks, k) for k in (9, 2**40, 8)] == [1, 2, -1]
    # the index grows past its first table
    many = np.arange(5000, dtype=np.int64) * 3
    table, ranks, unique, _ = index_keys(many)
    assert unique.size == 5000 and lookup(table, ranks, 4999 * 3) == 4999
    table, values, unique, count, rank = insert_key(np.full(4, EMPTY_KEY, np.int64),
                                                    np.empty(4, np.int64),
                                                    np.empty(1, np.int64), 0, 11)
    assert (count, rank, unique[0]) == (1, 0, 11)


@pytest.mark.parametrize("nchunks", [1, 3])
def test_empty_inputs(nchunks):
    start, order = counting_sort(np.zeros(0, np.int64), 5, nchunks)
    assert order.size == 0 and (start == 0).all()
