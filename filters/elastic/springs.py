"""Damped springs: forces, energies and analytic 3x3 Jacobians, and a spring system for the
integrators.

A spring joins particles ``a`` and ``b`` with rest length ``L`` and stiffness ``k``.  With
``d = x_a - x_b``, ``l = |d|`` and ``u = d / l`` the force on ``a`` is the seed's

.. math::  f_a = -k (l / L - 1) u \\qquad (L > 0),

i.e. ``k`` is a *strain* stiffness in newtons, so a chain of ``n`` springs of total length ``n L``
has the same overall stiffness ``k / (n L)`` at every resolution.  A zero-rest-length spring
(``L = 0``) is the linear spring ``f_a = -k d`` with ``k`` in N/m.  Internally both are written
``f_a = -k_e (l - L) u`` with the *effective* stiffness ``k_e = k / L`` (N/m) or ``k``.

Damping (``c`` in N s/m), with ``w = v_a - v_b``:

* ``"axial"`` (the seed's): ``f_a = -c (w . u) u`` — damps stretching only;
* ``"relative"``: ``f_a = -c w`` (the simplified form);
* a zero-rest-length spring has no direction at zero length: it always damps ``-c w``;
* a per-particle *drag* ``f_i = -c_drag v_i`` (the simplest form) lives in :class:`SpringSystem`.

The force on ``b`` is always ``-f_a``, so linear momentum is conserved to round-off.

Jacobians (Baraff & Witkin 1998, "Large steps in cloth simulation", SIGGRAPH):
``J_x = df_a/dx_a = -k_e [u u^T + (1 - L/l)(I - u u^T)]`` plus, for axial damping,
``-(c/l) [u w^T P + (w . u) P]`` with ``P = I - u u^T``; ``J_v = df_a/dv_a = -c u u^T`` (axial) or
``-c I`` (relative).  ``df_a/dx_b = -J_x`` and so on.  For a compressed spring (``l < L``) the
transverse term ``(1 - L/l) < 0`` makes ``-J_x`` indefinite; the *definite* Jacobians clamp it to 0
(Choi & Ko 2002, "Stable but responsive cloth"), which keeps the implicit system matrix SPD.

Polylines (hair) can also carry the quadratic bending energy of :func:`bending_springs`, written
as linear springs of which some have negative stiffness (their sum is positive semi-definite).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..linalg import BlockOperator, ImplicitSystem
from ..validation import check_choice, check_finite_vector, check_points, check_range
from .spring_kernels import (
    assemble_system,
    elastic_energy,
    elastic_energy_serial,
    incidence,
    incidence_in_spring_order,
    jacobian_blocks,
    operator_coefficients,
    operator_diagonal,
    per_spring_forces,
    point_energies,
    symplectic_parallel,
    symplectic_serial,
    total_forces,
    total_forces_serial,
)
from .threads import serial_below

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray
    from scipy.sparse import csr_matrix

__all__ = [
    "DAMPING_MODES",
    "bending_springs",
    "effective_stiffness",
    "spring_forces",
    "spring_energy",
    "spring_jacobians",
    "SpringSystem",
]

#: Spring damping models: 0 = axial (seed), 1 = relative velocity.
DAMPING_MODES = ("axial", "relative")

#: Below this many springs the kernels run on one thread: a parallel region costs more than the
#: work, and on a busy machine a descheduled worker thread stalls every region.
PARALLEL_MIN_SPRINGS = 50_000

#: Below this many springs the explicit step runs on one thread.  Both kernels give the same
#: bits (the parallel one gathers each particle's forces in spring order), so this is a speed
#: setting only: on 2 threads the serial kernel is faster up to ~50k springs (one step of a
#: hanging cloth, serial / 2 threads: 13.3k springs 88 / 125 us, 23.9k 172 / 195 us, 54.3k
#: 509 / 476 us, 97k 780 / 700 us, 193k 1.93 / 1.55 ms; 2026-11-28).  On a machine shared
#: with other busy processes a parallel region can stall: raise it to force the serial kernel.
PARALLEL_MIN_SPRINGS_EXPLICIT = 50_000


def _threads(work):
    """One thread below ``PARALLEL_MIN_SPRINGS`` (:func:`filters.elastic.threads.serial_below`)."""
    return serial_below(work, PARALLEL_MIN_SPRINGS)


# ---------------------------------------------------------------------------------------------
# Array-level public functions
# ---------------------------------------------------------------------------------------------
def _check_springs(pairs, n_points):
    pairs = np.ascontiguousarray(pairs, dtype=np.int64)
    if pairs.ndim != 2 or pairs.shape[1] != 2:
        raise ValueError(f"springs must have shape (S, 2), got {pairs.shape}")
    if pairs.size and (pairs.min() < 0 or pairs.max() >= n_points):
        raise ValueError(f"springs must index particles in [0, {n_points - 1}]")
    if pairs.size and np.any(pairs[:, 0] == pairs[:, 1]):
        raise ValueError("springs must join two different particles (found a spring i-i)")
    return pairs


def _per_spring(name, value, n, low=0.0):
    arr = np.ascontiguousarray(np.broadcast_to(np.asarray(value, dtype=np.float64), (n,)))
    if not np.isfinite(arr).all() or (arr.size and arr.min() < low):
        raise ValueError(f"{name} must be finite and >= {low:g} for every spring")
    return arr.copy()


def bending_springs(triples: ArrayLike, stiffness: ArrayLike, damping: ArrayLike,
                    n_points: int) -> tuple[NDArray[np.int64], NDArray[np.float64],
                                            NDArray[np.float64]]:
    """The quadratic bending energy of polylines as zero-rest-length springs.

    For consecutive particles ``(a, b, c)`` of a polyline whose rest shape is straight with
    equal segments, ``E = k/2 |x_a - 2 x_b + x_c|^2`` is the isometric (quadratic) bending
    energy of Bergou, Wardetzky, Harmon, Zorin & Grinspun (2006, "A quadratic bending model
    for inextensible surfaces", SGP), in its one-dimensional form: ``|x_a - 2 x_b + x_c| =
    2 l sin(theta / 2)`` for a turning angle ``theta``, so ``E ~ (EI / l) theta^2 / 2`` with
    ``k = EI / l^3``, the discrete elastic-rod energy for small angles; it is invariant under
    rigid motions and its Hessian is constant.  Since ``|a - 2b + c|^2 = 2|a - b|^2 +
    2|b - c|^2 - |a - c|^2``, it is the energy of three linear (zero-rest-length) springs of
    stiffness ``2k``, ``2k`` and ``-k``; the damping force ``-c (v_a - 2 v_b + v_c)`` (per
    particle, weighted like the stiffness) is their relative damping ``2c, 2c, -c``.  Springs
    shared by neighbouring triples are merged.

    Parameters
    ----------
    triples : (B, 3) int array_like
        Particles ``(a, b, c)``.
    stiffness, damping : (B,) array_like or float
        ``k`` (N/m) and ``c`` (N s/m) per triple, >= 0.
    n_points : int
        Number of particles.

    Returns
    -------
    pairs : (S, 2) int64 array
    stiffness : (S,) float64 array
        Linear spring constants (N/m), some negative; their sum is positive semi-definite.
    damping : (S,) float64 array
        Relative damping (N s/m), likewise.
    """
    t = np.ascontiguousarray(triples, dtype=np.int64)
    if t.ndim != 2 or t.shape[1] != 3:
        raise ValueError(f"bend_triples must have shape (B, 3), got {t.shape}")
    if t.size and (t.min() < 0 or t.max() >= n_points):
        raise ValueError(f"bend_triples must index particles in [0, {n_points - 1}]")
    if t.size and np.any((t[:, 0] == t[:, 1]) | (t[:, 1] == t[:, 2]) | (t[:, 0] == t[:, 2])):
        raise ValueError("bend_triples must join three different particles")
    b = t.shape[0]
    k = _per_spring("bend_stiffness", stiffness, b)
    c = _per_spring("bend_damping", damping, b)
    pairs = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [0, 2]]])
    factor = np.repeat([2.0, 2.0, -1.0], b)
    pairs = np.sort(pairs, axis=1)
    keys = pairs[:, 0] * n_points + pairs[:, 1]
    uniq, inverse = np.unique(keys, return_inverse=True)
    ks = np.zeros(uniq.size)
    cs = np.zeros(uniq.size)
    np.add.at(ks, inverse, factor * np.tile(k, 3))
    np.add.at(cs, inverse, factor * np.tile(c, 3))
    out = np.ascontiguousarray(np.stack([uniq // n_points, uniq % n_points], axis=1))
    return out, ks, cs


def effective_stiffness(stiffness: ArrayLike, rest_lengths: ArrayLike) -> NDArray[np.float64]:
    """Effective spring constants ``k_e`` (N/m): ``k / L`` for ``L > 0``, ``k`` for ``L == 0``.

    Parameters
    ----------
    stiffness : (S,) array_like
        Seed-form strain stiffness ``k`` (N) or, for zero rest length, spring constant (N/m).
    rest_lengths : (S,) array_like
        Rest lengths ``L`` (m), >= 0.

    Returns
    -------
    (S,) float64 array
    """
    k = np.asarray(stiffness, dtype=np.float64)
    L = np.asarray(rest_lengths, dtype=np.float64)
    return np.where(L > 0.0, k / np.where(L > 0.0, L, 1.0), k)


def _prep(positions, velocities, springs, rest_lengths, stiffness, damping, damping_mode):
    x = check_points("positions", positions)
    v = np.zeros_like(x) if velocities is None else check_points("velocities", velocities)
    if v.shape != x.shape:
        raise ValueError("velocities must have the same shape as positions")
    pairs = _check_springs(springs, x.shape[0])
    s = pairs.shape[0]
    rest = _per_spring("rest_lengths", rest_lengths, s)
    k = _per_spring("stiffness", stiffness, s)
    c = _per_spring("damping", damping, s)
    mode = DAMPING_MODES.index(check_choice("damping_mode", damping_mode, DAMPING_MODES))
    return x, v, pairs, rest, effective_stiffness(k, rest), c, mode


def spring_forces(positions: ArrayLike, springs: ArrayLike, rest_lengths: ArrayLike,
                  stiffness: ArrayLike, velocities: ArrayLike | None = None,
                  damping: ArrayLike = 0.0, damping_mode: str = "axial") -> NDArray[np.float64]:
    """Per-spring force on the first end of every spring.

    Parameters
    ----------
    positions : (N, 3) array_like
        Particle positions (m).
    springs : (S, 2) int array_like
        Particle indices ``(a, b)`` of every spring.
    rest_lengths : (S,) or scalar
        Rest lengths (m), >= 0.
    stiffness : (S,) or scalar
        Seed-form stiffness ``k`` (N) (N/m for zero rest length), >= 0.
    velocities : (N, 3) array_like, optional
        Particle velocities (m/s), for damping.
    damping : (S,) or scalar
        Damping coefficient ``c`` (N s/m), >= 0.
    damping_mode : {"axial", "relative"}
        See the module docstring.

    Returns
    -------
    (S, 3) float64 array
        Force (N) on particle ``a``; the force on ``b`` is its negative.
    """
    x, v, pairs, rest, ke, c, mode = _prep(positions, velocities, springs, rest_lengths,
                                           stiffness, damping, damping_mode)
    fs = np.empty((pairs.shape[0], 3))
    per_spring_forces(x, v, pairs, ke, rest, c, mode, fs)
    return fs


def spring_energy(positions: ArrayLike, springs: ArrayLike, rest_lengths: ArrayLike,
                  stiffness: ArrayLike) -> float:
    """Elastic energy ``sum 0.5 k_e (l - L)^2`` (J) of a set of springs (arguments as in
    :func:`spring_forces`)."""
    x, _, pairs, rest, ke, _, _ = _prep(positions, None, springs, rest_lengths, stiffness, 0.0,
                                        "axial")
    return float(elastic_energy(x, pairs, ke, rest))


def spring_jacobians(positions: ArrayLike, springs: ArrayLike, rest_lengths: ArrayLike,
                     stiffness: ArrayLike, velocities: ArrayLike | None = None,
                     damping: ArrayLike = 0.0, damping_mode: str = "axial", *,
                     definite: bool = False,
                     damping_dx: bool = True) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Analytic Jacobians of the force on the first end of every spring.

    Parameters
    ----------
    positions, springs, rest_lengths, stiffness, velocities, damping, damping_mode
        As in :func:`spring_forces`.
    definite : bool
        Clamp the transverse term of compressed springs to zero so that ``-J_x`` is positive
        semi-definite (for implicit solves).  ``False`` gives the exact derivative.
    damping_dx : bool
        Include the (non-symmetric) derivative of axial damping with respect to positions.

    Returns
    -------
    jx : (S, 3, 3) float64 array
        ``df_a/dx_a`` (N/m); ``df_a/dx_b = -jx``, ``df_b/dx_b = jx``.
    jv : (S, 3, 3) float64 array
        ``df_a/dv_a`` (N s/m); ``df_a/dv_b = -jv``.
    """
    x, v, pairs, rest, ke, c, mode = _prep(positions, velocities, springs, rest_lengths,
                                           stiffness, damping, damping_mode)
    s = pairs.shape[0]
    jx = np.empty((s, 3, 3))
    jv = np.empty((s, 3, 3))
    jacobian_blocks(x, v, pairs, ke, rest, c, mode, bool(definite), bool(damping_dx), jx, jv)
    return jx, jv


class SpringSystem(ImplicitSystem):
    """A set of damped springs between particles with masses, gravity, drag and pins.

    An :class:`filters.linalg.ImplicitSystem`: it supplies what :mod:`filters.integrators`
    needs: total forces, potential energy, the
    frozen-direction damping force, and the implicit system matrix
    ``H = M / h^2 + K + C / h`` assembled in Numba into a fixed-pattern ``scipy.sparse`` CSR
    matrix (``K = -df/dx`` made definite, ``C = -df/dv``); rows and columns of pinned particles are
    eliminated (replaced by the identity).

    Parameters
    ----------
    springs : (S, 2) int array_like
        Particle indices of every spring.
    rest_lengths : (S,) array_like or float
        Rest lengths (m), >= 0.
    stiffness : (S,) array_like or float
        Seed-form stiffness ``k`` (N) (N/m for zero rest length), >= 0.
    masses : (N,) array_like
        Particle masses (kg), > 0.
    damping : (S,) array_like or float
        Spring damping ``c`` (N s/m), >= 0.
    damping_mode : {"axial", "relative"}
        Spring damping model.
    drag : float
        Per-particle drag ``-drag * v_i`` (N s/m), >= 0.
    gravity : sequence of 3 float
        Gravitational acceleration (m/s^2).
    pinned : (N,) bool array_like, optional
        Particles held fixed.
    bend_triples : (B, 3) int array_like, optional
        Consecutive particles ``(a, b, c)`` of polylines (hair) with the quadratic bending
        energy ``bend_stiffness / 2 |x_a - 2 x_b + x_c|^2`` (see :func:`bending_springs`).
    bend_stiffness : (B,) array_like or float
        Bending stiffness (N/m) of every triple, >= 0: ``EI / l^3`` for a rod of bending
        rigidity ``EI`` (N m^2) and segments of length ``l``.
    bend_damping : (B,) array_like or float
        Bending damping (N s/m) of every triple, >= 0: the force ``-bend_damping (v_a - 2 v_b
        + v_c)`` weighted like the stiffness (Rayleigh damping of the bending modes).

    Contacts are not part of the system: the schemes of :mod:`filters.integrators` add them
    (``contact=``, :class:`filters.elastic.contact_model.ContactModel`).
    """

    def __init__(self, springs: ArrayLike, rest_lengths: ArrayLike, stiffness: ArrayLike,
                 masses: ArrayLike, *, damping: ArrayLike = 0.0, damping_mode: str = "axial",
                 drag: float = 0.0, gravity: ArrayLike = (0.0, 0.0, -9.81),
                 pinned: ArrayLike | None = None, bend_triples: ArrayLike | None = None,
                 bend_stiffness: ArrayLike = 0.0, bend_damping: ArrayLike = 0.0):
        masses = np.ascontiguousarray(masses, dtype=np.float64)
        if masses.ndim != 1 or masses.size == 0:
            raise ValueError(f"masses must be a non-empty (N,) array, got shape {masses.shape}")
        if not np.isfinite(masses).all() or masses.min() <= 0.0:
            raise ValueError("masses must be finite and > 0 (kg)")
        n = masses.shape[0]
        self.n_points = n
        self.masses = masses
        pairs = _check_springs(springs, n)
        s = pairs.shape[0]
        rest = _per_spring("rest_lengths", rest_lengths, s)
        stiffness = _per_spring("stiffness", stiffness, s)
        damping = _per_spring("damping", damping, s)
        self.n_springs = s
        if bend_triples is not None:
            b_pairs, b_k, b_c = bending_springs(bend_triples, bend_stiffness, bend_damping, n)
            pairs = np.ascontiguousarray(np.concatenate([pairs, b_pairs]))
            rest = np.concatenate([rest, np.zeros(b_k.shape[0])])
            stiffness = np.concatenate([stiffness, b_k])
            damping = np.concatenate([damping, b_c])
            s = pairs.shape[0]
        self.pairs = pairs
        self.rest = rest
        self.stiffness = stiffness
        self.damping = damping
        self.damping_mode = check_choice("damping_mode", damping_mode, DAMPING_MODES)
        self.mode = DAMPING_MODES.index(self.damping_mode)
        self.drag = check_range("drag", drag, 0.0)
        self.gravity = check_finite_vector("gravity", gravity, 3).copy()
        if pinned is None:
            pinned = np.zeros(n, dtype=bool)
        pinned = np.ascontiguousarray(pinned, dtype=bool)
        if pinned.shape != (n,):
            raise ValueError(f"pinned must have shape ({n},), got {pinned.shape}")
        self.pinned = pinned
        self.inv_mass = np.where(pinned, 0.0, 1.0 / masses)
        self.ke = np.ascontiguousarray(effective_stiffness(self.stiffness, self.rest))
        self.inc_ptr, self.inc_spring, self.inc_sign, self.inc_other = incidence(self.pairs, n)
        # the explicit step's gather in spring order: its parallel kernel then adds each
        # particle's forces in the serial kernel's order (the same bits on either)
        self._step_spring, self._step_sign = incidence_in_spring_order(self.pairs, n)
        # per-spring forces (rows 0-2) and scratch of the force kernels
        self._fbuf = np.empty((6, s))
        # the springs' end points as uint32 (no negative-index wrap-around in the kernels)
        self._pa, self._pb = (np.ascontiguousarray(pairs[:, k], dtype=np.uint32) for k in (0, 1))
        self._zero_c = np.zeros(s)
        self._zero_k = np.zeros(s)
        self._zero_g = np.zeros(3)
        self._f_scratch = None
        self._pattern = None
        self._operator = None
        self._undamped = self.drag == 0.0 and not np.any(self.damping)
        self._no_blocks = np.zeros((0, 3, 3))

    # -- forces and energies --------------------------------------------------------------
    def _force_kernel(self, x, v, ke, c, mode, gravity, drag, f):
        """Spring + gravity + drag forces into ``f`` (per-spring forces gathered per particle:
        every particle's sum in a fixed order, which keeps the momentum test's round-off)."""
        kernel = (total_forces_serial if self.pairs.shape[0] < PARALLEL_MIN_SPRINGS
                  else total_forces)
        kernel(x, v, self._pa, self._pb, ke, self.rest, c, mode, self.inc_ptr, self.inc_spring,
               self.inc_sign, self.masses, gravity, drag, self._fbuf, f)

    def forces(self, x: np.ndarray, v: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Total force (N) on every particle: springs, damping, gravity and drag, (N, 3)."""
        f = np.empty_like(x) if out is None else out
        self._force_kernel(x, v, self.ke, self.damping, self.mode, self.gravity, self.drag, f)
        return f

    def conservative_forces(self, x: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Spring elastic forces plus gravity (no damping), (N, 3)."""
        f = np.empty_like(x) if out is None else out
        self._force_kernel(x, x, self.ke, self._zero_c, 1, self.gravity, 0.0, f)
        return f

    def damping_forces(self, xdir: np.ndarray, v: np.ndarray,
                       out: np.ndarray | None = None) -> np.ndarray:
        """Damping force (springs and drag) at velocity ``v`` with directions from ``xdir``.

        Linear in ``v``: it equals ``-C v`` with ``C`` the damping matrix at ``xdir``.
        """
        f = np.empty_like(v) if out is None else out
        if self._undamped:
            f[...] = 0.0
            return f
        self._force_kernel(xdir, v, self._zero_k, self.damping, self.mode, self._zero_g,
                           self.drag, f)
        return f

    def elastic_energy(self, x: np.ndarray) -> float:
        """Elastic energy (J) of the springs (and bending) at ``x``."""
        if self.pairs.shape[0] < PARALLEL_MIN_SPRINGS:
            return float(elastic_energy_serial(x, self.pairs, self.ke, self.rest))
        return float(elastic_energy(x, self.pairs, self.ke, self.rest))

    def elastic_diagonal(self) -> NDArray[np.float64]:
        """Each particle's elastic stiffness (N/m): the sum of ``k_e`` over its springs (the
        diagonal of ``-df/dx`` for springs at rest length), (N,)."""
        k = np.zeros(self.n_points)
        np.add.at(k, self.pairs[:, 0], self.ke)
        np.add.at(k, self.pairs[:, 1], self.ke)
        return k

    def gravitational_energy(self, x: np.ndarray) -> float:
        """Gravitational energy ``-sum m_i g . x_i`` (J), zero at the origin."""
        x = np.ascontiguousarray(x, dtype=np.float64)
        return float(point_energies(x, x, self.masses, self.gravity)[1])

    def potential_energy(self, x: np.ndarray) -> float:
        """Elastic plus gravitational potential energy (J)."""
        elastic = (elastic_energy_serial(x, self.pairs, self.ke, self.rest)
                   if self.pairs.shape[0] < PARALLEL_MIN_SPRINGS
                   else elastic_energy(x, self.pairs, self.ke, self.rest))
        x = np.ascontiguousarray(x, dtype=np.float64)
        return float(elastic + point_energies(x, x, self.masses, self.gravity)[1])

    def kinetic_energy(self, v: np.ndarray) -> float:
        """Kinetic energy (J)."""
        v = np.ascontiguousarray(v, dtype=np.float64)
        return float(point_energies(v, v, self.masses, self.gravity)[0])

    def energy(self, x: np.ndarray, v: np.ndarray) -> float:
        """Total mechanical energy (J)."""
        return self.kinetic_energy(v) + self.potential_energy(x)

    def symplectic_step(self, x: np.ndarray, v: np.ndarray, h: float) -> float:
        """Symplectic Euler in one fused kernel (in place); returns the largest speed (m/s).

        Below :data:`PARALLEL_MIN_SPRINGS_EXPLICIT` springs a serial kernel scatters the forces
        directly; above, a parallel kernel computes them per spring and gathers them per
        particle (no atomics, no races).  Contacts are not included
        (:func:`filters.integrators.symplectic_euler` adds them).
        """
        if self.pairs.shape[0] < PARALLEL_MIN_SPRINGS_EXPLICIT:
            if self._f_scratch is None:
                self._f_scratch = np.empty((self.n_points, 3))
            return symplectic_serial(x, v, self._pa, self._pb, self.ke, self.rest, self.damping,
                                     self.mode, self.masses, self.inv_mass, self.gravity,
                                     self.drag, h, self._f_scratch, self._fbuf)
        return symplectic_parallel(x, v, self._pa, self._pb, self.ke, self.rest, self.damping,
                                   self.mode, self.inc_ptr, self._step_spring, self._step_sign,
                                   self.masses, self.inv_mass, self.gravity, self.drag, h,
                                   self._fbuf)

    # -- implicit system --------------------------------------------------------------------
    def _build_pattern(self):
        import scipy.sparse as sp

        n = self.n_points
        a, b = self.pairs[:, 0], self.pairs[:, 1]
        keys = np.unique(np.concatenate([a * n + b, b * n + a, np.arange(n) * (n + 1)]))
        rows = keys // n
        cols = keys % n
        bptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(rows, minlength=n), out=bptr[1:])
        diag_slot = np.searchsorted(keys, np.arange(n) * (n + 1)).astype(np.int64)
        node = np.repeat(np.arange(n), np.diff(self.inc_ptr))
        inc_slot = np.searchsorted(keys, node * n + self.inc_other).astype(np.int64)
        nb = np.diff(bptr)
        # Scalar CSR: row 3i+r holds, for every block k of block-row i, columns 3*col_k + q.
        indptr = np.zeros(3 * n + 1, dtype=np.int64)
        indptr[1:] = np.cumsum(np.repeat(3 * nb, 3))
        row_cols = np.repeat(3 * cols, 3) + np.tile(np.arange(3), cols.size)
        indices = np.empty(9 * keys.size, dtype=np.int64)
        blocks_start = 3 * bptr[:-1]
        # Row 3i+r's indices are row_cols[3*bptr[i] : 3*bptr[i+1]] for r = 0, 1, 2.
        seg = np.repeat(np.arange(n), 3 * nb)  # block-row of each entry of row_cols
        within = np.arange(row_cols.size) - np.repeat(blocks_start, 3 * nb)
        for r in range(3):
            pos = 9 * bptr[seg] + 3 * r * nb[seg] + within
            indices[pos] = row_cols
        data = np.zeros(9 * keys.size)
        index_dtype = np.int32 if 9 * keys.size < 2**31 else np.int64
        mat = sp.csr_matrix((data, indices.astype(index_dtype), indptr.astype(index_dtype)),
                            shape=(3 * n, 3 * n), copy=False)
        mat.has_sorted_indices = True
        self._pattern = dict(bptr=bptr, diag_slot=diag_slot, inc_slot=inc_slot, matrix=mat,
                             jx=np.empty((self.pairs.shape[0], 3, 3)),
                             jv=np.empty((self.pairs.shape[0], 3, 3)),
                             jx2=np.empty((self.pairs.shape[0], 3, 3)))

    def system_matrix(self, x: np.ndarray, xdir: np.ndarray, h: float) -> csr_matrix:
        """Assemble ``H = M/h^2 + K(x) + C(xdir)/h`` in place into the fixed-pattern CSR matrix.

        Parameters
        ----------
        x : (N, 3) array
            Positions (m) where the stiffness ``K = -df/dx`` (made definite) is evaluated.
        xdir : (N, 3) array
            Positions fixing the axial damping directions of ``C = -df/dv``.
        h : float
            Time step (s).

        Returns
        -------
        scipy.sparse.csr_matrix, (3N, 3N)
            The same object every call (its ``data`` is overwritten).
        """
        if self._pattern is None:
            self._build_pattern()
        p = self._pattern
        jx, jv = p["jx"], p["jv"]
        zero_v = np.zeros_like(x)
        mat = p["matrix"]
        with _threads(self.pairs.shape[0]):
            jacobian_blocks(x, zero_v, self.pairs, self.ke, self.rest, self.damping, self.mode,
                             True, False, jx, jv)
            if self.mode == 0 and xdir is not x:
                jacobian_blocks(xdir, zero_v, self.pairs, self.ke, self.rest, self.damping,
                                 self.mode, True, False, p["jx2"], jv)
            assemble_system(jx, jv, self.inc_ptr, self.inc_spring, self.inc_other, p["inc_slot"],
                      p["diag_slot"], p["bptr"], self.masses, self.pinned, float(h), self.drag,
                      mat.data)
        return mat

    def implicit_operator(self, x: np.ndarray, xdir: np.ndarray, h: float) -> BlockOperator:
        """The matrix ``H`` of :meth:`system_matrix`, matrix-free: per spring the 6 entries of
        the symmetric block ``K_s + C_s / h``, per particle ``(m/h^2 + drag/h) I`` (a
        :class:`filters.linalg.BlockOperator`; a product costs ~0.1 ms instead of ~0.5 ms for
        the CSR matrix on the 64x64 benchmark cloth).

        Same arguments and same matrix as :meth:`system_matrix`; the PCG solver of
        :mod:`filters.integrators` uses it (the CSR matrix remains for direct solves).  The
        returned object's arrays are reused (overwritten) by the next call.

        Returns
        -------
        filters.linalg.BlockOperator
        """
        if self._operator is None:
            # The operator keeps its springs in upper-incidence order (sorted by their lower
            # end point), which makes every sweep over them a sequential stream.
            n = self.n_points
            s = self.pairs.shape[0]
            lo = np.minimum(self.pairs[:, 0], self.pairs[:, 1])
            hi = np.maximum(self.pairs[:, 0], self.pairs[:, 1])
            order = np.lexsort((hi, lo))
            pairs = np.ascontiguousarray(np.stack([lo[order], hi[order]], axis=1))
            self._op_params = tuple(np.ascontiguousarray(a[order])
                                    for a in (self.ke, self.rest, self.damping))
            inc_ptr, inc_spring, _, inc_other = incidence(pairs, n)
            self._operator = BlockOperator(pairs, np.where(self.pinned, 0.0, 1.0),
                                            np.empty((s, 6)), np.empty((n, 3, 3)),
                                            inc_ptr, inc_spring, inc_other)
        op = self._operator
        ke, rest, damping = self._op_params
        operator_coefficients(x, xdir, op.pairs, ke, rest, damping, self.mode, float(h),
                               op.blocks)
        operator_diagonal(self.masses, self.pinned, float(h), self.drag, self._no_blocks,
                          op.diag)
        return op
