"""What the implicit time integrators need of a system of particles: :class:`ImplicitSystem`.

A system (the damped springs of :class:`filters.elastic.springs.SpringSystem`, or any other)
derives from :class:`ImplicitSystem` and supplies its forces, energies and the implicit system
matrix ``H = M / h^2 + K + C / h`` (``K = -df/dx`` made definite, ``C = -df/dv``; rows and
columns of pinned particles the identity) assembled as a sparse matrix, and, when it has one,
the same matrix as a matrix-free :class:`filters.linalg.operator.BlockOperator` (conjugate
gradients then run without assembling). The integrators of :mod:`filters.integrators` and the
solvers of :mod:`filters.linalg.solver` call only these; the integrators add contacts
(:class:`filters.elastic.contact_model.ContactModel`, whose barrier stiffness can follow a
system's ``elastic_diagonal()`` when it has one) and the solvers add their diagonal blocks, so
any system gets them.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from scipy.sparse import csr_matrix

    from .operator import BlockOperator

__all__ = ["ImplicitSystem"]


class ImplicitSystem(ABC):
    """Base class of the particle systems the implicit integrators advance.

    Attributes
    ----------
    masses : (N,) float64
        Particle masses (kg).
    inv_mass : (N,) float64
        Inverse masses (1/kg), 0 for pinned particles.
    pinned : (N,) bool
        Particles held fixed.
    gravity : (3,) float64
        Gravitational acceleration (m/s^2).
    """

    masses: np.ndarray
    inv_mass: np.ndarray
    pinned: np.ndarray
    gravity: np.ndarray

    @abstractmethod
    def forces(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Total force (N) on every particle at positions ``x`` and velocities ``v``, (N, 3)."""

    @abstractmethod
    def conservative_forces(self, x: np.ndarray) -> np.ndarray:
        """Forces of the potential energy (elastic, gravity) at ``x``, (N, 3); contacts are
        the integrators' (``contact=``)."""

    @abstractmethod
    def damping_forces(self, xdir: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Damping force ``-C v`` (N) with the damping directions of ``xdir``, (N, 3)."""

    @abstractmethod
    def potential_energy(self, x: np.ndarray) -> float:
        """Potential energy (J) at ``x``."""

    @abstractmethod
    def system_matrix(self, x: np.ndarray, xdir: np.ndarray, h: float) -> csr_matrix:
        """``H = M/h^2 + K(x) + C(xdir)/h`` as a ``scipy.sparse`` CSR matrix, (3N, 3N)."""

    def implicit_operator(self, x: np.ndarray, xdir: np.ndarray, h: float) -> BlockOperator | None:
        """``H`` as a matrix-free :class:`filters.linalg.operator.BlockOperator`, or None when
        the system has no matrix-free form (the solvers then use :meth:`system_matrix`)."""
        return None

    def symplectic_step(self, x: np.ndarray, v: np.ndarray, h: float) -> None:
        """Symplectic Euler in place: ``v += h f(x, v) / m; x += h v`` (systems with a fused
        kernel override it)."""
        v += h * self.forces(x, v) * self.inv_mass[:, None]
        x += h * v
