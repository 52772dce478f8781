"""Per-particle attributes from noise: sizes, colours, lifetimes that vary smoothly in space.

Noise sampled at each particle's position (spatially coherent variation: neighbours look alike)
and, when ids are given, shifted by an irrational multiple of the id so that particles born at
the same place still differ. Deterministic.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..validation import check_finite, check_int, check_points, check_range
from .fractal import MAX_OCTAVES, check_top_frequency, fbm_value
from .perlin import kernel_tables

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["noise_variation"]

_ID_STEP = (0.6180339887498949, 0.3819660112501051, 0.7548776662466927)


@njit(parallel=True, cache=True)
def _variation_many(table, pts, ids, has_ids, frequency, octaves, low, high, out):
    norm = 0.0
    amp = 1.0
    for _ in range(octaves):
        norm += amp
        amp *= 0.5
    for i in prange(pts.shape[0]):
        ox = 0.0
        oy = 0.0
        oz = 0.0
        if has_ids:
            k = np.float64(ids[i] % 1048576)
            ox = k * _ID_STEP[0]
            oy = k * _ID_STEP[1]
            oz = k * _ID_STEP[2]
        n = fbm_value(table, pts[i, 0], pts[i, 1], pts[i, 2], frequency, octaves, 2.0, 0.5,
                      ox, oy, oz, False) / norm
        s = 0.5 + 0.5 * n * 1.6  # improved noise rarely exceeds +-0.6: stretch, then clip
        if s < 0.0:
            s = 0.0
        elif s > 1.0:
            s = 1.0
        out[i] = low + (high - low) * s

def noise_variation(points: ArrayLike, low: float, high: float, *, ids: ArrayLike | None = None,
                    frequency: float = 1.0, octaves: int = 1, seed: int = 0) -> np.ndarray:
    """Per-particle attributes (size, colour, lifetime...) in ``[low, high]`` from noise.

    Noise sampled at each particle's position (spatially coherent variation: neighbours look
    alike) and, when ``ids`` are given, shifted by an irrational multiple of the id so that
    particles born at the same place still differ.  Deterministic.

    Parameters
    ----------
    points : (N, 3) array_like
        Positions (m), e.g. where the particles were born.
    low, high : float
        Range of the attribute (any unit), ``low <= high``.
    ids : (N,) int array_like, optional
        Particle ids.
    frequency : float
        Lattice cells per metre, > 0.
    octaves : int
        1 to 16.
    seed : int
        Permutation seed.

    Returns
    -------
    (N,) float64 in [low, high]
    """
    pts = check_points("points", points)
    low = check_range("low", low)
    high = check_range("high", high, low, math.inf)
    frequency = check_finite("frequency", frequency, 0.0, math.inf, low_inclusive=False)
    octaves = check_int("octaves", octaves, 1, MAX_OCTAVES)
    check_top_frequency(frequency, octaves, 2.0)
    seed = check_int("seed", seed, 0, (1 << 63) - 1)
    if ids is None:
        id_array = np.zeros(1, dtype=np.int64)
    else:
        id_array = np.ascontiguousarray(ids, dtype=np.int64).ravel()
        if id_array.shape[0] != pts.shape[0]:
            raise ValueError(f"ids must have {pts.shape[0]} entries, got {id_array.shape[0]}")
    out = np.empty(pts.shape[0])
    _variation_many(kernel_tables(seed, 1)[0], pts, id_array, ids is not None, frequency, octaves,
                    low, high, out)
    return out
