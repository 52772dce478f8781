"""Closed triangle meshes of simple solids for rigid bodies (a sphere is
:func:`filters.elastic.topology.icosphere`)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..validation import check_finite_vector, check_range

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["box_mesh"]

#: The 12 outward-oriented triangles of a box whose corner ``4 i + 2 j + k`` is at
#: ``(x_i, y_j, z_k)``.
_BOX_FACES = np.array([(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
                       (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)],
                      dtype=np.int64)


def box_mesh(size: ArrayLike,
             center: ArrayLike = (0.0, 0.0, 0.0)) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """An axis-aligned box as 8 vertices and 12 outward-oriented triangles.

    Parameters
    ----------
    size : float or (3,) array_like
        Edge lengths (m), > 0.
    center : (3,) array_like
        Centre (m).

    Returns
    -------
    vertices : (8, 3) float64 array
    faces : (12, 3) int64 array
    """
    if np.ndim(size) == 0:
        s = check_range("size", size, 0.0, math.inf, low_inclusive=False, high_inclusive=False)
        size = (s, s, s)
    size = check_finite_vector("size", size, 3)
    if not (size > 0).all():
        raise ValueError(f"size must be > 0 on every axis, got {size.tolist()}")
    c = check_finite_vector("center", center, 3)
    h = 0.5 * size
    v = np.array([[x, y, z] for x in (-h[0], h[0]) for y in (-h[1], h[1])
                  for z in (-h[2], h[2])]) + c
    return v, _BOX_FACES.copy()
