"""The Kuhn (Freudenthal) split of a cube into six tetrahedra, shared by meshing and contouring.

Every cube of a lattice is cut into the six tetrahedra that share its main diagonal from corner
``(0, 0, 0)`` to ``(1, 1, 1)``: one per ordering ``(a, b, c)`` of the axes, with vertices
``0, e_a, e_a + e_b, e_a + e_b + e_c`` (Freudenthal 1942, "Simplizialzerlegungen von
beschränkter Flachheit"; Kuhn 1960, "Some combinatorial lemmas in topology").  The split is
the same in every cube, so two neighbouring cubes cut their shared face along the same
diagonal and the tetrahedra of a whole lattice form one conforming mesh.  The edges of that
mesh leave every lattice point in the seven directions of :data:`KUHN_DIRECTIONS`.

Corners of a cube are numbered ``c = i + 2 j + 4 k`` for the offset ``(i, j, k)``.  A point
with local coordinates ``t`` in ``[0, 1]^3`` lies in the tetrahedron of the ordering that sorts
``t`` decreasingly, with barycentric weights ``1 - t_a, t_a - t_b, t_b - t_c, t_c``
(:func:`kuhn_locate`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = ["CORNER_OFFSETS", "KUHN_ORDERS", "KUHN_TETS", "KUHN_DIRECTIONS", "kuhn_locate"]

#: Offsets (8, 3) of the cube corners, corner ``c = i + 2 j + 4 k``.
CORNER_OFFSETS = np.array([[c & 1, (c >> 1) & 1, (c >> 2) & 1] for c in range(8)], np.int64)

#: The six orderings ``(a, b, c)`` of the axes, one per tetrahedron.
KUHN_ORDERS = np.array([(0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)],
                       np.int64)

#: Whether each ordering is an odd permutation (its path tetrahedron is negatively oriented).
_ODD = np.array([(int(a > b) + int(a > c) + int(b > c)) % 2 == 1 for a, b, c in KUHN_ORDERS])


def _kuhn_tets():
    tets = np.empty((6, 4), np.int64)
    for n in range(6):
        a, b, _ = (int(v) for v in KUHN_ORDERS[n])
        path = [0, 1 << a, (1 << a) | (1 << b), 7]
        # the volume's sign is the ordering's parity: odd orderings swap the last two
        # vertices so that every tetrahedron is positively oriented
        if _ODD[n]:
            path[2], path[3] = path[3], path[2]
        tets[n] = path
    return tets


#: Corners (6, 4) of the six positively oriented tetrahedra of a cube
#: (``det[x1 - x0, x2 - x0, x3 - x0] = +1`` on the unit cube).
KUHN_TETS = _kuhn_tets()

#: The seven edge directions (7, 3) leaving a lattice point towards higher indices: the axes,
#: the face diagonals ``e_a + e_b`` and the main diagonal.
KUHN_DIRECTIONS = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, 0, 1], [0, 1, 1],
                            [1, 1, 1]], np.int64)


def kuhn_locate(t: np.ndarray) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The tetrahedron of the Kuhn split holding local points and their barycentric weights.

    Parameters
    ----------
    t : (M, 3) float array
        Local coordinates in the unit cube, in ``[0, 1]^3``.

    Returns
    -------
    tet : (M,) int64
        Row of :data:`KUHN_TETS`.
    weights : (M, 4) float64
        Barycentric weights of the corners ``KUHN_TETS[tet]`` (non-negative, summing to 1).
    """
    t = np.asarray(t, dtype=np.float64).reshape(-1, 3)
    order = np.argsort(-t, axis=1, kind="stable")  # decreasing, ties by axis
    key = order[:, 0] * 9 + order[:, 1] * 3 + order[:, 2]
    lookup = np.full(27, -1, np.int64)
    for n, (a, b, c) in enumerate(KUHN_ORDERS):
        lookup[a * 9 + b * 3 + c] = n
    tet = lookup[key]
    ts = np.take_along_axis(t, order, axis=1)
    path = np.stack([1.0 - ts[:, 0], ts[:, 0] - ts[:, 1], ts[:, 1] - ts[:, 2], ts[:, 2]], 1)
    weights = path.copy()
    odd = _ODD[tet]
    weights[odd, 2], weights[odd, 3] = path[odd, 3], path[odd, 2]
    return tet, weights
