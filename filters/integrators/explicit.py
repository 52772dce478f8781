"""Explicit schemes: forward Euler and symplectic Euler, with contacts solved after the update
(:func:`filters.contact_solve.apply_explicit_contact`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..contact_solve import apply_explicit_contact
from .common import StepInfo, check_h

if TYPE_CHECKING:
    from ..elastic.contact_model import ContactModel
    from ..linalg.protocol import ImplicitSystem
    from ..simulation import State

__all__ = ["euler", "symplectic_euler"]


def euler(system: ImplicitSystem, state: State, h: float, *, contact: ContactModel | None = None,
          contact_tol: float = 1e-4) -> StepInfo:
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
    h = check_h(h)
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


def symplectic_euler(system: ImplicitSystem, state: State, h: float, *,
                     contact: ContactModel | None = None, contact_tol: float = 1e-4) -> StepInfo:
    """Symplectic (semi-implicit) Euler: ``v += h f(x, v) / m; x += h v``, in place, by the
    system's :meth:`~filters.linalg.ImplicitSystem.symplectic_step`; ``contact`` and the other
    arguments as in :func:`euler`."""
    h = check_h(h)
    if contact is None:
        system.symplectic_step(state.positions, state.velocities, h)
        return StepInfo()
    x0 = state.positions.copy()
    system.symplectic_step(state.positions, state.velocities, h)
    contact.begin_step(x0, h)
    dx_free = h * state.velocities
    return StepInfo(newton_iterations=apply_explicit_contact(system, state, x0, dx_free, h,
                                                            contact, contact_tol))

