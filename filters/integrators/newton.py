"""Backward Euler by Newton's method with a line search on the incremental potential."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from ..contact_solve import feasible_start, step_kinetic_energy
from ..linalg.cg import vdot
from ..validation import check_int, check_range
from .common import StepInfo, check_h, linear_solver, store_warm_start, warm_start

if TYPE_CHECKING:
    from collections.abc import Callable

    from ..elastic.contact_model import ContactModel
    from ..linalg.protocol import ImplicitSystem
    from ..linalg.solver import LinearSolver
    from ..simulation import State

__all__ = ["backward_euler", "NEWTON_RTOL"]

#: Loosest relative PCG tolerance of a Newton solve as a multiple of ``tol_k / |d_prev|``, with
#: ``tol_k`` the step's stopping tolerance (see :func:`backward_euler`).
_STEP_FORCING = 0.3

#: Default relative Newton tolerance: the Newton step must fall below this fraction of the
#: step's velocity change ``max |dx / h - v|``.
NEWTON_RTOL = 1e-2

#: Absolute floor (m/s) of the relative tolerance, as a fraction of ``newton_tol``: a step that
#: changes no velocity (a body at rest) converges once the Newton step is below it.
_FLOOR = 1e-6


@njit(cache=True)
def _norm(g):
    """The 2-norm of an (N, 3) array, scaled by its largest entry so that no square underflows
    or overflows (a state of 1e-200 has a norm of 1e-200, not 0)."""
    top = 0.0
    for i in range(g.shape[0]):
        for k in range(3):
            top = max(top, abs(g[i, k]))
    if top == 0.0 or not math.isfinite(top):
        return top
    acc = 0.0
    for i in range(g.shape[0]):
        for k in range(3):
            t = g[i, k] / top
            acc += t * t
    return top * math.sqrt(acc)


@njit(cache=True)
def _max_abs_diff(dx, v, h):
    """``max |dx / h - v|`` (m/s) over all entries of two (N, 3) arrays: the velocity change of
    the step ``dx`` from velocities ``v``."""
    acc = 0.0
    for i in range(dx.shape[0]):
        for k in range(3):
            t = abs(dx[i, k] / h - v[i, k])
            if t > acc:
                acc = t
    return acc


@njit(cache=True)
def _incremental_potential_parts(dx, v, masses, h):
    # serial: a parallel reduction over a few thousand particles cost ~6 ms on the busy machine
    acc = 0.0
    for i in range(dx.shape[0]):
        for k in range(3):
            t = dx[i, k] - h * v[i, k]
            acc += masses[i] * t * t
    return 0.5 * acc / (h * h)


def backward_euler(system: ImplicitSystem, state: State, h: float, *,
                   solver: str | LinearSolver = "auto", newton_tol: float = 1e-3,
                   newton_rtol: float = NEWTON_RTOL, max_newton: int = 20, tol: float = 1e-3,
                   max_iter: int = 1000,
                   callback: Callable[[int, float, float], object] | None = None,
                   preconditioner: str | None = None, forcing: float = 0.1,
                   extrapolate: bool = False, omega: float | None = None,
                   contact: ContactModel | None = None) -> StepInfo:
    """Backward Euler by Newton iterations with a line search on the incremental potential.

    Minimises ``E(dx) = |dx - h v|_M^2/(2h^2) + U(x + dx) + dx^T C dx/(2h)`` over the position
    increment ``dx`` (Gast et al. 2015), with ``U`` the elastic plus gravitational potential and
    ``C`` the damping matrix with directions frozen at the start of the step.  Newton directions
    solve ``(M/h^2 + K(x + dx) + C/h) d = -grad E`` with ``K`` made definite, so every ``d`` is a
    descent direction; a backtracking (Armijo) line search accepts only decreases of ``E``.
    Then ``v = dx / h``, ``x += dx``.  Newton stops on a tolerance that is absolute *and*
    relative to the step's own velocity change, so the result is the backward Euler step to a
    fraction of the scheme's own change per step, at any ``h``: first order, and, since the
    exact minimiser of ``E`` does not gain energy for convex potentials (Gast et al. 2015), an
    energy within that tolerance of exact backward Euler's.

    Parameters
    ----------
    system, state, h
        As in :func:`filters.integrators.euler`.
    solver : {"auto", "pcg", "direct"} or LinearSolver
        Linear solver for the Newton directions (see :mod:`filters.linalg.solver`); a
        :class:`LinearSolver` object keeps its scratch arrays between steps.
    newton_tol : float
        Absolute Newton tolerance (m/s), > 0: Newton stops when the full Newton step
        ``max |d| / h`` is below ``tol_k = min(newton_tol, newton_rtol max |dx / h - v|)``
        (the second term the step's velocity change at the current iterate, floored at
        ``1e-6 newton_tol`` for a step that changes nothing) -- with contacts, when also the
        Newton decrement ``-g . d`` is below the kinetic energy ``M newton_tol^2`` of the whole
        system moving at that speed (J), since a stiff barrier can hold much energy in a small
        step --, or when two full steps converge quadratically (``|d_k| < |d_{k-1}| / 4``) and
        the next step, estimated as ``|d_k|^2 / |d_{k-1}|``, would be below ``tol_k / 2``.
    newton_rtol : float
        Relative Newton tolerance, in (0, 1): the Newton step must be below this fraction of the
        step's velocity change.  An absolute tolerance alone is met after one iteration once
        ``h`` is small (the whole velocity change falls below it) and turns backward Euler into
        a different, inexact scheme (with the loose first solve, one that gains energy).
    max_newton : int
        Newton iteration limit.
    tol, max_iter : float, int
        PCG relative tolerance (inexact Newton) and iteration limit per solve.  With
        ``forcing``, ``tol`` is the tightest tolerance the forcing sequence may ask for.
    callback : callable, optional
        Called after every Newton iteration as ``callback(iteration, step_norm, potential)``.
    preconditioner : {"ssor", "block_jacobi", "sgs"}, optional
        Preconditioner of the matrix-free PCG (only with a solver given by name): block
        symmetric successive over-relaxation with Eisenstat's trick (the default: on the 64x64
        benchmark cloth about 3x fewer iterations than block Jacobi at ~2x the cost per
        iteration), per-particle 3x3 block Jacobi, or block symmetric Gauss-Seidel applied
        separately from the product; see ``benchmarks/results/springs.json``.
    forcing : float or None
        Largest relative PCG tolerance of the inexact Newton iterations: the first solve uses
        ``forcing``, later ones the Eisenstat & Walker (1996, "Choosing the forcing terms in an
        inexact Newton method", SIAM J. Sci. Comput.) choice 2,
        ``eta_k = 0.9 (|g_k| / |g_{k-1}|)^2`` (safeguarded), clipped to ``[tol, forcing]``.
        Far from the solution the solve is loose, near it as tight as ``tol`` -- but never
        tighter than ``0.3 tol_k / |d_prev|`` (``|d_prev|`` the previous Newton step,
        ``max |d| / h``): once the steps approach ``tol_k`` the last direction only has to be
        accurate to a fraction of it (Newton steps shrink).  The loose solves are safe because
        the stopping test is relative: a direction (or the warm start of PCG, accepted when its
        true residual is below ``eta_k``) that is 10 % off leaves a next Newton step of ~10 %
        of this one, and Newton goes on.  ``None``: every solve to ``tol``.
    extrapolate : bool
        Also try the start ``dx = h (v + dv_prev)`` (the previous step's velocity change, kept in
        ``state.extra["newton_dv"]``) and keep it if it has the lowest incremental potential.
    omega : float, optional
        Over-relaxation factor of ``"ssor"``, in (0, 2) (default
        :data:`filters.linalg.DEFAULT_OMEGA`; only with a solver given by name).
    contact : contact model, optional
        Contacts and friction (:class:`filters.elastic.contact_model.ContactModel`): their
        barrier, friction and normal-damping terms join ``E`` and their Hessian blocks the
        Newton matrix, and the line search never lets a contact point cross a collider, so
        that the step that lowers ``E`` also satisfies the contacts.  Newton then also stops
        only on a step that gains no energy; if ``max_newton`` iterations leave one that
        does, its velocities are scaled back to the energy of the start of the step
        (:attr:`StepInfo.velocity_scale`).

    Returns
    -------
    StepInfo
    """
    h = check_h(h)
    check_range("newton_tol", newton_tol, 0.0, math.inf, low_inclusive=False)
    check_range("newton_rtol", newton_rtol, 0.0, 1.0, low_inclusive=False, high_inclusive=False)
    if forcing is not None:
        check_range("forcing", forcing, 0.0, 1.0, low_inclusive=False, high_inclusive=False)
    check_int("max_newton", max_newton, 1)
    check_range("tol", tol, 0.0, 1.0, low_inclusive=False, high_inclusive=False)
    check_int("max_iter", max_iter, 1)
    linear = linear_solver(solver, preconditioner, omega)
    x0, v = state.positions, state.velocities
    n = x0.shape[0]
    m = system.masses
    pinned = system.pinned
    free = ~pinned
    floor = _FLOOR * newton_tol

    def potential(dx):
        e = _incremental_potential_parts(dx, v_free, m, h)
        e += system.potential_energy(x0 + dx)
        e -= 0.5 / h * vdot(dx, system.damping_forces(x0, dx))
        if contact is not None:
            e += contact.value(x0, dx)
        return e

    def gradient(dx):
        g = m[:, None] * (dx - h * v_free) / (h * h)
        g -= system.conservative_forces(x0 + dx)
        g -= system.damping_forces(x0, dx) / h
        g[pinned] = 0.0
        return g

    def tolerance(dx):
        """The stopping tolerance (m/s) at the iterate ``dx``."""
        return min(newton_tol, max(newton_rtol * _max_abs_diff(dx, v_free, h), floor))

    v_free = v.copy()
    v_free[pinned] = 0.0
    blocks = None
    if contact is not None:
        contact.begin_step(x0, h)
        blocks = np.zeros((n, 3, 3))
        # the kinetic energy of the whole system moving at newton_tol, twice
        decrement_tol = float(m[free].sum()) * newton_tol * newton_tol
    # Start from the better of the inertial guess h v and the free-fall guess h v + h^2 g
    # (with contacts: each brought back, particle by particle, to where no contact point crosses
    # a collider, and standing still as a third guess).
    def start(guess):
        return guess if contact is None else feasible_start(contact, x0, guess, pinned)

    dx = start(h * v_free)
    e = potential(dx)
    trial = start(h * v_free + (h * h) * np.where(free[:, None], system.gravity[None, :], 0.0))
    e_trial = potential(trial)
    if e_trial < e:
        dx, e = trial, e_trial
    if contact is not None:
        # standing still: E(0) is the energy at the start of the step
        trial = np.zeros_like(dx)
        e_before = e_trial = potential(trial)
        if e_trial < e:
            dx, e = trial, e_trial

        def total_energy(dx):
            """Kinetic + potential + contact energy (J) after the step ``dx``."""
            x1 = x0 + dx
            return (step_kinetic_energy(dx, m, h) + system.potential_energy(x1)
                    + contact.energy(x1))

        def gains(dx):
            return total_energy(dx) > e_before + decrement_tol
    dv_prev = warm_start(state, "newton_dv", 3 * n) if extrapolate else None
    if dv_prev is not None:
        trial = h * (v_free + dv_prev.reshape(n, 3))
        trial[pinned] = 0.0
        trial = start(trial)
        e_trial = potential(trial)
        if e_trial < e:
            dx, e = trial, e_trial
    info = StepInfo()
    warm = warm_start(state, "newton_warm", 3 * n)
    first_direction = None
    eta = tol if forcing is None else max(tol, forcing)
    gnorm_prev = 0.0
    prev_step = 0.0
    full_before = False
    for it in range(max_newton):
        g = gradient(dx)
        points = None
        if contact is not None:
            contact.derivatives(x0, dx, g, blocks)
            g[pinned] = 0.0
            # embedded contact points: their exact Hessian blocks W^T H W, not the diagonal
            # bound (with which Newton converged linearly, at 0.97 per iteration on a landing
            # jello)
            points = contact.point_hessians()
        gnorm = _norm(g)
        if not gnorm > 0.0:
            break  # the exact minimiser (a body at rest with nothing acting, or round-off)
        tol_k = tolerance(dx)
        if forcing is not None and gnorm_prev > 0.0:
            # Eisenstat & Walker (1996), choice 2 (gamma = 0.9, alpha = 2) with safeguard
            eta_new = 0.9 * (gnorm / gnorm_prev) ** 2
            if 0.9 * eta * eta > 0.1:
                eta_new = max(eta_new, 0.9 * eta * eta)
            eta = min(max(forcing, tol), max(eta_new, tol))
            if prev_step > 0.0:
                # Near convergence the step only has to be accurate to a fraction of tol_k
                # (Newton steps shrink, so |d_k| <= |d_{k-1}|): no tighter than that.
                eta = max(eta, min(forcing, _STEP_FORCING * tol_k / prev_step))
        gnorm_prev = gnorm
        d, lin_it, direct = linear.solve(system, x0 + dx, x0, h, -g, warm, eta, max_iter,
                                         diagonal=blocks, points=points)
        info.linear_iterations += lin_it
        info.direct_solves += int(direct)
        info.newton_iterations = it + 1
        d = d.reshape(n, 3)
        d[pinned] = 0.0
        if first_direction is None:
            first_direction = d.copy()
        warm = None
        slope = vdot(g, d)
        step_norm = float(np.abs(d).max()) / h if d.size else 0.0
        older_step, prev_step = prev_step, step_norm
        info.residual = step_norm
        underflow = slope == 0.0 and step_norm > 0.0
        if slope > 0.0 or (slope == 0.0 and not underflow):
            # not a descent direction (inexact solve): steepest descent instead
            d = -g / (m[:, None] / (h * h))
            d[pinned] = 0.0
            slope = vdot(g, d)
        # with contacts, the longest step that keeps every contact point outside (Li et al.
        # 2020's filtered line search)
        alpha = 1.0 if contact is None else contact.max_step(x0, dx, d)
        accepted = False
        if underflow:
            # a state so small (~1e-160) that g . d and E underflow to zero: the line search
            # cannot judge, the direction (a solve at unit scale) is taken as it is
            trial = dx + alpha * d
            e_trial = potential(trial)
            accepted = True
        for _ in range(0 if underflow else 40 if contact is None else 60):
            trial = dx + alpha * d
            e_trial = potential(trial)
            if e_trial <= e + 1e-4 * alpha * slope:
                accepted = True
                break
            alpha *= 0.5
            info.line_search_halvings += 1
        if not accepted:
            break  # no decrease possible: converged to round-off
        dx, e = trial, e_trial
        if callback is not None:
            callback(it, step_norm * alpha, e)
        tol_k = tolerance(dx)
        small = step_norm <= tol_k  # the full Newton step, whatever the line search took
        if contact is None:
            if small:
                break
        elif small and -slope < decrement_tol and not gains(dx):
            # converged: the full step is small, so is the Newton decrement g . H^-1 g (twice
            # the decrease left to the minimum), and the step gains no energy
            break
        if alpha == 1.0 and full_before and older_step > 0.0 and (
                step_norm < 0.25 * older_step) and (
                step_norm * step_norm / older_step < 0.5 * tol_k) and (
                contact is None or not gains(dx)):
            # Quadratic convergence (two full steps, contraction < 1/4): the next step would be
            # ~ |d_k|^2 / |d_{k-1}|, well below tol_k (Deuflhard 2004, "Newton methods for
            # nonlinear problems"): skip the solve that would only confirm it.
            info.residual = step_norm * step_norm / older_step
            break
        full_before = alpha == 1.0
    if first_direction is not None:
        store_warm_start(state, "newton_warm", first_direction)
    if extrapolate:
        dv = dx / h - v_free
        dv[pinned] = 0.0
        store_warm_start(state, "newton_dv", dv)
    scale = 1.0
    if contact is not None and gains(dx):
        # Newton stopped (max_newton) short of a minimiser that would not gain energy: keep
        # the positions, take from the velocities what the step gained (the energy budget of
        # Dinev, Liu & Kavan 2018, "Stabilizing integrators for real-time physics", TOG)
        kinetic = step_kinetic_energy(dx, m, h)
        budget = e_before - (total_energy(dx) - kinetic)
        scale = math.sqrt(budget / kinetic) if budget > 0.0 and kinetic > 0.0 else 0.0
        info.velocity_scale = scale
    x0 += dx
    v[:] = dx / h
    if scale != 1.0:
        v *= scale
    v[pinned] = 0.0
    return info
