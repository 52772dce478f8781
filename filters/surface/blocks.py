"""The block driver of the splats: which blocks of the sparse voxel grid to evaluate, and in what
rounds, for any kernel shape.

Both splats (:mod:`filters.surface.spheres`, :mod:`filters.surface.ellipsoids`) work the same
way: particles are binned by the block of ``block_size ** 3`` voxels that holds them
(:func:`bin_by_block`, a stable counting sort: deterministic); the *candidate* blocks are those
a particle can reach; among them, blocks whose 8 corner samples are all clearly inside are
marked inside, and blocks where an upper bound of the field over the block grown by one voxel
cannot reach the iso value are marked outside (:func:`classify_and_evaluate`); every other
block is evaluated voxel by voxel, and then every skipped block next to which an evaluated
voxel has the other sign, round after round, until none is left (:func:`evaluate_rounds`), so
that every voxel edge the surface crosses has two computed values: the contour of the sparse
grid is the contour of the dense one. A closed pocket of outside (a bubble) wholly inside one
skipped block, i.e. smaller than a block and missed by its corners, would be lost; the splats'
``skip_interior=False`` evaluates every block that is not provably outside.

The kernel-specific parts (corner samples, bounds, voxel values) are the caller's callables;
every evaluated voxel is written by one task summing in a fixed order, so the grid is bitwise
identical for any number of threads.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..binning import counting_sort, index_keys, lookup
from .grid import (
    SparseGrid,
    block_keys,
    check_budget,
    corner_index,
    pack_key,
    unpack_key,
    unpack_keys,
)

if TYPE_CHECKING:
    from collections.abc import Callable
    from typing import Any

    from numpy.typing import NDArray

__all__ = ["bin_by_block", "grown_block_box", "classify_and_evaluate", "evaluate_rounds",
           "blocks_meeting_box"]


@njit(cache=True)
def _ranks_of(table, ranks, keys, out):
    for t in range(keys.size):
        out[t] = lookup(table, ranks, keys[t])


def bin_by_block(positions: np.ndarray, cell_size: float, block_size: int,
                 sort_blocks: bool = False) -> tuple[NDArray[np.int64], NDArray[np.int64],
                                                     NDArray[np.int64], NDArray[np.int32]]:
    """Bin points by the block that holds them.

    Parameters
    ----------
    positions : (N, 3) float64
        Points (m), within the block keys' range (:func:`filters.surface.grid.check_block_range`).
    cell_size : float
        Voxel edge (m).
    block_size : int
        Voxels per block edge.
    sort_blocks : bool
        Number the home blocks in sorted (x-major) key order rather than in order of first
        appearance, so that neighbouring blocks stay close in memory whatever the point order.

    Returns
    -------
    table, ranks : (C,) int64
        Hash index of the home blocks (:func:`filters.binning.lookup` gives a block's number).
    unique : (U,) int64
        Keys of the home blocks, by number.
    start : (U + 1,) int64
        Block ``u`` holds the points ``order[start[u]:start[u + 1]]``.
    order : (N,) int32
        Point indices in block order (stable).
    """
    keys = block_keys(positions, 1.0 / cell_size, block_size)
    table, ranks, unique, inverse = index_keys(keys)
    if sort_blocks:
        unique.sort()
        table, ranks, _, _ = index_keys(unique)
        _ranks_of(table, ranks, keys, inverse)
    start, order = counting_sort(inverse, unique.size, 1)
    return table, ranks, unique, start, order


@njit(cache=True, inline="always")
def grown_block_box(key, bsz):
    """Block ``key``'s coordinates and its box grown by one voxel (voxel units):
    ``(bx, by, bz, lox, loy, loz, hix, hiy, hiz)``."""
    bx, by, bz = unpack_key(key)
    lox = bx * bsz - 1.0
    loy = by * bsz - 1.0
    loz = bz * bsz - 1.0
    hix = lox + bsz + 1.0
    hiy = loy + bsz + 1.0
    hiz = loz + bsz + 1.0
    return bx, by, bz, lox, loy, loz, hix, hiy, hiz


def blocks_meeting_box(keys: np.ndarray, block_size: int, cell_size: float, lower: np.ndarray,
                       upper: np.ndarray) -> NDArray[np.bool_]:
    """Which blocks, grown by one voxel, meet the box ``[lower, upper]`` (m).

    Parameters
    ----------
    keys : (K,) int64
        Block keys.
    block_size : int
        Voxels per block edge.
    cell_size : float
        Voxel edge (m).
    lower, upper : (3,) float
        Corners of the box (m).

    Returns
    -------
    (K,) bool
    """
    b = unpack_keys(np.asarray(keys, np.int64)).astype(np.float64)
    lo = (b * block_size - 1.0) * cell_size
    hi = ((b + 1.0) * block_size + 1.0) * cell_size
    return np.all((hi >= np.asarray(lower)) & (lo <= np.asarray(upper)), axis=1)


def classify_and_evaluate(active: np.ndarray, *, block_size: int, cell_size: float, max_bytes: int,
                          inside_value: float, outside_value: float, evaluate: Callable[..., Any],
                          corner_values: Callable[..., Any] | None = None,
                          inside_margin: float = 0.0,
                          upper_bounds: Callable[..., Any] | None = None,
                          outside: Callable[..., Any] = None) -> SparseGrid:
    """Mark candidate blocks inside or outside where that is certain, evaluate the rest.

    Parameters
    ----------
    active : (K,) int64
        Sorted keys of the candidate blocks.
    block_size : int
        Voxels per block edge.
    cell_size : float
        Voxel edge (m).
    max_bytes : int
        Memory budget (bytes).
    inside_value, outside_value : float
        Values standing for the blocks left unevaluated inside / outside.
    evaluate : callable
        ``evaluate(targets, data, first)``: see :func:`evaluate_rounds`.
    corner_values : callable, optional
        ``corner_values(points (M, 3) float64, voxel units) -> (M,)`` implicit values at block
        corners; a block whose 8 corners are all ``<= -inside_margin`` is marked inside. None:
        no block is marked inside (every reachable block is evaluated or bounded).
    inside_margin : float
        See ``corner_values``.
    upper_bounds : callable, optional
        ``upper_bounds(keys (M,)) -> (M,)`` bounds of the field over each block grown by one
        voxel; with ``outside(bounds) -> (M,) bool`` they mark blocks outside. None: no block is
        marked outside.
    outside : callable
        See ``upper_bounds``.

    Returns
    -------
    SparseGrid
    """
    check_budget(active.size * 40, max_bytes, f"an index of {active.size} blocks")
    states = np.full(active.size, 2, np.int8)
    if corner_values is not None:
        # coarse samples at the corners of every candidate block: inside if all are clearly
        # inside (the consistency rounds repair any wrong guess at faces)
        ucorner, corner_ranks = corner_index(active)
        vals = corner_values(np.ascontiguousarray(unpack_keys(ucorner) * float(block_size)))
        del ucorner
        states[vals[corner_ranks].max(axis=1) <= -inside_margin] = 1
        del corner_ranks, vals
    if upper_bounds is not None:
        rest = np.flatnonzero(states == 2)
        states[rest[outside(upper_bounds(active[rest]))]] = 0
    return evaluate_rounds(active, states, evaluate, cell_size, block_size, inside_value,
                           outside_value, max_bytes)


def evaluate_rounds(active: np.ndarray, states: np.ndarray, evaluate: Callable[..., Any],
                    cell_size: float, bsz: int, inside_value: float, outside_value: float,
                    max_bytes: int) -> SparseGrid:
    """Evaluate the candidate blocks still undecided, then those the face check flags, round by
    round, and return the grid.

    Parameters
    ----------
    active : (K,) int64
        Sorted keys of the candidate blocks.
    states : (K,) int8
        Per block: 0 outside, 1 inside, 2 to evaluate (updated in place).
    evaluate : callable
        ``evaluate(targets, data, first)`` fills ``data[first + t]`` with the implicit values of
        block ``targets[t]``.
    cell_size : float
    bsz : int
        Voxels per block edge.
    inside_value, outside_value : float
        Values of the blocks left unevaluated inside / outside.
    max_bytes : int
        Memory budget (bytes) for the evaluated blocks.
    """
    atable, aranks, _, _ = index_keys(active)
    _interior_closure(active, states, atable, aranks)
    block_bytes = 4 * bsz**3
    todo = np.flatnonzero(states == 2)
    count = 0
    # room for every candidate block: pages never written are never resident, so this costs
    # address space only, and later rounds need no copy
    capacity = min(active.size, max_bytes // block_bytes + 1)
    data = np.empty((capacity, bsz, bsz, bsz), np.float32)
    done_keys = np.empty(capacity, np.int64)
    while todo.size:
        need = count + todo.size
        check_budget(need * block_bytes, max_bytes, f"{need} blocks of {bsz}^3 voxels")
        targets = active[todo]
        evaluate(targets, data, count)
        done_keys[count:need] = targets
        flags = _mismatches(targets, data[count:need], bsz, atable, aranks, states)
        count = need
        flagged = np.unique(flags[flags >= 0])
        states[flagged] = 2
        # newly evaluated inside blocks may expose inside neighbours to outside ones
        todo = flagged
    # keys stay in evaluation order (deterministic: sorted candidates, then sorted rounds of
    # additions); no copy of the data
    return SparseGrid(cell_size, bsz, done_keys[:count], data[:count],
                      np.sort(active[states == 1]), inside_value, outside_value)


@njit(parallel=True, cache=True)
def _mismatches(keys, data, bsz, skeys_table, sranks, states):
    """For each evaluated block and each of its 26 neighbours, 1 if the neighbour is skipped
    (state 0 outside / 1 inside) and a voxel of the block next to it has the other sign."""
    m = keys.size
    flags = np.full((m, 27), -1, np.int64)
    for t in prange(m):
        bx, by, bz = unpack_key(keys[t])
        d = data[t]
        c = 0
        for dz in range(-1, 2):
            for dy in range(-1, 2):
                for dx in range(-1, 2):
                    c += 1
                    if dx == 0 and dy == 0 and dz == 0:
                        continue
                    r = lookup(skeys_table, sranks, pack_key(bx + dx, by + dy, bz + dz))
                    if r < 0:
                        continue
                    st = states[r]
                    if st == 2:
                        continue
                    i0 = 0 if dx <= 0 else bsz - 1
                    i1 = bsz if dx >= 0 else 1
                    j0 = 0 if dy <= 0 else bsz - 1
                    j1 = bsz if dy >= 0 else 1
                    k0 = 0 if dz <= 0 else bsz - 1
                    k1 = bsz if dz >= 0 else 1
                    bad = False
                    for k in range(k0, k1):
                        for j in range(j0, j1):
                            for i in range(i0, i1):
                                val = d[k, j, i]
                                if st == 1 and val >= 0:
                                    bad = True
                                elif st == 0 and val <= 0:
                                    bad = True
                    if bad:
                        flags[t, c - 1] = r
    return flags


@njit(cache=True)
def _interior_closure(keys, states, table, ranks):
    """Inside blocks with an outside or unreached neighbour must be evaluated."""
    changed = 0
    for t in range(keys.size):
        if states[t] != 1:
            continue
        bx, by, bz = unpack_key(keys[t])
        for dz in range(-1, 2):
            for dy in range(-1, 2):
                for dx in range(-1, 2):
                    r = lookup(table, ranks, pack_key(bx + dx, by + dy, bz + dz))
                    if r < 0 or states[r] == 0:
                        if states[t] == 1:
                            states[t] = 2
                            changed += 1
    return changed
