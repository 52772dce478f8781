"""Linear solves of the implicit integrators: one :class:`LinearSolver` per simulation.

``method="pcg"``: preconditioned conjugate gradients in Numba, warm started from the previous
step's solution; on the system's matrix-free operator when it has one
(:meth:`filters.linalg.protocol.ImplicitSystem.implicit_operator`; :func:`pcg_operator`, with a
choice of per-particle block Jacobi, block symmetric Gauss-Seidel, or block SSOR with
Eisenstat's trick), otherwise block Jacobi on the CSR matrix (:func:`filters.linalg.cg.pcg`).
``method="direct"``: SuperLU (:func:`filters.linalg.direct.direct_solve`). ``method="auto"``:
PCG, falling back to the direct solve when PCG does not converge in ``max_iter`` iterations.
The choice was made with ``benchmarks/bench_springs.py`` (see ``benchmarks/results/springs.json``).
A :class:`LinearSolver` owns the scratch arrays of its solves, so a simulation that keeps one
allocates nothing per step.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..validation import check_choice, check_range
from .block_cg import pcg_blocks
from .cg import pcg
from .coupling import add_point_hessians_csr, add_point_hessians_pairs
from .direct import direct_solve
from .scale import unit_scale
from .ssor import DEFAULT_OMEGA, SSORWorkspace, pcg_ssor

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray
    from scipy.sparse import csr_matrix

    from .operator import BlockOperator
    from .protocol import ImplicitSystem

__all__ = ["SOLVERS", "PRECONDITIONERS", "DEFAULT_OMEGA", "LinearSolver", "pcg_operator",
           "solve_linear", "add_block_diagonal"]

#: Linear solvers of the implicit schemes.
SOLVERS = ("auto", "pcg", "direct")
#: Preconditioners of the matrix-free PCG.
PRECONDITIONERS = ("sgs", "block_jacobi", "ssor")


def pcg_operator(operator: BlockOperator, b: np.ndarray, x0: ArrayLike | None = None, *,
                 tol: float = 1e-6, max_iter: int = 1000, preconditioner: str = "sgs",
                 omega: float = DEFAULT_OMEGA,
                 workspace: SSORWorkspace | None = None) -> tuple[NDArray[np.float64], int, float]:
    """Solve ``operator @ x = b`` by PCG with a matrix-free spring operator, in Numba.

    Parameters
    ----------
    operator : filters.linalg.operator.BlockOperator
        The SPD system matrix (e.g. ``SpringSystem.implicit_operator``), (3N, 3N).
    b : (N, 3) or (3N,) float64 array
        Right-hand side.
    x0 : array like ``b``, optional
        Warm start (zeros if omitted); not modified.
    tol : float
        Relative residual ``|b - A x| / |b|`` to reach.
    max_iter : int
        Iteration limit.
    preconditioner : {"sgs", "block_jacobi", "ssor"}
        Block symmetric Gauss-Seidel (two sweeps over the springs per iteration, about half the
        iterations of block Jacobi on cloth), per-particle 3x3 block Jacobi, or block symmetric
        successive over-relaxation with Eisenstat's trick (:func:`filters.linalg.ssor.pcg_ssor`: the
        two sweeps
        *replace* the product with ``H``, so an iteration costs two passes over the springs;
        with ``omega`` near its optimum the preconditioned condition number is
        ``O(sqrt(kappa))`` on model problems (Axelsson 1994, "Iterative solution methods"),
        so the iterations grow like ``kappa^(1/4)`` instead of ``kappa^(1/2)``; ``tol``
        applies to the residual of ``H``, mapped back from the transformed system every few
        iterations).
    omega : float
        Over-relaxation factor of ``"ssor"``, in (0, 2) (1 is symmetric Gauss-Seidel).
    workspace : SSORWorkspace, optional
        Scratch arrays of ``"ssor"`` kept between solves; a new one when omitted.

    Returns
    -------
    x : float64 array shaped like ``b``
    iterations : int
    relative_residual : float

    Notes
    -----
    The system is solved at unit scale (:func:`filters.linalg.scale.unit_scale`), so a
    right-hand side of 1e-200 or of denormals gives its (tiny) solution, and a zero one zero.
    """
    check_choice("preconditioner", preconditioner, PRECONDITIONERS)
    check_range("omega", omega, 0.0, 2.0, low_inclusive=False, high_inclusive=False)
    b = np.ascontiguousarray(b, dtype=np.float64)
    shape = b.shape
    s, bs, xs = unit_scale(b, x0)  # tiny right-hand sides solved at unit scale
    if s == 0.0:
        return np.zeros_like(b), 0, 0.0
    b3 = np.ascontiguousarray(bs.reshape(-1, 3))
    x = np.zeros_like(b3) if xs is None else np.array(xs, dtype=np.float64).reshape(-1, 3)
    x = np.ascontiguousarray(x)
    if preconditioner == "ssor":
        work = (workspace or SSORWorkspace()).get(operator.diag.shape[0],
                                                  operator.upper[1].shape[0])
        it, res = pcg_ssor(operator.pairs, operator.free, operator.blocks, operator.diag,
                           operator.upper, b3, x, float(tol), int(max_iter), float(omega), work,
                           operator.upper_ordered)
    else:
        it, res = pcg_blocks(operator.pairs, operator.free, operator.blocks, operator.diag,
                             operator.lower, operator.upper, b3, x, float(tol), int(max_iter),
                             preconditioner == "sgs")
    if s != 1.0:
        x *= s
    return x.reshape(shape), int(it), float(res)


def solve_linear(matrix: csr_matrix, b: np.ndarray, x0: np.ndarray | None = None, *,
                 solver: str = "auto", tol: float = 1e-6,
                 max_iter: int = 1000) -> tuple[NDArray[np.float64], int, bool]:
    """Solve ``matrix @ x = b`` with the chosen solver.

    Parameters
    ----------
    matrix : scipy.sparse.csr_matrix
        SPD system matrix.
    b : (n,) float64 array
        Right-hand side.
    x0 : (n,) float64 array, optional
        Warm start for PCG.
    solver : {"auto", "pcg", "direct"}
        ``"auto"`` runs PCG and falls back to the direct solve if it has not converged.
    tol, max_iter : float, int
        PCG relative tolerance and iteration limit.

    Returns
    -------
    x : (n,) float64 array
    iterations : int
        PCG iterations (including those of a PCG attempt before a fallback).
    direct : bool
        Whether a direct solve produced ``x``.
    """
    check_choice("solver", solver, SOLVERS)
    if solver == "direct":
        return direct_solve(matrix, b), 0, True
    x, it, res = pcg(matrix, b, x0, tol=tol, max_iter=max_iter)
    if res <= tol or solver == "pcg":
        return x, it, False
    return direct_solve(matrix, b), it, True




class LinearSolver:
    """The linear solver of an implicit integrator, with its scratch arrays.

    Parameters
    ----------
    method : {"auto", "pcg", "direct"}
        See the module docstring.
    preconditioner : {"ssor", "block_jacobi", "sgs"}
        Preconditioner of the matrix-free PCG.
    omega : float
        Over-relaxation factor of ``"ssor"``, in (0, 2).
    """

    def __init__(self, method: str = "auto", *, preconditioner: str = "ssor",
                 omega: float = DEFAULT_OMEGA):
        self.method = check_choice("solver", method, SOLVERS)
        self.preconditioner = check_choice("preconditioner", preconditioner, PRECONDITIONERS)
        self.omega = check_range("omega", omega, 0.0, 2.0, low_inclusive=False,
                                 high_inclusive=False)
        self.workspace = SSORWorkspace()

    def operator(self, system: ImplicitSystem, x: np.ndarray, xdir: np.ndarray, h: float,
                 diagonal: np.ndarray | None = None,
                 points: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
                 ) -> csr_matrix | BlockOperator:
        """The system matrix at ``(x, xdir, h)``: matrix-free when the method iterates and the
        system has such a form, else the assembled CSR matrix; plus the particle blocks
        ``diagonal`` (N, 3, 3) when given (rows of pinned particles stay the identity).  With
        ``points`` = ``(nodes (M, K), weights (M, K), hessians (M, 6))`` of terms on embedded
        points whose diagonal bound ``diagonal`` is, their exact blocks ``W^T H W`` instead
        where the matrix's pattern holds them (:mod:`filters.linalg.coupling`).  A
        matrix-free operator's arrays are overwritten by the next call."""
        op = system.implicit_operator(x, xdir, h) if self.method != "direct" else None
        if op is not None:
            if diagonal is not None:
                op.diag += np.where(system.pinned[:, None, None], 0.0, diagonal)
                if points is not None:
                    add_point_hessians_pairs(op, *points)
            return op
        mat = system.system_matrix(x, xdir, h)
        return _with_contact(mat, system.pinned, diagonal, points)

    def solve(self, system: ImplicitSystem, x: np.ndarray, xdir: np.ndarray, h: float,
              rhs: np.ndarray, warm: np.ndarray | None, tol: float, max_iter: int,
              diagonal: np.ndarray | None = None,
              points: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
              ) -> tuple[NDArray[np.float64], int, bool]:
        """Solve ``(H(x, xdir) + diagonal) d = rhs`` for an
        :class:`~filters.linalg.protocol.ImplicitSystem`.

        Parameters
        ----------
        system : ImplicitSystem
        x, xdir : (N, 3) float64
            Positions of the stiffness and of the damping directions (m).
        h : float
            Time step (s).
        rhs : (N, 3) float64
            Right-hand side.
        warm : (3N,) float64 or None
            Warm start of PCG.
        tol : float
            Relative residual PCG must reach.
        max_iter : int
            PCG iteration limit.
        diagonal : (N, 3, 3) float64, optional
            Symmetric positive semi-definite blocks added to the particles' diagonal blocks
            (contacts); ignored on pinned particles.
        points : tuple, optional
            The embedded points whose bound ``diagonal`` is, for their exact blocks (see
            :meth:`operator`).

        Returns
        -------
        d : (3N,) float64
        iterations : int
            PCG iterations (including those of a PCG attempt before a direct fallback).
        direct : bool
            Whether a direct solve produced ``d``.
        """
        op = self.operator(system, x, xdir, h, diagonal, points)
        if not hasattr(op, "tocsc"):  # matrix-free
            d, it, res = pcg_operator(op, rhs, warm, tol=tol, max_iter=max_iter,
                                      preconditioner=self.preconditioner, omega=self.omega,
                                      workspace=self.workspace)
            if res <= tol or self.method == "pcg":
                return d.ravel(), it, False
            mat = _with_contact(system.system_matrix(x, xdir, h), system.pinned, diagonal,
                                points)
            return direct_solve(mat, rhs.ravel()), it, True
        return solve_linear(op, rhs.ravel(), warm, solver=self.method, tol=tol,
                            max_iter=max_iter)

    def product(self, system: ImplicitSystem, x: np.ndarray, xdir: np.ndarray, h: float,
                p: np.ndarray) -> NDArray[np.float64]:
        """``H(x, xdir) p`` for ``p`` (N, 3) (no added blocks), shaped like ``p``."""
        op = self.operator(system, x, xdir, h)
        return (op @ np.ascontiguousarray(p).ravel()).reshape(p.shape)


def _with_contact(mat, pinned, diagonal, points):
    """A CSR matrix plus contact blocks: exact ones of ``points`` where its pattern holds
    them, else the diagonal bound ``diagonal``."""
    if diagonal is None:
        return mat
    if points is not None:
        exact = add_point_hessians_csr(mat, *points, pinned)
        if exact is not None:
            return exact
    return add_block_diagonal(mat, diagonal, pinned)


def add_block_diagonal(matrix: csr_matrix, blocks: np.ndarray, pinned: np.ndarray) -> csr_matrix:
    """``matrix + diag(blocks)`` for a CSR ``matrix`` (3N, 3N) and particle blocks (N, 3, 3),
    leaving the rows and columns of ``pinned`` particles alone; a new CSR matrix."""
    import scipy.sparse as sp

    n = blocks.shape[0]
    data = np.where(pinned[:, None, None], 0.0, blocks)
    extra = sp.bsr_matrix((data, np.arange(n), np.arange(n + 1)), shape=matrix.shape)
    return (matrix + extra).tocsr()
