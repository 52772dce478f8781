"""What the schemes of :mod:`filters.integrators` share: :class:`StepInfo`, the step check, the
linear solver of a name, and the warm starts kept in a state's ``extra``."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..linalg.solver import LinearSolver
from ..validation import check_range

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from ..simulation import State

__all__ = ["StepInfo", "check_h", "linear_solver", "warm_start", "store_warm_start"]


@dataclass
class StepInfo:
    """What one integration step did.

    Attributes
    ----------
    newton_iterations : int
        Newton iterations (0 for explicit schemes, 1 for the linearised one).
    linear_iterations : int
        Total PCG iterations over the step (0 for direct solves).
    direct_solves : int
        Number of sparse direct factorisations.
    line_search_halvings : int
        Total step halvings of the line search.
    residual : float
        Final Newton step size ``max |d| / h`` (m/s) -- or, when :func:`backward_euler` stopped
        on quadratic convergence, the estimate ``|d_k|^2 / |d_{k-1}|`` of the next one --, or 0
        for explicit schemes.
    velocity_scale : float
        1, or the factor :func:`backward_euler` with contacts applied to the velocities of a
        step that ``max_newton`` iterations left gaining energy.
    """

    newton_iterations: int = 0
    linear_iterations: int = 0
    direct_solves: int = 0
    line_search_halvings: int = 0
    residual: float = 0.0
    velocity_scale: float = 1.0


#: Loosest relative PCG tolerance of a Newton solve as a multiple of ``newton_tol / |d_prev|``


def check_h(h: float) -> float:
    """``h`` as a float, or ``ValueError`` unless it is a finite step (s) > 0."""
    return check_range("h", h, 0.0, math.inf, low_inclusive=False)


def linear_solver(solver: str | LinearSolver, preconditioner: str | None,
                  omega: float | None) -> LinearSolver:
    """A :class:`LinearSolver`: the one given, or a new one for a method name."""
    if isinstance(solver, LinearSolver):
        if preconditioner is not None or omega is not None:
            raise ValueError("preconditioner and omega belong to the LinearSolver given as "
                             "solver; pass them to it")
        return solver
    options = {} if omega is None else {"omega": omega}
    return LinearSolver(solver, preconditioner=preconditioner or "ssor", **options)



def warm_start(state: State, key: str, n: int) -> NDArray[np.float64] | None:
    """The warm start ``state.extra[key]`` as a flat float64 copy, or None if absent or not of
    size ``n``."""
    extra = state.extra
    if key in extra and extra[key].size == n:
        return np.array(extra[key], dtype=np.float64).ravel()
    return None


def store_warm_start(state: State, key: str, value: np.ndarray) -> None:
    """Keep ``value`` (any shape, 3N entries) as ``state.extra[key]`` (N, 3), a copy."""
    state.extra[key] = value.reshape(-1, 3).copy()
