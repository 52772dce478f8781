"""Frictional contact of elastic objects with static colliders, inside every time step.

:class:`ContactModel` turns a :class:`filters.elastic.contact.Colliders` into terms of the
minimisation that every scheme of :mod:`filters.integrators` solves per step (over the position
increment ``dx`` of a step ``h`` from positions ``x0``, :mod:`filters.contact_solve`)::

    min_dx  Q(dx) + B(x0 + dx) + D(dx) + N(dx)

``Q`` is the scheme's own part (backward Euler's incremental potential, its quadratic model for
the linearised scheme, or ``|dx - dx*|_M^2 / (2 h^2)`` around an explicit update).  The contact
terms, per contact point ``p`` and collider ``c`` (signed distance ``d = phi_c(p)``):

* **non-penetration**: the barrier of Li, Ferguson, Schneider, Langlois, Zorin, Panozzo & Jiang
  (2020, "Incremental potential contact", SIGGRAPH), ``B = sum kappa_p b(d)``,
  ``b(d) = -(d - dhat)^2 ln(d / dhat)`` for ``d < dhat`` (the colliders' ``thickness``), which
  is smooth, zero beyond ``dhat`` and infinite at the surface.  Every line search starts from
  a point outside every collider and is cut where a point would come closer than
  :attr:`ContactModel.KEEP` of its distance (their filtered line search; exact for planes and
  spheres, conservative advancement for boxes), so no iterate, converged or not, ever crosses
  a collider.  ``kappa_p`` is ``stiffness_ratio`` times the point's share of the diagonal of the
  implicit system matrix, ``m_p / h_ref^2 + k_p``, so contacts weigh like what they hold;
* **Coulomb friction** as a dissipative potential with the normal forces ``lambda_p`` and the
  tangent planes lagged from the start of the step (Li et al. 2020, section 5)::

      D = sum mu_c lambda_pc f0(|u_t|),   u_t = (I - n n^T)(p(x0 + dx) - p(x0)),

  ``f0`` the C2 smoothing of ``|u_t|`` below the slip ``eps_v h`` (``f1 = f0'`` rises from
  0 to 1 as ``2y/(eps_v h) - y^2/(eps_v h)^2``): the force ``mu lambda f1`` is the kinetic
  friction ``mu lambda`` when sliding faster than ``eps_v``, and holds any tangential load
  below ``mu lambda`` with a creep slower than ``eps_v`` (the static regime);
* **normal damping** of points within ``dhat``, ``N = c_p / (2 h) (n . u)^2`` with
  ``c_p = 2 zeta sqrt(k_p m_p)`` for the barrier's stiffness ``k_p`` at the start of the step
  (critical, ``zeta = 1``, by default): contacts are inelastic (restitution 0), and elastic
  objects bounce through their own elasticity.

``B`` is convex for planes, ``D`` and ``N`` are convex, non-negative and do negative work
(``grad . dx >= 0``): added to a minimisation whose minimiser does not raise the mechanical
energy, they can only remove energy (the argument of Gast et al. 2015 for backward Euler with
convex potentials).  The energy account counts ``B`` as the contact energy.

Contact points are the particles, or points embedded in them with fixed weights (a jello's
surface mesh in its lattice, :class:`filters.elastic.topology.Embedding`):
``p_j = sum_k w_jk x[nodes_jk]``, ``sum_k w_jk = 1``, ``w >= 0``.  Their Hessian blocks are
spread on the particles' diagonal blocks as ``sum_j w_jk H_j``, which bounds ``W^T H W``
from above (Jensen's inequality): the Newton directions stay descent directions of the true
terms, and for particles (``W = I``) it is the exact Gauss-Newton Hessian.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..validation import check_range
from .contact import Colliders
from .contact_kernels import (
    barrier,
    barrier_energies,
    contact_clearance,
    contact_terms,
    feasible_steps,
    lag_normal_forces,
    scatter_to_particles,
)
from .threads import serial_below

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["ContactModel", "DEFAULT_STIFFNESS_RATIO", "DEFAULT_SLIP_VELOCITY", "barrier"]

#: Barrier stiffness over the diagonal of the implicit system matrix (see the module docstring).
DEFAULT_STIFFNESS_RATIO = 1.0
#: Slip velocity (m/s) below which friction is static (creep slower than this).  The friction
#: potential is smoothed over a slip of ``eps_v h`` (4 um at 1 mm/s and h = 1/240 s): its
#: curvature falls from ``2 mu lambda / (eps_v h)`` to 0 within it, so Newton's quadratic model
#: holds only that far and the line search cuts every step.  Measured on ``jello_fem``'s drop
#: (2 s, exact contact Hessians): 1 mm/s left 18 % of the steps at the limit of 10 Newton
#: iterations (52 % in contact), 5 mm/s 4.2 %, 1 cm/s 1.2 % (2.8 iterations a step).
DEFAULT_SLIP_VELOCITY = 1e-2

#: Below this many contact points the kernels run on one thread (a parallel region costs more
#: than the work, and on a busy machine a descheduled worker stalls it).
PARALLEL_MIN_POINTS = 50_000


def _threads(points):
    """One thread below ``PARALLEL_MIN_POINTS`` (:func:`filters.elastic.threads.serial_below`)."""
    return serial_below(points, PARALLEL_MIN_POINTS)


# ---------------------------------------------------------------------------------------------
class ContactModel:
    """Barrier contact and lagged Coulomb friction of particles, or of points embedded in them,
    against static colliders (see the module docstring).

    The schemes of :mod:`filters.integrators` take it as ``contact=``: they call
    :meth:`begin_step` once per step, then :meth:`value`, :meth:`derivatives` and
    :meth:`max_step` inside their minimisation; simulations report :meth:`energy` in their
    energy account.

    Parameters
    ----------
    colliders : Colliders
        The obstacles and their friction coefficients; restitution must be 0 (contacts of
        elastic objects are inelastic, see the module docstring).  Its ``thickness`` is the
        distance ``dhat`` (m) within which the barrier repels (1 mm when it is 0).
    masses : (N,) array_like
        Particle masses (kg), > 0.
    reference_step : float
        The step (s) the barrier stiffness is scaled for (a simulation's largest step), > 0.
    embedding : (nodes, weights), optional
        Contact points embedded in the particles: ``nodes`` (M, K) int and ``weights``
        (M, K) float, rows of non-negative weights summing to 1.  Default: the particles.
    pinned : (N,) bool array_like, optional
        Particles that never move; points on pinned particles only take no part.
    stiffness_ratio : float
        ``kappa_p`` over the point's share of the diagonal of the implicit system matrix,
        ``m_p / h_ref^2 + k_p``, > 0 (default :data:`DEFAULT_STIFFNESS_RATIO`).
    stiffness : float, optional
        One barrier stiffness ``kappa`` (N/m) for every point instead, > 0.
    slip_velocity : float
        ``eps_v`` (m/s) of the friction smoothing, > 0 (default
        :data:`DEFAULT_SLIP_VELOCITY`).
    elastic_diagonal : (N,) array_like, optional
        Each particle's elastic stiffness ``k_i`` (N/m), the diagonal of ``-df/dx`` (negative
        values count as 0); default 0.
    damping_ratio : float
        Damping of the normal motion of points within ``dhat``, as a ratio of the critical
        damping ``2 sqrt(k m)`` of the barrier's stiffness ``k`` at the start of the step,
        >= 0: 1 (the default) makes contacts inelastic.

    Attributes
    ----------
    kappa : (M,) float64
        Barrier stiffness of every contact point (N/m).
    point_masses : (M,) float64
        Mass (kg) each contact point stands for (``m_i`` shared by the points that weigh on
        particle ``i``).
    dhat : float
        Distance (m) within which the barrier acts.
    """

    #: A Newton step may bring a point at most this fraction closer to a collider than it was.
    KEEP = 0.2

    def __init__(self, colliders: Colliders, masses: ArrayLike, reference_step: float, *,
                 embedding: tuple[np.ndarray, np.ndarray] | None = None,
                 pinned: ArrayLike | None = None, stiffness_ratio: float = DEFAULT_STIFFNESS_RATIO,
                 stiffness: float | None = None, slip_velocity: float = DEFAULT_SLIP_VELOCITY,
                 elastic_diagonal: ArrayLike | None = None, damping_ratio: float = 1.0):
        if not isinstance(colliders, Colliders):
            raise TypeError(f"colliders must be a Colliders object, got "
                            f"{type(colliders).__name__}")
        restitution = np.concatenate([colliders.planes[:, 4], colliders.spheres[:, 5],
                                      colliders.boxes[:, 7]])
        if restitution.size and restitution.max() > 0.0:
            raise ValueError("restitution of the colliders of an elastic object must be 0 "
                             f"(got {restitution.max():g}): its contacts are inelastic and "
                             "it bounces through its own elasticity")
        masses = np.ascontiguousarray(masses, dtype=np.float64)
        if masses.ndim != 1 or not np.isfinite(masses).all() or masses.min(initial=1.0) <= 0:
            raise ValueError("masses must be a (N,) array of finite values > 0 (kg)")
        self.reference_step = check_range("reference_step", reference_step, 0.0, math.inf,
                                          low_inclusive=False)
        ratio = check_range("stiffness_ratio", stiffness_ratio, 0.0, math.inf,
                            low_inclusive=False)
        self.slip_velocity = check_range("slip_velocity", slip_velocity, 0.0, math.inf,
                                         low_inclusive=False)
        self.damping_ratio = check_range("damping_ratio", damping_ratio, 0.0)
        n = masses.shape[0]
        if embedding is None:
            nodes = np.arange(n, dtype=np.int64)[:, None]
            weights = np.ones((n, 1))
        else:
            nodes = np.ascontiguousarray(embedding[0], dtype=np.int64)
            weights = np.ascontiguousarray(embedding[1], dtype=np.float64)
            if nodes.ndim != 2 or weights.shape != nodes.shape or nodes.shape[0] == 0:
                raise ValueError("embedding must be (nodes, weights), two (M, K) arrays")
            if nodes.min() < 0 or nodes.max() >= n:
                raise ValueError(f"embedding nodes must index particles in [0, {n - 1}]")
            if (not np.isfinite(weights).all() or weights.min() < 0.0
                    or np.abs(weights.sum(axis=1) - 1.0).max() > 1e-9):
                raise ValueError("embedding weights must be >= 0 and sum to 1 per point")
        pinned = np.zeros(n, bool) if pinned is None else np.asarray(pinned, dtype=bool)
        if pinned.shape != (n,):
            raise ValueError(f"pinned must have shape ({n},), got {pinned.shape}")
        self.colliders = colliders
        self.dhat = colliders.thickness if colliders.thickness > 0.0 else 1e-3
        self.nodes = nodes
        self.weights = weights
        self.n_particles = n
        self.identity = embedding is None
        self.active = np.ascontiguousarray(~np.all(pinned[nodes] | (weights == 0.0), axis=1))
        # each particle's mass (and stiffness) shared among the points that weigh on it
        load = np.zeros(n)
        np.add.at(load, nodes.ravel(), weights.ravel())
        inv_load = np.where(load > 0.0, 1.0 / np.where(load > 0.0, load, 1.0), 0.0)
        self.point_masses = (weights * (masses * inv_load)[nodes]).sum(axis=1)
        diagonal = self.point_masses / self.reference_step ** 2
        if elastic_diagonal is not None:
            k = np.ascontiguousarray(elastic_diagonal, dtype=np.float64)
            if k.shape != (n,) or not np.isfinite(k).all():
                raise ValueError(f"elastic_diagonal must be a finite ({n},) array (N/m)")
            diagonal = diagonal + (weights * (np.maximum(k, 0.0) * inv_load)[nodes]).sum(axis=1)
        if stiffness is None:
            self.kappa = ratio * diagonal
        else:
            stiffness = check_range("stiffness", stiffness, 0.0, math.inf, low_inclusive=False)
            self.kappa = np.full(nodes.shape[0], stiffness)
        m = nodes.shape[0]
        self._lagged = np.zeros((m, 5))
        self._energies = np.empty(m)
        self._steps = np.empty(m)
        self._grad_p = np.empty((m, 3))
        self._hess_p = np.empty((m, 6))
        self._h = self.reference_step
        self.touching = 0

    def __len__(self):
        """Number of contact points."""
        return self.nodes.shape[0]

    def _args(self):
        c = self.colliders
        return self.active, c.planes, c.spheres, c.boxes

    def begin_step(self, x0: np.ndarray, h: float) -> int:
        """Lag the normal forces and tangent planes at the start positions ``x0`` (N, 3) for a
        step of ``h`` (s); returns the number of contact points within ``dhat``.

        Raises
        ------
        ValueError
            If a contact point is on or inside a collider (a start state the barrier cannot
            hold).
        """
        self._h = float(h)
        self.check_outside(x0)
        with _threads(len(self)):
            self.touching = int(lag_normal_forces(x0, self.nodes, self.weights, *self._args(),
                                                  self.dhat, self.kappa, self.point_masses,
                                                  self.damping_ratio, self._lagged))
        return self.touching

    def check_outside(self, x: np.ndarray) -> None:
        """Raise ``ValueError`` if a contact point at positions ``x`` is on or inside a
        collider (a state the barrier cannot hold)."""
        clearance = np.where(self.active, self.clearance(x), np.inf)
        if clearance.size and not clearance.min() > 0.0:
            j = int(np.argmin(clearance))
            raise ValueError(f"positions: contact point {j} is {-clearance[j]:.3g} m inside a "
                             "collider; elastic objects must start outside their colliders")

    def value(self, x0: np.ndarray, dx: np.ndarray) -> float:
        """Barrier plus friction (J) of the step ``dx`` (N, 3) from ``x0``; ``inf`` when a
        point would be on or inside a collider."""
        with _threads(len(self)):
            contact_terms(x0, dx, self.nodes, self.weights, *self._args(), self.dhat,
                          self.kappa, self._lagged, self.slip_velocity * self._h, self._h,
                          self._grad_p[:0], self._hess_p[:0], self._energies)
        return float(self._energies.sum())

    def derivatives(self, x0: np.ndarray, dx: np.ndarray, grad: np.ndarray,
                    blocks: np.ndarray) -> float:
        """Barrier plus friction (J) of the step ``dx``; adds its gradient to ``grad`` (N, 3)
        and writes the particles' Hessian blocks (a bound from above for embedded points) into
        ``blocks`` (N, 3, 3)."""
        with _threads(len(self)):
            contact_terms(x0, dx, self.nodes, self.weights, *self._args(), self.dhat,
                          self.kappa, self._lagged, self.slip_velocity * self._h, self._h,
                          self._grad_p, self._hess_p, self._energies)
        scatter_to_particles(self.nodes, self.weights, self._grad_p, self._hess_p, grad, blocks)
        return float(self._energies.sum())

    def point_hessians(self) -> tuple[NDArray[np.int64], NDArray[np.float64],
                                      NDArray[np.float64]] | None:
        """``(nodes (M, K), weights (M, K), hessians (M, 6))`` of the last
        :meth:`derivatives` call, for the exact blocks ``W^T H W`` of embedded points
        (:mod:`filters.linalg.coupling`); None for contact points that are the particles
        themselves, whose diagonal blocks are exact already."""
        if self.identity:
            return None
        return self.nodes, self.weights, self._hess_p

    def max_step(self, x0: np.ndarray, dx: np.ndarray, d: np.ndarray) -> float:
        """Largest fraction in [0, 1] of the step ``d`` (N, 3) from ``x0 + dx`` that brings no
        contact point closer to a collider than :attr:`KEEP` times its distance (the
        feasibility filter of the line search, Li et al. 2020)."""
        with _threads(len(self)):
            feasible_steps(x0, dx, d, self.nodes, self.weights, *self._args(), self.KEEP,
                           self._steps)
        return float(self._steps.min(initial=1.0))

    def particle_steps(self, x0: np.ndarray, dx: np.ndarray, d: np.ndarray) -> NDArray[np.float64]:
        """Per particle, a fraction in [0, 1] of ``d`` (N, 3) that keeps its contact points
        feasible when each particle moves by its own fraction (the smallest over a particle's
        points; one common fraction for embedded points, whose particles move together)."""
        with _threads(len(self)):
            feasible_steps(x0, dx, d, self.nodes, self.weights, *self._args(), self.KEEP,
                           self._steps)
        if not self.identity:
            return np.full(self.n_particles, float(self._steps.min(initial=1.0)))
        return self._steps.copy()

    def energy(self, x: np.ndarray) -> float:
        """Barrier (contact) energy (J) at positions ``x`` (N, 3)."""
        with _threads(len(self)):
            barrier_energies(x, self.nodes, self.weights, *self._args(), self.dhat, self.kappa,
                             self._energies)
        return float(self._energies.sum())

    def clearance(self, x: np.ndarray) -> NDArray[np.float64]:
        """Signed distance (M,) (m) of every contact point to the colliders at positions ``x``
        (negative inside an obstacle)."""
        out = np.empty(self.nodes.shape[0])
        c = self.colliders
        with _threads(len(self)):
            contact_clearance(x, self.nodes, self.weights, c.planes, c.spheres, c.boxes, out)
        return out

    def points(self, x: np.ndarray) -> NDArray[np.float64]:
        """Contact points (M, 3) (m) for particle positions ``x`` (N, 3)."""
        return np.einsum("mk,mkj->mj", self.weights, x[self.nodes])
