"""The energy account of an elastic simulation: kinetic, gravitational, elastic and contact.

Every elastic simulation reports :func:`energy_account` of its state (and writes it as field
data of every frame, :meth:`EnergyAccount.field_data`).  With static pins and colliders and no
driven boundaries, nothing does work on the system: stepped by an implicit scheme (backward
Euler, linearised backward Euler: the scenes' defaults) its total can only fall, through
damping, drag, friction, inelastic contacts and the dissipation of the time integrator
(``tests/scenes/test_elastic_scenes.py``).  The explicit schemes do not promise that:
symplectic Euler keeps a spring system's energy bounded but not monotonic (measured: an
undamped cloth hanging from two pins rose in 11 of 30 frames, ending 6.7e-5 J above its start;
on a sphere, by up to 7.3e-3 of its start), forward Euler gains energy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ..linalg.protocol import ImplicitSystem
    from .contact_model import ContactModel

__all__ = ["EnergyAccount", "energy_account", "ENERGY_FIELDS"]

#: Field-data array names of the account in written frames (J, one value each).
ENERGY_FIELDS = ("energy_kinetic", "energy_gravitational", "energy_elastic", "energy_contact",
                 "energy_total")


@dataclass(frozen=True)
class EnergyAccount:
    """Energies (J) of one state.

    Attributes
    ----------
    kinetic : float
        ``sum m_i |v_i|^2 / 2``.
    gravitational : float
        ``-sum m_i g . x_i`` (zero at the origin: ``m g z`` above ``z = 0``).
    elastic : float
        Energy stored in springs, bending or elements.
    contact : float
        Energy stored in contact penalties.
    """

    kinetic: float
    gravitational: float
    elastic: float
    contact: float

    @property
    def total(self) -> float:
        """Sum of the four (J)."""
        return self.kinetic + self.gravitational + self.elastic + self.contact

    def field_data(self) -> dict:
        """``{name: (1,) float64}`` under the names of :data:`ENERGY_FIELDS`."""
        values = (self.kinetic, self.gravitational, self.elastic, self.contact, self.total)
        return {name: np.array([value]) for name, value in zip(ENERGY_FIELDS, values, strict=False)}


def energy_account(system: ImplicitSystem, positions: np.ndarray, velocities: np.ndarray,
                   contact: ContactModel | None = None) -> EnergyAccount:
    """The energy account of a system of particles.

    Parameters
    ----------
    system : filters.linalg.ImplicitSystem
        Supplies ``masses``, ``gravity`` and ``potential_energy(x)`` (elastic plus
        gravitational), or ``elastic_energy(x)`` when it has one.
    positions, velocities : (N, 3) float64 arrays
        The state (m, m/s).
    contact : contact model, optional
        Supplies ``energy(x)``, the stored contact energy
        (:class:`filters.elastic.contact_model.ContactModel`).

    Returns
    -------
    EnergyAccount
    """
    x = np.ascontiguousarray(positions, dtype=np.float64)
    v = np.ascontiguousarray(velocities, dtype=np.float64)
    m = system.masses
    kinetic = 0.5 * float(np.einsum("i,ij,ij->", m, v, v))
    gravitational = -float(np.einsum("i,ij,j->", m, x, system.gravity))
    if hasattr(system, "elastic_energy"):
        elastic = float(system.elastic_energy(x))
    else:
        elastic = float(system.potential_energy(x)) - gravitational
    contact_energy = 0.0 if contact is None else float(contact.energy(x))
    return EnergyAccount(kinetic, gravitational, elastic, contact_energy)
