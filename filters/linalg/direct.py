"""Sparse direct solves: SuperLU (``scipy.sparse.linalg``) with a minimum-degree ordering."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .scale import unit_scale

if TYPE_CHECKING:
    from numpy.typing import NDArray
    from scipy.sparse import spmatrix

__all__ = ["direct_solve"]


def direct_solve(matrix: spmatrix, b: np.ndarray) -> NDArray[np.float64]:
    """Solve the SPD system ``matrix @ x = b`` by a sparse LU factorisation.

    SuperLU with a minimum-degree ordering on ``A + A^T``, symmetric mode and no pivoting
    threshold (the systems are SPD).

    Parameters
    ----------
    matrix : scipy.sparse matrix, (n, n)
        Symmetric positive definite.
    b : (n,) float64 array
        Right-hand side.

    Returns
    -------
    (n,) float64 array
        Solved at unit scale (:func:`filters.linalg.scale.unit_scale`): a right-hand side of
        1e-200 or of denormals gives its tiny solution, a zero one zero.
    """
    from scipy.sparse.linalg import splu

    b = np.ascontiguousarray(b, dtype=np.float64)
    s, bs, _ = unit_scale(b)
    if s == 0.0:
        return np.zeros_like(b)
    lu = splu(matrix.tocsc(), permc_spec="MMD_AT_PLUS_A",
              options={"SymmetricMode": True, "DiagPivotThresh": 0.0})
    x = lu.solve(bs)
    if s != 1.0:
        x *= s
    return x
