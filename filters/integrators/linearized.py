"""The linearised backward Euler step (Baraff & Witkin 1998): one Newton step of backward Euler,
with contacts solved exactly on the quadratic model
(:func:`filters.contact_solve.linearized_contact`)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..contact_solve import linearized_contact
from ..validation import check_int, check_range
from .common import StepInfo, check_h, linear_solver, store_warm_start, warm_start

if TYPE_CHECKING:
    from ..elastic.contact_model import ContactModel
    from ..linalg.protocol import ImplicitSystem
    from ..linalg.solver import LinearSolver
    from ..simulation import State

__all__ = ["linearized_backward_euler"]


def linearized_backward_euler(system: ImplicitSystem, state: State, h: float, *,
                              solver: str | LinearSolver = "auto", tol: float = 1e-6,
                              max_iter: int = 1000, preconditioner: str | None = None,
                              omega: float | None = None, contact: ContactModel | None = None,
                              contact_tol: float = 1e-3,
                              max_contact_iterations: int = 20) -> StepInfo:
    """One Newton step of backward Euler (Baraff & Witkin 1998), in place.

    Solves ``(M/h^2 + C/h + K) dv = (f0 - h K v0) / h`` with ``K = -df/dx`` (made definite) and
    ``C = -df/dv`` at the start of the step, then ``v += dv; x += h v``.  Cheap (one solve) but,
    on a flat cloth released under gravity, unstable above ``h ~ 0.012`` s: the first solve
    sees no transverse stiffness.  Use :func:`backward_euler` for large steps.

    Parameters
    ----------
    system, state, h
        As in :func:`forward_euler`.
    solver : {"auto", "pcg", "direct"} or LinearSolver
        Linear solver (see :mod:`filters.linalg.solver`); a :class:`LinearSolver` object keeps
        its scratch arrays between steps.
    tol, max_iter : float, int
        PCG tolerance and iteration limit.
    preconditioner : {"ssor", "block_jacobi", "sgs"}, optional
        As in :func:`backward_euler` (default ``"ssor"``: 25 instead of 92 iterations on the
        hanging 64x64 benchmark cloth); only with a solver given by name.
    omega : float, optional
        Over-relaxation factor of ``"ssor"`` (default :data:`filters.linalg.DEFAULT_OMEGA`);
        only with a solver given by name.
    contact : contact model, optional
        Contacts and friction (:class:`filters.elastic.contact_model.ContactModel`): the
        step then minimises the quadratic model of the incremental potential plus the contact
        terms (:func:`filters.contact_solve.linearized_contact`): the elastic forces are
        linearised once, the contacts solved exactly, by Newton iterations whose directions
        reuse the matrix at ``x`` (one solve when nothing touches).
    contact_tol : float
        Newton tolerance (m/s) of that minimisation, > 0.
    max_contact_iterations : int
        Its iteration limit, >= 1.

    Returns
    -------
    StepInfo
    """
    h = check_h(h)
    linear = linear_solver(solver, preconditioner, omega)
    x, v = state.positions, state.velocities
    n = x.shape[0]
    if contact is not None:
        return _linearized_with_contact(system, state, h, linear, tol, max_iter, contact,
                                        contact_tol, max_contact_iterations)
    f0 = system.forces(x, v)
    mat = linear.operator(system, x, x, h)  # matrix-free when it can be
    # K v0 = -(df/dx) v0 = H v0 - (M/h^2 + C/h) v0 on free particles; compute it from the matrix.
    kv = (mat @ v.ravel()).reshape(n, 3)
    kv -= (system.masses[:, None] / (h * h)) * v
    kv += system.damping_forces(x, v) / h
    rhs = (f0 - h * kv) / h
    rhs[system.pinned] = 0.0
    dv, it, direct = linear.solve(system, x, x, h, rhs, warm_start(state, "lbe_warm", 3 * n), tol,
                                  max_iter)
    store_warm_start(state, "lbe_warm", dv)
    v += dv.reshape(n, 3)
    v[system.pinned] = 0.0
    x += h * v
    return StepInfo(newton_iterations=1, linear_iterations=it, direct_solves=int(direct))


def _linearized_with_contact(system, state, h, linear, tol, max_iter, contact, contact_tol,
                             max_contact_iterations):
    """:func:`linearized_backward_euler` with contacts, in place."""
    check_range("contact_tol", contact_tol, 0.0, math.inf, low_inclusive=False)
    check_int("max_contact_iterations", max_contact_iterations, 1)
    x, v = state.positions, state.velocities
    dx, it, lin_it, direct = linearized_contact(
        system, linear, x, v, h, contact, tol=contact_tol, max_iter=max_contact_iterations,
        lin_tol=tol, lin_max_iter=max_iter, warm=warm_start(state, "lbe_contact_warm", v.size))
    store_warm_start(state, "lbe_contact_warm", dx - h * np.where(system.pinned[:, None], 0.0, v))
    x += dx
    v[:] = dx / h
    v[system.pinned] = 0.0
    return StepInfo(newton_iterations=it, linear_iterations=lin_it, direct_solves=direct)
