"""Linear algebra of the implicit integrators, in Numba: conjugate gradients on CSR matrices
(:mod:`~filters.linalg.cg`) and on matrix-free block operators (:mod:`~filters.linalg.operator`,
:mod:`~filters.linalg.block_cg`, :mod:`~filters.linalg.ssor`), sparse direct solves
(:mod:`~filters.linalg.direct`), dense 3x3 blocks (:mod:`~filters.linalg.dense3`), the
:class:`ImplicitSystem` a system implements (:mod:`~filters.linalg.protocol`) and the
:class:`LinearSolver` an integrator uses (:mod:`~filters.linalg.solver`)."""

from .cg import pcg
from .direct import direct_solve
from .operator import BlockOperator
from .protocol import ImplicitSystem
from .solver import (
                     DEFAULT_OMEGA,
                     PRECONDITIONERS,
                     SOLVERS,
                     LinearSolver,
                     pcg_operator,
                     solve_linear,
)

__all__ = ["ImplicitSystem", "BlockOperator", "LinearSolver", "SOLVERS", "PRECONDITIONERS",
           "DEFAULT_OMEGA", "pcg", "pcg_operator", "solve_linear", "direct_solve"]
