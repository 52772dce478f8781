"""Time integrators for particle systems: explicit, symplectic, linearised and full backward Euler.

Every scheme has the same shape::

    info = scheme(system, state, h, **options)

``system`` is an :class:`filters.linalg.ImplicitSystem` (forces, energies and the implicit
system matrix; e.g. :class:`filters.elastic.springs.SpringSystem`); ``state`` has
``positions`` and ``velocities`` (N, 3) float64 arrays and an ``extra`` dict (a
:class:`filters.simulation.State`), advanced by one step ``h`` (s) **in place**; ``extra`` keeps
the warm start of the iterative solver, so that a checkpointed state resumes bit-identically.
Each scheme returns a :class:`StepInfo`. The linear algebra is :mod:`filters.linalg`.

Schemes (the names of :data:`SCHEMES`; the advection of :mod:`filters.advect` uses the same
vocabulary, plus ``"rk2"`` and ``"rk4"``)
--------------------------------------------------------------------------------------------
* ``"euler"``, :func:`euler` -- forward Euler: ``x += h v; v += h f(x, v) / m``.  Energy of an
  undamped oscillator grows by ``(1 + h^2 w^2)`` per step.
* ``"symplectic_euler"``, :func:`symplectic_euler` -- ``v += h f(x, v) / m; x += h v``.  Bounded
  energy error, unstable for ``h w > 2``.
* ``"linearized_backward_euler"``, :func:`linearized_backward_euler` -- one Newton step of
  backward Euler (Baraff & Witkin 1998, "Large steps in cloth simulation"):
  ``(M - h df/dv - h^2 df/dx) dv = h (f0 + h df/dx v0)``.
* ``"backward_euler"``, :func:`backward_euler` -- backward Euler solved by Newton's method with a
  backtracking line search on the incremental potential (Gast, Schroeder, Stomakhin, Jiang &
  Teran 2015, "Optimization integrator for large time steps", IEEE TVCG)::

      E(dx) = |dx - h v|_M^2 / (2 h^2) + U(x + dx) + dx^T C dx / (2 h)

  whose minimiser is the backward Euler step; every accepted iterate lowers ``E``, so the step
  cannot gain energy.  Axial damping directions are frozen at the start of the step so that the
  damping term is a true (quadratic) dissipation potential.  The robust default.
  :func:`backward_euler` solves inexactly with an Eisenstat & Walker (1996) forcing sequence.
* :func:`implicit_advection` -- the first-order form for particles advected by a velocity field
  ``dx/dt = v(x)``: ``(I - h dv/dx) dx = h v(x^n)`` (one linearised backward Euler step).

Contacts (``contact=``, a :class:`filters.elastic.contact_model.ContactModel` or any object
with its methods) are part of every scheme's step, not a pass after it: each step minimises its
own part plus the contact terms -- barrier, lagged Coulomb friction, normal damping -- over a
feasibility-filtered line search (:mod:`filters.contact_solve`), so that any
:class:`~filters.linalg.ImplicitSystem` gets contacts that can only remove energy.

Earlier names (``"forward"``, ``"symplectic"``, ``"linearized"``, ``"newton"``) raise a
``ValueError`` naming the current one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from .contact_solve import (apply_explicit_contact, feasible_start, linearized_contact,
                            step_kinetic_energy)
from .linalg.cg import vdot
from .linalg.dense3 import implicit_step3
from .linalg.solver import SOLVERS, LinearSolver
from .validation import check_int, check_points, check_range

__all__ = [
    "StepInfo",
    "SCHEMES",
    "SOLVERS",
    "euler",
    "symplectic_euler",
    "linearized_backward_euler",
    "backward_euler",
    "implicit_advection",
    "integrate",
    "check_scheme",
]


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
#: (see :func:`backward_euler`).
_STEP_FORCING = 0.3


def _check_h(h):
    return check_range("h", h, 0.0, math.inf, low_inclusive=False)


def _linear_solver(solver, preconditioner, omega) -> LinearSolver:
    """A :class:`LinearSolver`: the one given, or a new one for a method name."""
    if isinstance(solver, LinearSolver):
        if preconditioner is not None or omega is not None:
            raise ValueError("preconditioner and omega belong to the LinearSolver given as "
                             "solver; pass them to it")
        return solver
    options = {} if omega is None else {"omega": omega}
    return LinearSolver(solver, preconditioner=preconditioner or "ssor", **options)


def _warm(state, key, n):
    extra = state.extra
    if key in extra and extra[key].size == n:
        return np.array(extra[key], dtype=np.float64).ravel()
    return None


def _store_warm(state, key, value):
    state.extra[key] = value.reshape(-1, 3).copy()


@njit(cache=True)
def _incremental_potential_parts(dx, v, masses, h):
    # serial: a parallel reduction over a few thousand particles cost ~6 ms on the busy machine
    acc = 0.0
    for i in range(dx.shape[0]):
        for k in range(3):
            t = dx[i, k] - h * v[i, k]
            acc += masses[i] * t * t
    return 0.5 * acc / (h * h)


# ---------------------------------------------------------------------------------------------
# Explicit schemes
# ---------------------------------------------------------------------------------------------
def euler(system, state, h, *, contact=None, contact_tol=1e-4):
    """Forward (explicit) Euler: ``x += h v; v += h f(x, v) / m``, in place.

    Parameters
    ----------
    system : ImplicitSystem
        Supplies ``forces(x, v)`` (N) and ``inv_mass`` (1/kg, 0 for pinned particles).
    state : State
        ``positions`` (m) and ``velocities`` (m/s), (N, 3), advanced in place.
    h : float
        Time step (s), > 0.
    contact : contact model, optional
        Contacts and friction (:class:`filters.elastic.contact_model.ContactModel`), solved
        after the explicit update as the smallest momentum change that satisfies them
        (:func:`filters.contact_solve.explicit_contact`).
    contact_tol : float
        Newton tolerance (m/s) of that contact solve, > 0.

    Returns
    -------
    StepInfo
    """
    h = _check_h(h)
    x, v = state.positions, state.velocities
    f = system.forces(x, v)
    x0 = x.copy() if contact is not None else None
    x += h * v
    dx_free = h * v if contact is not None else None
    v += h * f * system.inv_mass[:, None]
    if contact is None:
        return StepInfo()
    contact.begin_step(x0, h)
    return StepInfo(newton_iterations=apply_explicit_contact(system, state, x0, dx_free, h,
                                                            contact, contact_tol))


def symplectic_euler(system, state, h, *, contact=None, contact_tol=1e-4):
    """Symplectic (semi-implicit) Euler: ``v += h f(x, v) / m; x += h v``, in place, by the
    system's :meth:`~filters.linalg.ImplicitSystem.symplectic_step`; ``contact`` and the other
    arguments as in :func:`euler`."""
    h = _check_h(h)
    if contact is None:
        system.symplectic_step(state.positions, state.velocities, h)
        return StepInfo()
    x0 = state.positions.copy()
    system.symplectic_step(state.positions, state.velocities, h)
    contact.begin_step(x0, h)
    dx_free = h * state.velocities
    return StepInfo(newton_iterations=apply_explicit_contact(system, state, x0, dx_free, h,
                                                            contact, contact_tol))


# ---------------------------------------------------------------------------------------------
# Implicit schemes
# ---------------------------------------------------------------------------------------------
def linearized_backward_euler(system, state, h, *, solver="auto", tol=1e-6, max_iter=1000,
                              preconditioner=None, omega=None, contact=None, contact_tol=1e-3,
                              max_contact_iterations=20):
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
    h = _check_h(h)
    linear = _linear_solver(solver, preconditioner, omega)
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
    dv, it, direct = linear.solve(system, x, x, h, rhs, _warm(state, "lbe_warm", 3 * n), tol,
                                  max_iter)
    _store_warm(state, "lbe_warm", dv)
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
        lin_tol=tol, lin_max_iter=max_iter, warm=_warm(state, "lbe_contact_warm", v.size))
    _store_warm(state, "lbe_contact_warm", dx - h * np.where(system.pinned[:, None], 0.0, v))
    x += dx
    v[:] = dx / h
    v[system.pinned] = 0.0
    return StepInfo(newton_iterations=it, linear_iterations=lin_it, direct_solves=direct)


def backward_euler(system, state, h, *, solver="auto", newton_tol=1e-3, max_newton=20,
                   tol=1e-3, max_iter=1000, callback=None, preconditioner=None,
                   forcing=0.1, extrapolate=False, omega=None, contact=None):
    """Backward Euler by Newton iterations with a line search on the incremental potential.

    Minimises ``E(dx) = |dx - h v|_M^2/(2h^2) + U(x + dx) + dx^T C dx/(2h)`` over the position
    increment ``dx`` (Gast et al. 2015), with ``U`` the elastic plus gravitational potential and
    ``C`` the damping matrix with directions frozen at the start of the step.  Newton directions
    solve ``(M/h^2 + K(x + dx) + C/h) d = -grad E`` with ``K`` made definite, so every ``d`` is a
    descent direction; a backtracking (Armijo) line search accepts only decreases of ``E``.
    Then ``v = dx / h``, ``x += dx``.

    Parameters
    ----------
    system, state, h
        As in :func:`forward_euler`.
    solver : {"auto", "pcg", "direct"} or LinearSolver
        Linear solver for the Newton directions (see :mod:`filters.linalg.solver`); a
        :class:`LinearSolver` object keeps its scratch arrays between steps.
    newton_tol : float
        Stop when ``max |d| / h`` (m/s) falls below this (1 mm/s by default: well below what
        an animation shows, and 2x fewer Newton iterations than 1e-5 on the benchmark cloth)
        -- with contacts, when also the Newton decrement ``-g . d`` is below the kinetic
        energy ``M newton_tol^2`` of the whole system moving at that speed (J), since a stiff
        barrier can hold much energy in a small step --,
        or when two full steps converge quadratically (``|d_k| < |d_{k-1}| / 4``) and the
        next step, estimated as ``|d_k|^2 / |d_{k-1}|``, would be below ``newton_tol / 2``
        (3.17 -> 2.75 Newton iterations per step on the 64x64 benchmark cloth).
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
        benchmark cloth 3.3x fewer iterations than block Jacobi at ~2x the cost per
        iteration, 10.5 instead of 16.0 ms per step), per-particle 3x3 block Jacobi, or block
        symmetric Gauss-Seidel applied separately from the product (2.4x fewer iterations than
        block Jacobi but ~2.5x the cost per iteration); see ``benchmarks/results/springs.json``.
    forcing : float or None
        Largest relative PCG tolerance of the inexact Newton iterations: the first solve uses
        ``forcing``, later ones the Eisenstat & Walker (1996, "Choosing the forcing terms in an
        inexact Newton method", SIAM J. Sci. Comput.) choice 2,
        ``eta_k = 0.9 (|g_k| / |g_{k-1}|)^2`` (safeguarded), clipped to ``[tol, forcing]``.
        Far from the solution the solve is loose, near it as tight as ``tol`` -- but never
        tighter than ``0.3 newton_tol / |d_prev|`` (``|d_prev|`` the previous Newton step,
        ``max |d| / h``): once the steps approach ``newton_tol`` the last direction only has to
        be accurate to a fraction of it (Newton steps shrink).  This floor cut the PCG
        iterations of the 64x64 benchmark cloth from 28 to 21 per step with the same Newton
        iterations.  ``None``: every solve to ``tol`` (the fixed-tolerance behaviour).
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
    h = _check_h(h)
    check_range("newton_tol", newton_tol, 0.0, math.inf, low_inclusive=False)
    if forcing is not None:
        check_range("forcing", forcing, 0.0, 1.0, low_inclusive=False, high_inclusive=False)
    check_int("max_newton", max_newton, 1)
    check_range("tol", tol, 0.0, 1.0, low_inclusive=False, high_inclusive=False)
    check_int("max_iter", max_iter, 1)
    linear = _linear_solver(solver, preconditioner, omega)
    x0, v = state.positions, state.velocities
    n = x0.shape[0]
    m = system.masses
    pinned = system.pinned
    free = ~pinned

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
    dv_prev = _warm(state, "newton_dv", 3 * n) if extrapolate else None
    if dv_prev is not None:
        trial = h * (v_free + dv_prev.reshape(n, 3))
        trial[pinned] = 0.0
        trial = start(trial)
        e_trial = potential(trial)
        if e_trial < e:
            dx, e = trial, e_trial
    info = StepInfo()
    warm = _warm(state, "newton_warm", 3 * n)
    first_direction = None
    eta = tol if forcing is None else max(tol, forcing)
    gnorm_prev = None
    prev_step = 0.0
    full_before = False
    for it in range(max_newton):
        g = gradient(dx)
        if contact is not None:
            contact.derivatives(x0, dx, g, blocks)
            g[pinned] = 0.0
        gnorm = math.sqrt(vdot(g, g))
        if forcing is not None and gnorm_prev is not None:
            # Eisenstat & Walker (1996), choice 2 (gamma = 0.9, alpha = 2) with safeguard
            eta_new = 0.9 * (gnorm / gnorm_prev) ** 2
            if 0.9 * eta * eta > 0.1:
                eta_new = max(eta_new, 0.9 * eta * eta)
            eta = min(max(forcing, tol), max(eta_new, tol))
            if prev_step > 0.0:
                # Near convergence the step only has to be accurate to a fraction of newton_tol
                # (Newton steps shrink, so |d_k| <= |d_{k-1}|): no tighter than that.
                eta = max(eta, min(forcing, _STEP_FORCING * newton_tol / prev_step))
        gnorm_prev = gnorm
        d, lin_it, direct = linear.solve(system, x0 + dx, x0, h, -g, warm, eta, max_iter,
                                         diagonal=blocks)
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
        if slope >= 0.0:  # not a descent direction (inexact solve): steepest descent instead
            d = -g / (m[:, None] / (h * h))
            slope = vdot(g, d)
        # with contacts, the longest step that keeps every contact point outside (Li et al.
        # 2020's filtered line search)
        alpha = 1.0 if contact is None else contact.max_step(x0, dx, d)
        accepted = False
        for _ in range(40 if contact is None else 60):
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
        if contact is None:
            if step_norm * alpha < newton_tol:
                break
        elif step_norm < newton_tol and -slope < decrement_tol and not gains(dx):
            # converged: the full step is small, so is the Newton decrement g . H^-1 g (twice
            # the decrease left to the minimum), and the step gains no energy
            break
        if alpha == 1.0 and full_before and step_norm < 0.25 * older_step and (
                step_norm * step_norm / older_step < 0.5 * newton_tol) and (
                contact is None or not gains(dx)):
            # Quadratic convergence (two full steps, contraction < 1/4): the next step would be
            # ~ |d_k|^2 / |d_{k-1}|, well below newton_tol (Deuflhard 2004, "Newton methods
            # for nonlinear problems"): skip the solve that would only confirm it.
            info.residual = step_norm * step_norm / older_step
            break
        full_before = alpha == 1.0
    if first_direction is not None:
        _store_warm(state, "newton_warm", first_direction)
    if extrapolate:
        dv = dx / h - v_free
        dv[pinned] = 0.0
        _store_warm(state, "newton_dv", dv)
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


# ---------------------------------------------------------------------------------------------
# First-order (velocity field) form
# ---------------------------------------------------------------------------------------------
@njit(parallel=True, cache=True)
def _implicit_advection(x, v, jac, h, out):
    """New positions ``out`` (N, 3); returns the number of singular particles."""
    bad = 0
    for i in prange(v.shape[0]):
        out[i, 0], out[i, 1], out[i, 2], det = implicit_step3(
            jac[i], h, x[i, 0], x[i, 1], x[i, 2], v[i, 0], v[i, 1], v[i, 2])
        if not (abs(det) > 1e-12):
            bad += 1
    return bad


def implicit_advection(positions, velocity, jacobian, h):
    """Linearised backward Euler for particles in a velocity field ``dx/dt = v(x)``.

    Solves ``(I - h dv/dx) dx = h v(x^n)`` per particle by Cramer's rule (the solve of
    :class:`filters.advect.NoiseAdvection`'s ``"linearized_backward_euler"``,
    :func:`filters.linalg.dense3.implicit_step3`).  For a linear
    field ``v = A x`` this is exactly backward Euler, ``x^{n+1} = (I - h A)^{-1} x^n``.

    Parameters
    ----------
    positions : (N, 3) array_like
        Particle positions ``x^n`` (m).
    velocity : (N, 3) array_like
        Field velocity ``v(x^n)`` (m/s) at the particles.
    jacobian : (N, 3, 3) array_like
        Field gradient ``dv/dx`` (1/s) at the particles, ``jacobian[i, p, q] = dv_p/dx_q``.
    h : float
        Time step (s), > 0.

    Returns
    -------
    (N, 3) float64 array
        New positions ``x^n + dx`` (m).

    Raises
    ------
    ValueError
        If ``I - h dv/dx`` is singular for some particle, or shapes disagree.
    """
    x = check_points("positions", positions)
    v = check_points("velocity", velocity)
    jac = np.ascontiguousarray(jacobian, dtype=np.float64)
    if v.shape != x.shape or jac.shape != (x.shape[0], 3, 3):
        raise ValueError("velocity must be (N, 3) and jacobian (N, 3, 3) with N = len(positions)")
    h = _check_h(h)
    out = np.empty_like(x)
    if _implicit_advection(x, v, jac, h, out):
        raise ValueError("I - h dv/dx is singular for some particle: reduce h")
    return out


# ---------------------------------------------------------------------------------------------
SCHEMES = {
    "euler": euler,
    "symplectic_euler": symplectic_euler,
    "linearized_backward_euler": linearized_backward_euler,
    "backward_euler": backward_euler,
}

#: Earlier scheme names, refused with the current one in the message.
_RENAMED = {"forward": "euler", "symplectic": "symplectic_euler",
            "linearized": "linearized_backward_euler", "newton": "backward_euler"}


def check_scheme(name: str, choices=tuple(SCHEMES), what: str = "scheme") -> str:
    """Return ``name`` if it is one of ``choices``; a former name gets a message naming the
    current one."""
    if name in _RENAMED and name not in choices:
        raise ValueError(f"{what} {name!r} is now called {_RENAMED[name]!r}; {what} must be "
                         f"one of {', '.join(map(repr, choices))}")
    if name not in choices:
        raise ValueError(f"{what} must be one of {', '.join(map(repr, choices))}; got {name!r}")
    return name


def integrate(system, state, h, scheme="backward_euler", **options):
    """Advance ``state`` by one step with the named scheme.

    Parameters
    ----------
    system, state, h
        As in :func:`euler`.
    scheme : {"euler", "symplectic_euler", "linearized_backward_euler", "backward_euler"}
        Integration scheme.
    **options
        Passed to the scheme (solver options of the implicit ones).

    Returns
    -------
    StepInfo
    """
    check_scheme(scheme)
    return SCHEMES[scheme](system, state, h, **options)
