"""The contact part of a time step: one minimisation over the step's position increment.

Every scheme of :mod:`filters.integrators` given a ``contact`` model (such as
:class:`filters.elastic.contact_model.ContactModel`) ends its step by minimising, over the
position increment ``dx`` from the start positions ``x0``,

    ``Q(dx) + C(dx)``,

with ``C`` the contact model's penalty and friction terms and ``Q`` the scheme's own part:

* explicit schemes (:func:`filters.integrators.euler`,
  :func:`~filters.integrators.symplectic_euler`):
  ``Q = |dx - dx*|_M^2 / (2 h^2)`` around the increment ``dx*`` of the explicit update, so the
  contact impulses are the smallest change of momentum that satisfies the contacts -- the
  velocity-level response of Bridson, Fedkiw & Anderson (2002, "Robust treatment of collisions,
  contact and friction for cloth animation"), with the contact treated implicitly;
* the linearised backward Euler step (:func:`~filters.integrators.linearized_backward_euler`):
  ``Q`` is the quadratic model of the incremental potential at ``x0`` (Baraff & Witkin 1998's
  linear system), so the elastic forces are linearised once and the contacts are solved
  exactly;
* backward Euler (:func:`~filters.integrators.backward_euler`) adds ``C`` to its incremental
  potential in place (no function here).

The minimisation is Newton's method with a backtracking (Armijo) line search: every accepted
iterate lowers ``Q + C``.  A contact model supplies ``begin_step(x0, h)``, ``value(x0, dx)`` and
``derivatives(x0, dx, grad, blocks)`` (adds its gradient to ``grad`` (N, 3), writes positive
semi-definite particle blocks (N, 3, 3)).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from .linalg.cg import vdot

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy.typing import NDArray

    from .elastic.contact_model import ContactModel
    from .linalg.protocol import ImplicitSystem
    from .linalg.solver import LinearSolver
    from .simulation import State

__all__ = ["minimize_with_contact", "feasible_start", "explicit_contact", "linearized_contact",
           "apply_explicit_contact", "step_kinetic_energy"]

#: Armijo constant of the line searches.
ARMIJO = 1e-4


@njit(cache=True)
def _diagonal_solve(scale, blocks, g, pinned, d):
    """``d_i = -(scale_i I + blocks_i)^-1 g_i`` per particle (Cramer's rule); 0 if pinned.
    Serial: a few hundred ns per thousand particles, less than a parallel region's start."""
    for i in range(g.shape[0]):
        d[i, 0] = 0.0
        d[i, 1] = 0.0
        d[i, 2] = 0.0
        if pinned[i]:
            continue
        s = scale[i]
        a00 = s + blocks[i, 0, 0]
        a01 = blocks[i, 0, 1]
        a02 = blocks[i, 0, 2]
        a11 = s + blocks[i, 1, 1]
        a12 = blocks[i, 1, 2]
        a22 = s + blocks[i, 2, 2]
        c00 = a11 * a22 - a12 * a12
        c01 = a02 * a12 - a01 * a22
        c02 = a01 * a12 - a02 * a11
        c11 = a00 * a22 - a02 * a02
        c12 = a01 * a02 - a00 * a12
        c22 = a00 * a11 - a01 * a01
        det = a00 * c00 + a01 * c01 + a02 * c02
        g0 = g[i, 0]
        g1 = g[i, 1]
        g2 = g[i, 2]
        d[i, 0] = -(c00 * g0 + c01 * g1 + c02 * g2) / det
        d[i, 1] = -(c01 * g0 + c11 * g1 + c12 * g2) / det
        d[i, 2] = -(c02 * g0 + c12 * g1 + c22 * g2) / det


def minimize_with_contact(dx: np.ndarray, q_value: Callable[[np.ndarray], float],
                          q_gradient: Callable[[np.ndarray], np.ndarray],
                          solve: Callable[..., np.ndarray], contact: ContactModel, x0: np.ndarray,
                          h: float, pinned: np.ndarray, *, tol: float, max_iter: int,
                          decrement_tol: float) -> tuple[NDArray[np.float64], int, int]:
    """Minimise ``Q(dx) + C(dx)`` by Newton's method with a backtracking line search.

    Parameters
    ----------
    dx : (N, 3) float64
        Start increment (m); not modified.
    q_value : callable
        ``q_value(dx) -> float``: ``Q`` (J).
    q_gradient : callable
        ``q_gradient(dx) -> (N, 3)``: its gradient (N), a new array.
    solve : callable
        ``solve(g, blocks) -> (N, 3)``: the Newton direction ``-(Q'' + blocks)^-1 g``.
    contact : contact model
        See the module docstring; ``begin_step`` already called.
    x0 : (N, 3) float64
        Start positions (m).
    h : float
        Time step (s).
    pinned : (N,) bool
        Particles that do not move.
    tol : float
        Stop when ``max |d| / h`` (m/s) of a full step falls below it, and
    decrement_tol : float
        the Newton decrement ``-g . d`` (J) below this.
    max_iter : int
        Newton iteration limit.

    Returns
    -------
    dx : (N, 3) float64
        The minimiser (m).
    iterations : int
        Newton iterations.
    halvings : int
        Step halvings of the line search.
    """
    dx = dx.copy()
    n = dx.shape[0]
    blocks = np.zeros((n, 3, 3))
    energy = q_value(dx) + contact.value(x0, dx)
    halvings = 0
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 (the count is reported after the loop)
        g = q_gradient(dx)
        contact.derivatives(x0, dx, g, blocks)
        g[pinned] = 0.0
        d = solve(g, blocks)
        d[pinned] = 0.0
        slope = vdot(g, d)
        if not slope < 0.0:
            break  # at the minimum (to round-off)
        alpha = contact.max_step(x0, dx, d)
        accepted = False
        for _ in range(60):
            trial = dx + alpha * d
            e_trial = q_value(trial) + contact.value(x0, trial)
            if e_trial <= energy + ARMIJO * alpha * slope:
                accepted = True
                break
            alpha *= 0.5
            halvings += 1
        if not accepted:
            break
        dx, energy = trial, e_trial
        if float(np.abs(d).max()) / h < tol and -slope < decrement_tol:
            break
    return dx, it, halvings


def feasible_start(contact: ContactModel, x0: np.ndarray, dx: np.ndarray,
                   pinned: np.ndarray) -> NDArray[np.float64]:
    """``dx`` scaled per particle (by the contact model's :meth:`particle_steps`) so that no
    contact point crosses a collider on the way from ``x0``; pinned particles stay."""
    fractions = contact.particle_steps(x0, np.zeros_like(dx), dx)
    out = dx * fractions[:, None]
    out[pinned] = 0.0
    return out


def explicit_contact(masses: np.ndarray, pinned: np.ndarray, x0: np.ndarray, dx_free: np.ndarray,
                     h: float, contact: ContactModel, *, tol: float = 1e-4,
                     max_iter: int = 20) -> tuple[NDArray[np.float64] | None, int]:
    """Contact correction of an explicit step: minimise ``|c|_M^2 / (2 h^2) + C(dx_free + c)``.

    Parameters
    ----------
    masses : (N,) float64
        Particle masses (kg).
    pinned : (N,) bool
        Particles that do not move.
    x0 : (N, 3) float64
        Positions at the start of the step (m).
    dx_free : (N, 3) float64
        The explicit scheme's position increment (m).
    h : float
        Time step (s).
    contact : contact model
        See the module docstring; ``begin_step`` already called.
    tol, max_iter
        As in :func:`minimize_with_contact` (``tol`` in m/s; the decrement tolerance is
        ``M tol^2``, the kinetic energy of all the mass moving at ``tol``).

    Returns
    -------
    c : (N, 3) float64 or None
        The correction of the increment (m) -- the velocity changes by ``c / h`` --, or None
        when no particle touches anything (nothing to change).
    iterations : int
    """
    n = dx_free.shape[0]
    start = feasible_start(contact, x0, dx_free, pinned)
    grad = np.zeros((n, 3))
    blocks = np.zeros((n, 3, 3))
    contact.derivatives(x0, start, grad, blocks)
    grad[pinned] = 0.0
    if not np.any(grad) and np.array_equal(start, np.where(pinned[:, None], 0.0, dx_free)):
        return None, 0
    scale = masses / (h * h)

    def q_value(dx):
        c = dx - dx_free
        c[pinned] = 0.0
        return 0.5 * vdot(scale[:, None] * c, c)

    def q_gradient(dx):
        return scale[:, None] * (dx - dx_free)

    def solve(g, b):
        d = np.empty_like(g)
        _diagonal_solve(scale, b, g, pinned, d)
        return d

    dx, it, _ = minimize_with_contact(start, q_value, q_gradient, solve, contact, x0, h, pinned,
                                      tol=tol, max_iter=max_iter,
                                      decrement_tol=float(masses[~pinned].sum()) * tol * tol)
    c = dx - dx_free
    c[pinned] = 0.0
    untouched = np.all(dx == dx_free, axis=1)
    c[untouched] = 0.0
    return c, it


def linearized_contact(system: ImplicitSystem, linear: LinearSolver, x0: np.ndarray, v: np.ndarray,
                       h: float, contact: ContactModel, *, tol: float, max_iter: int,
                       lin_tol: float, lin_max_iter: int,
                       warm: np.ndarray | None = None) -> tuple[NDArray[np.float64], int, int, int]:
    """The linearised backward Euler step with contacts: minimise
    ``Q(dx) = |dx - h v|_M^2 / (2 h^2) - f_c(x0) . dx + dx^T (K + C / h) dx / 2`` (whose
    minimiser is Baraff & Witkin's step; ``K``, ``C`` and ``f_c``, the conservative forces, at
    ``x0``) plus the contact terms, by Newton iterations on the matrix at ``x0``.

    Parameters
    ----------
    system : ImplicitSystem
    linear : filters.linalg.LinearSolver
    x0, v : (N, 3) float64
        Positions (m) and velocities (m/s) at the start of the step; not modified.
    h : float
        Time step (s).
    contact : contact model
        ``begin_step`` is called here.
    tol, max_iter
        Newton stopping tolerance (m/s; the decrement tolerance is ``M tol^2``) and iteration
        limit.
    lin_tol, lin_max_iter
        PCG tolerance and iteration limit of each solve.
    warm : (3N,) float64, optional
        Warm start of the first solve.

    Returns
    -------
    dx : (N, 3) float64
        The increment (m), zero on pinned particles.
    iterations : int
        Newton iterations.
    linear_iterations : int
        PCG iterations.
    direct_solves : int
    """
    pinned = system.pinned
    v_free = np.where(pinned[:, None], 0.0, v)
    rhs_b = system.masses[:, None] * v_free / h + system.conservative_forces(x0)
    rhs_b[pinned] = 0.0
    contact.begin_step(x0, h)
    counts = [0, 0]
    warm_box = [warm]

    def q_value(dx):
        hdx = linear.product(system, x0, x0, h, dx)
        return 0.5 * vdot(dx, hdx) - vdot(rhs_b, dx)

    def q_gradient(dx):
        g = linear.product(system, x0, x0, h, dx) - rhs_b
        g[pinned] = 0.0
        return g

    def solve(g, blocks):
        d, it, direct = linear.solve(system, x0, x0, h, -g, warm_box[0], lin_tol, lin_max_iter,
                                     diagonal=blocks)
        warm_box[0] = None
        counts[0] += it
        counts[1] += int(direct)
        return d.reshape(-1, 3)

    start = feasible_start(contact, x0, h * v_free, pinned)
    dx, it, _ = minimize_with_contact(start, q_value, q_gradient, solve, contact, x0, h,
                                      pinned, tol=tol, max_iter=max_iter,
                                      decrement_tol=float(system.masses[~pinned].sum()) * tol * tol)
    dx[pinned] = 0.0
    return dx, it, counts[0], counts[1]


def apply_explicit_contact(system: ImplicitSystem, state: State, x0: np.ndarray,
                           dx_free: np.ndarray, h: float, contact: ContactModel, tol: float) -> int:
    """Correct an explicit step for contacts (:func:`explicit_contact`), in place:
    ``x = x0 + dx_free + c``, ``v += c / h``; particles without contact keep their bits.
    Returns the Newton iterations."""
    c, it = explicit_contact(system.masses, system.pinned, x0, dx_free, h, contact, tol=tol)
    if c is None:
        return 0
    moved = np.any(c != 0.0, axis=1)
    state.positions[moved] = x0[moved] + dx_free[moved] + c[moved]
    state.velocities[moved] += c[moved] / h
    return it


@njit(cache=True)
def step_kinetic_energy(dx, masses, h):
    """Kinetic energy ``sum m |dx / h|^2 / 2`` (J) of a step ``dx`` (N, 3) of ``h`` (s)."""
    acc = 0.0
    for i in range(dx.shape[0]):
        acc += masses[i] * (dx[i, 0] * dx[i, 0] + dx[i, 1] * dx[i, 1] + dx[i, 2] * dx[i, 2])
    return 0.5 * acc / (h * h)
