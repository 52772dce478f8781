"""Time integrators for particle systems: explicit, symplectic, linearised and full backward Euler.

Every scheme has the same shape::

    info = scheme(system, state, h, **options)

``system`` is an :class:`filters.linalg.ImplicitSystem` (forces, energies and the implicit
system matrix; e.g. :class:`filters.elastic.springs.SpringSystem`); ``state`` has
``positions`` and ``velocities`` (N, 3) float64 arrays and an ``extra`` dict (a
:class:`filters.simulation.State`), advanced by one step ``h`` (s) **in place**; ``extra`` keeps
the warm start of the iterative solver, so that a checkpointed state resumes bit-identically.
Each scheme returns a :class:`StepInfo`. The linear algebra is :mod:`filters.linalg`.

**Schemes** (the names of :data:`SCHEMES`; the advection of :mod:`filters.advect` uses the
same vocabulary, plus ``"rk2"`` and ``"rk4"``):

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

  whose minimiser is the backward Euler step, which for convex potentials does not gain
  energy; every accepted iterate lowers ``E``, and Newton stops on a tolerance both absolute
  and relative to the step's velocity change, so the result is that step to a fraction of the
  scheme's own change at any ``h`` (first order down to ``h = T/3200`` on an oscillator, the
  energy of exact backward Euler to 1 % on a stiff pendulum).  Axial damping directions are
  frozen at the start of the step so that the damping term is a true (quadratic) dissipation
  potential.  The robust default.  The linear solves are inexact, with an Eisenstat & Walker
  (1996) forcing sequence.
* :func:`implicit_advection` -- the first-order form for particles advected by a velocity field
  ``dx/dt = v(x)``: ``(I - h dv/dx) dx = h v(x^n)`` (one linearised backward Euler step).

Contacts (``contact=``, a :class:`filters.elastic.contact_model.ContactModel` or any object
with its methods) are part of every scheme's step, not a pass after it: each step minimises its
own part plus the contact terms -- barrier, lagged Coulomb friction, normal damping -- over a
feasibility-filtered line search (:mod:`filters.contact_solve`), so that any
:class:`~filters.linalg.ImplicitSystem` gets contacts that can only remove energy.

Earlier names (``"forward"``, ``"symplectic"``, ``"linearized"``, ``"newton"``) raise a
``ValueError`` naming the current one.

Modules: :mod:`~filters.integrators.common` (:class:`StepInfo`, warm starts),
:mod:`~filters.integrators.explicit`, :mod:`~filters.integrators.linearized`,
:mod:`~filters.integrators.newton` (backward Euler), :mod:`~filters.integrators.advection`
(the velocity-field form), :mod:`~filters.integrators.registry` (names and :func:`integrate`).
"""

from __future__ import annotations

from ..linalg.solver import SOLVERS
from .advection import implicit_advection
from .common import StepInfo
from .explicit import euler, symplectic_euler
from .linearized import linearized_backward_euler
from .newton import backward_euler
from .registry import SCHEMES, check_scheme, integrate

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
