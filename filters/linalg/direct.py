"""Sparse direct solves: SuperLU (``scipy.sparse.linalg``) with a minimum-degree ordering."""

from __future__ import annotations

__all__ = ["direct_solve"]


def direct_solve(matrix, b):
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
    """
    from scipy.sparse.linalg import splu

    lu = splu(matrix.tocsc(), permc_spec="MMD_AT_PLUS_A",
              options={"SymmetricMode": True, "DiagPivotThresh": 0.0})
    return lu.solve(b)
