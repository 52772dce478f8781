"""Ghost particles mirrored across the walls of a liquid's box-shaped container.

A summed kernel field falls off within a kernel support of the last particles; against a wall
that makes the surface pull away from it (most at the edges and corners of a tank, where two or
three walls meet), and the anisotropic kernels of the particles along a wall, whose neighbourhood
is cut in half, are flattened as if the wall were a free surface. Mirroring the particles near a
wall across it (ghost particles, as SPH boundary conditions do: Libersky et al. 1993, Colagrossi &
Landrini 2003) gives the particles next to the wall the neighbourhood of the liquid's interior,
and the field inside the container near the wall its interior value: intersected with the
container, the surface then meets the walls, their edges and their corners without a gap: the
field is computed up to :data:`WALL_MARGIN_R` radii beyond the walls, where the continued
surface is cut exactly at the walls' planes. A particle within ``reach`` of one wall gets one ghost,
of two walls (an
edge) three, of three walls (a corner) seven: the images under every combination of the
reflections.
"""

from __future__ import annotations

import itertools
import math
from typing import TYPE_CHECKING

import numpy as np

from ..geometry import Box
from ..validation import check_points, check_range

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["mirror_ghosts", "check_walls", "mirror_matrices", "grow_walls", "WALL_MARGIN_R"]

#: How far beyond the walls (over the largest particle radius ``r``: one spacing) the field of a
#: liquid with ghosts is computed: the surface crosses the walls there and is cut exactly at
#: them afterwards (``pipeline.surface.liquid.ClipBox``), so that neither the marching cubes'
#: sampling of the edges and corners nor the smoothing of the mesh reach the walls.
WALL_MARGIN_R = 2.0


def grow_walls(walls: tuple[np.ndarray, np.ndarray],
               margin: float) -> tuple[np.ndarray, np.ndarray]:
    """The box ``walls = (lower, upper)`` grown by ``margin`` (m) on every side."""
    lower, upper = walls
    return lower - margin, upper + margin


def check_walls(walls: Box | tuple[ArrayLike, ArrayLike] | None
                ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """``walls`` as ``(lower, upper)`` float64 arrays (m): a :class:`filters.geometry.Box` or a
    pair of corners with ``upper > lower`` on every axis; None stays None."""
    if walls is None:
        return None
    if isinstance(walls, Box):
        return np.asarray(walls.lower, np.float64), np.asarray(walls.upper, np.float64)
    try:
        lower, upper = (np.asarray(v, np.float64).reshape(3) for v in walls)
    except (TypeError, ValueError):
        raise TypeError("walls must be a filters.geometry.Box or a pair of (3,) corners "
                        "(lower, upper), m") from None
    if not (np.isfinite(lower).all() and np.isfinite(upper).all() and (upper > lower).all()):
        raise ValueError(f"walls must have finite corners with upper > lower on every axis, got "
                         f"{lower.tolist()}, {upper.tolist()}")
    return lower, upper


def mirror_ghosts(positions: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                  reach: float) -> tuple[NDArray[np.float64], NDArray[np.int64],
                                         NDArray[np.float64]]:
    """Images of the particles near the walls of the box ``[lower, upper]`` across those walls.

    Parameters
    ----------
    positions : (N, 3) float64
        Particle positions (m); those outside the box are not mirrored.
    lower, upper : (3,) float
        Corners of the box (m).
    reach : float
        A particle within ``reach`` (m) of a wall is mirrored across it, >= 0.

    Returns
    -------
    ghosts : (G, 3) float64
        Ghost positions (m), grouped by reflection (a fixed order: deterministic).
    source : (G,) int64
        The particle each ghost mirrors.
    signs, shifts : (G, 3) float64
        The reflection of each ghost as ``ghost = signs * particle + shifts`` (``signs`` -1 on
        the axes it is mirrored along, ``shifts`` twice the wall's coordinate there; +1 and 0
        elsewhere): the same map gives the image of any point of the particle, e.g. its kernel
        centre.
    """
    x = check_points("positions", positions)
    lower = np.asarray(lower, np.float64).reshape(3)
    upper = np.asarray(upper, np.float64).reshape(3)
    reach = check_range("reach", reach, 0.0, math.inf)
    inside = np.all((x >= lower) & (x <= upper), axis=1)
    near_lo = inside[:, None] & (x - lower < reach)
    near_hi = inside[:, None] & (upper - x < reach)
    ghosts, source, signs, shifts = [], [], [], []
    # every combination of (no wall / lower wall / upper wall) per axis but the identity
    for combo in itertools.product((0, -1, 1), repeat=3):
        if combo == (0, 0, 0):
            continue
        mask = np.ones(x.shape[0], bool)
        for a, side in enumerate(combo):
            if side < 0:
                mask &= near_lo[:, a]
            elif side > 0:
                mask &= near_hi[:, a]
        idx = np.flatnonzero(mask)
        if not idx.size:
            continue
        sign = np.array([1.0 if side == 0 else -1.0 for side in combo])
        shift = np.array([0.0 if side == 0 else 2.0 * (lower[a] if side < 0 else upper[a])
                          for a, side in enumerate(combo)])
        ghosts.append(x[idx] * sign + shift)
        source.append(idx)
        signs.append(np.broadcast_to(sign, (idx.size, 3)))
        shifts.append(np.broadcast_to(shift, (idx.size, 3)))
    if not ghosts:
        return np.zeros((0, 3)), np.zeros(0, np.int64), np.ones((0, 3)), np.zeros((0, 3))
    return (np.ascontiguousarray(np.concatenate(ghosts)),
            np.concatenate(source).astype(np.int64), np.concatenate(signs),
            np.concatenate(shifts))


def mirror_matrices(G: np.ndarray, signs: np.ndarray) -> NDArray[np.float64]:
    """Kernel matrices of mirrored ghosts: ``S G S`` with ``S = diag(signs)``.

    Parameters
    ----------
    G : (M, 3, 3) float64
        Kernel matrices of the mirrored particles (1/m).
    signs : (M, 3) float64
        Per-axis signs of the reflections (:func:`mirror_ghosts`).

    Returns
    -------
    (M, 3, 3) float64
    """
    return G * signs[:, :, None] * signs[:, None, :]
