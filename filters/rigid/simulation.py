"""Rigid bodies under gravity and applied forces, in contact with colliders and each other.

:class:`RigidBodies` follows the protocol of :mod:`filters.simulation`: its model
(:class:`RigidModel`: the bodies, gravity, colliders, solver settings) is fixed; its
:class:`~filters.simulation.State` holds per body the centre of mass (``positions``, (B, 3)),
the velocity (``velocities``), and in ``extra`` the orientation (``"orientations"``, (B, 4) unit
quaternions ``(w, x, y, z)``), the world angular velocity (``"angular_velocities"``, rad/s) and
the contact impulses of the last step that warm-start the next (``"contact_keys"``,
``"contact_impulses"``), so that a state restored from a checkpoint continues bit for bit.

One step of ``h`` (``symplectic_euler``, the default): the forces (gravity, and those applied
with :meth:`RigidBodies.apply_force` / :meth:`~RigidBodies.apply_point_forces` since the last
step) kick the velocities; contacts found at the current positions
(:func:`filters.rigid.contact.find_contacts`) get their impulses with Coulomb friction and
restitution (:func:`filters.rigid.impulses.solve_velocities`) and their overlaps a separating
push (:func:`~filters.rigid.impulses.solve_positions`); the drift then moves the bodies with the
new velocities (:func:`filters.rigid.dynamics.drift`).  ``euler`` drifts with the velocities of
the start of the step (for comparison; contacts can then overlap for a step).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..elastic.contact import Colliders
from ..elastic.energy import EnergyAccount
from ..elastic.threads import serial_below
from ..integrators import check_scheme
from ..simulation import Frame, OutputSpec, Simulation, SimulationUnstableError, State
from ..validation import check_finite_vector, check_int, check_points, check_range
from .body import RigidBody
from .contact import broad_phase, find_contacts, pack_colliders
from .dynamics import (
    PARALLEL_MIN_POINTS,
    body_rotations,
    drift,
    kick,
    point_force_sums,
    points_to_world,
    world_inverse_inertia,
)
from .impulses import solve_positions, solve_velocities
from .quaternion import check_quaternions
from .sdf import pack_sdfs

if TYPE_CHECKING:
    from collections.abc import Sequence

    from numpy.typing import ArrayLike, NDArray

__all__ = ["RigidModel", "RigidBodies", "SCHEMES", "BODY_FIELDS"]

#: Integration schemes of rigid bodies (names of :data:`filters.integrators.SCHEMES`).
SCHEMES = ("symplectic_euler", "euler")

#: Field-data arrays of a frame that describe the bodies, one row per body.
BODY_FIELDS = (("body_position", 3), ("body_orientation", 4), ("body_translation", 3),
               ("body_velocity", 3), ("body_angular_velocity", 3))


@dataclass(frozen=True)
class RigidModel:
    """Fixed parameters of :class:`RigidBodies`.

    Attributes
    ----------
    bodies : tuple of RigidBody
    gravity : tuple of 3 float
        Acceleration (m/s^2).
    colliders : Colliders or None
        The static obstacles (as given; packed once at construction).
    scheme : str
        One of :data:`SCHEMES`.
    iterations : int
        Largest number of Gauss-Seidel sweeps of each contact solve.
    slop : float
        Overlap (m) left alone, and the margin within which contacts are kept.
    separation_rate : float
        Fraction of a deeper overlap removed per step.
    rest_speed : float
        Approach speed (m/s) below which contacts are inelastic (at least twice what the
        forces of one step add).
    max_speed : float
        Speed (m/s) of a body, or of a point of it, above which the simulation is unstable.
    """

    bodies: tuple
    gravity: tuple
    colliders: object
    scheme: str
    iterations: int
    slop: float
    separation_rate: float
    rest_speed: float
    max_speed: float


def _body_rows(name, value, n, default):
    if value is None:
        return np.array(default, dtype=np.float64).reshape(n, 3)
    array = check_points(name, value)
    if array.shape[0] != n:
        raise ValueError(f"{name} must have {n} rows (one per body), got {array.shape[0]}")
    return array.copy()


class RigidBodies(Simulation):
    """Rigid bodies with contacts, friction and restitution (see the module docstring).

    Parameters
    ----------
    bodies : sequence of RigidBody
        At least one.
    positions : (B, 3) array_like, optional
        Initial centres of mass (m); by default each body's :attr:`RigidBody.center`, i.e. the
        mesh where it was given.
    orientations : (B, 4) array_like, optional
        Initial unit quaternions ``(w, x, y, z)`` (normalised here); identity by default.
    velocities, angular_velocities : (B, 3) array_like, optional
        Initial velocities (m/s) and world angular velocities (rad/s); zero by default (and
        always zero for fixed bodies).
    gravity : sequence of 3 float
        Acceleration (m/s^2).
    colliders : filters.elastic.contact.Colliders, optional
        Static obstacles; their restitution and friction mix with the bodies'
        (``max(e)``, ``sqrt(mu mu')``, Catto's Box2D rules).
    scheme : {"symplectic_euler", "euler"}
        Time integration (:mod:`filters.rigid.dynamics`).
    max_dt : float
        Largest step (s) of :meth:`advance_to`, > 0.
    iterations : int
        Largest number of Gauss-Seidel sweeps per contact solve, in [1, 10000].
    slop : float
        Overlap (m) tolerated without a push, >= 0 (and the extra margin of contacts).
    separation_rate : float
        Fraction of a deeper overlap removed per step, in (0, 1].
    rest_speed : float
        Approach speed (m/s) below which a contact does not bounce, >= 0.
    max_speed : float
        Any body or surface point faster than this (m/s) raises
        :class:`~filters.simulation.SimulationUnstableError`.

    Notes
    -----
    Forces given with :meth:`apply_force`, :meth:`apply_torque` or :meth:`apply_point_forces`
    act during the next :meth:`step` only, then are cleared; they are not part of the state.
    """

    instability_hint = ("a body was driven too hard for this time step: reduce max_dt or the "
                        "applied forces")

    def __init__(self, bodies: Sequence[RigidBody], positions: ArrayLike | None = None,
                 orientations: ArrayLike | None = None, velocities: ArrayLike | None = None,
                 angular_velocities: ArrayLike | None = None, *,
                 gravity: ArrayLike = (0.0, 0.0, -9.81), colliders: Colliders | None = None,
                 scheme: str = "symplectic_euler", max_dt: float = 1.0 / 240.0,
                 iterations: int = 200, slop: float = 1e-4, separation_rate: float = 0.2,
                 rest_speed: float = 1e-2, max_speed: float = 100.0):
        bodies = tuple(bodies) if not isinstance(bodies, RigidBody) else (bodies,)
        if not bodies:
            raise ValueError("bodies must hold at least one RigidBody")
        for i, b in enumerate(bodies):
            if not isinstance(b, RigidBody):
                raise TypeError(f"bodies[{i}] must be a RigidBody, got {type(b).__name__}")
        n = len(bodies)
        gravity = check_finite_vector("gravity", gravity, 3)
        if colliders is not None and not isinstance(colliders, Colliders):
            raise TypeError(f"colliders must be a filters.elastic.contact.Colliders, got "
                            f"{type(colliders).__name__}")
        check_scheme(scheme, SCHEMES)
        self.max_dt = check_range("max_dt", max_dt, 0.0, math.inf, low_inclusive=False,
                                  high_inclusive=False)
        iterations = check_int("iterations", iterations, 1, 10000)
        slop = check_range("slop", slop, 0.0, math.inf, high_inclusive=False)
        separation_rate = check_range("separation_rate", separation_rate, 0.0, 1.0,
                                      low_inclusive=False)
        rest_speed = check_range("rest_speed", rest_speed, 0.0, math.inf, high_inclusive=False)
        max_speed = check_range("max_speed", max_speed, 0.0, math.inf, low_inclusive=False)
        x = _body_rows("positions", positions, n, [b.center for b in bodies])
        v = _body_rows("velocities", velocities, n, np.zeros((n, 3)))
        w = _body_rows("angular_velocities", angular_velocities, n, np.zeros((n, 3)))
        q = (np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)) if orientations is None
             else check_quaternions("orientations", orientations, n))
        self.model = RigidModel(bodies, tuple(float(g) for g in gravity), colliders, scheme,
                                iterations, slop, separation_rate, rest_speed, max_speed)
        # packed, read-only arrays of the bodies
        self._fixed = np.array([b.fixed for b in bodies], dtype=np.bool_)
        v[self._fixed] = 0.0
        w[self._fixed] = 0.0
        self._mass = np.array([b.mass for b in bodies])
        self._inv_mass = np.where(self._fixed, 0.0, 1.0 / self._mass)
        self._inv_inertia = np.array([np.linalg.inv(b.inertia) for b in bodies])
        self._moments = np.array([b.principal_moments for b in bodies])
        self._principal = np.array([b.principal_rotation for b in bodies])
        self._radius = np.array([b.radius for b in bodies])
        self._restitution = np.array([b.restitution for b in bodies])
        self._friction = np.array([b.friction for b in bodies])
        self._gravity = np.asarray(gravity, dtype=np.float64)
        counts = np.array([b.contact_points.shape[0] for b in bodies])
        self._contact_points = np.ascontiguousarray(np.concatenate([b.contact_points
                                                                    for b in bodies]))
        self._owner = np.repeat(np.arange(n), counts).astype(np.int64)
        self._local = (np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
                       ).astype(np.int64)
        self._n_local = int(counts.max())
        self._colliders = pack_colliders(colliders)
        self._has_colliders = self._colliders[-1].size > 0 and not self._fixed.all()
        self._sdfs = pack_sdfs([b.sdf for b in bodies])
        vcounts = np.array([b.vertices.shape[0] for b in bodies])
        self._vertices = np.ascontiguousarray(np.concatenate([b.vertices for b in bodies]))
        self._vertex_body = np.repeat(np.arange(n), vcounts).astype(np.int64)
        first = np.cumsum(vcounts) - vcounts
        self._triangles = np.concatenate([b.faces + first[i] for i, b in enumerate(bodies)])
        samples = [b.samples for b in bodies]
        self._samples = np.ascontiguousarray(np.concatenate(
            [s.points if s is not None else np.zeros((0, 3)) for s in samples]))
        self._sample_volumes = np.concatenate(
            [s.volumes if s is not None else np.zeros(0) for s in samples])
        self._sample_body = np.repeat(np.arange(n), [0 if s is None else s.n_points
                                                     for s in samples]).astype(np.int64)
        for a in (self._fixed, self._mass, self._inv_mass, self._inv_inertia, self._moments,
                  self._principal, self._radius, self._restitution, self._friction,
                  self._gravity, self._contact_points, self._owner, self._local,
                  self._vertices, self._vertex_body, self._triangles, self._samples,
                  self._sample_volumes, self._sample_body):
            a.setflags(write=False)
        self.state = State(x, v, extra={
            "orientations": q, "angular_velocities": w,
            "contact_keys": np.zeros(0, dtype=np.int64), "contact_impulses": np.zeros((0, 4))})
        self._pending = np.zeros((n, 6))
        self.last_contacts = 0
        self.last_sweeps = 0

    # -- applied forces ---------------------------------------------------------------------
    @property
    def n_bodies(self) -> int:
        """Number of bodies ``B``."""
        return len(self.model.bodies)

    def _body_index(self, body) -> int:
        return check_int("body", body, 0, self.n_bodies - 1)

    def apply_force(self, body: int, force: ArrayLike, point: ArrayLike | None = None) -> None:
        """Apply ``force`` (3,) (N) to ``body`` for the next step, at the world ``point`` (m)
        (which adds the torque ``(point - x) x force``) or at the centre of mass."""
        b = self._body_index(body)
        f = check_finite_vector("force", force, 3)
        self._pending[b, :3] += f
        if point is not None:
            r = check_finite_vector("point", point, 3) - self.state.positions[b]
            self._pending[b, 3:] += np.cross(r, f)

    def apply_torque(self, body: int, torque: ArrayLike) -> None:
        """Apply ``torque`` (3,) (N m, world) to ``body`` for the next step."""
        b = self._body_index(body)
        self._pending[b, 3:] += check_finite_vector("torque", torque, 3)

    def apply_wrenches(self, wrenches: ArrayLike) -> None:
        """Apply a force (N) and a torque (N m, world, about the centre of mass) to every body
        for the next step, ``wrenches`` (B, 6): force then torque per row."""
        w = np.asarray(wrenches, dtype=np.float64)
        if w.shape != (self.n_bodies, 6) or not np.isfinite(w).all():
            raise ValueError(f"wrenches must be a finite ({self.n_bodies}, 6) array, "
                             f"got shape {w.shape}")
        self._pending += w

    def apply_point_forces(self, points: ArrayLike, forces: ArrayLike,
                           bodies: ArrayLike) -> np.ndarray:
        """Apply forces at many points for the next step (a liquid's forces on the samples).

        Parameters
        ----------
        points : (N, 3) array_like
            World points of application (m).
        forces : (N, 3) array_like
            Forces (N).
        bodies : int or (N,) array_like of int
            The body of every point (or one body for all), in ``[0, B)``.

        Returns
        -------
        (B, 6) float64 array
            What was added: total force (N) and torque about the centre of mass (N m) per body
            (:func:`filters.rigid.dynamics.point_force_sums`).
        """
        p = check_points("points", points)
        f = check_points("forces", forces)
        if f.shape != p.shape:
            raise ValueError(f"forces must have the shape of points {p.shape}, got {f.shape}")
        if isinstance(bodies, (int, np.integer)) and not isinstance(bodies, bool):
            idx = np.full(p.shape[0], self._body_index(bodies), dtype=np.int64)
        else:
            idx = np.asarray(bodies)
            if idx.shape != (p.shape[0],) or not np.issubdtype(idx.dtype, np.integer):
                raise ValueError(f"bodies must be an integer or ({p.shape[0]},) integers")
            if idx.size and (idx.min() < 0 or idx.max() >= self.n_bodies):
                raise ValueError(f"bodies must be in [0, {self.n_bodies - 1}]")
            idx = np.ascontiguousarray(idx, dtype=np.int64)
        sums = point_force_sums(p, f, idx, self.state.positions)
        self._pending += sums
        return sums

    def clear_forces(self) -> None:
        """Forget the forces applied since the last step."""
        self._pending[:] = 0.0

    def inverse_masses(self) -> tuple[np.ndarray, np.ndarray]:
        """Inverse masses (B,) (1/kg) and world inverse inertia tensors ``R I^-1 R^T`` (B, 3, 3)
        (1/(kg m^2)) at the bodies' orientations now; zero for fixed bodies."""
        inv_i = np.empty((self.n_bodies, 3, 3))
        world_inverse_inertia(self._rotations(), self._inv_inertia, self._fixed, inv_i)
        return self._inv_mass.copy(), inv_i

    # -- stepping ---------------------------------------------------------------------------
    def _rotations(self, orientations=None):
        q = self.state.extra["orientations"] if orientations is None else orientations
        r = np.empty((q.shape[0], 3, 3))
        body_rotations(np.ascontiguousarray(q), r)
        return r

    def _step(self, h: float) -> None:
        m = self.model
        s = self.state
        x = s.positions
        q = s.extra["orientations"]
        w = s.extra["angular_velocities"]
        rot = self._rotations()
        inv_i = np.empty_like(rot)
        world_inverse_inertia(rot, self._inv_inertia, self._fixed, inv_i)
        v1 = np.empty_like(x)
        w1 = np.empty_like(x)
        pending, self._pending = self._pending, np.zeros_like(self._pending)
        kick(s.velocities, w, self._inv_mass, inv_i, np.ascontiguousarray(pending[:, :3]),
             np.ascontiguousarray(pending[:, 3:]), self._gravity, h, self._fixed, v1, w1)
        dv = v1 - s.velocities
        threshold = np.maximum(m.rest_speed, 2.0 * np.sqrt(np.einsum("ij,ij->i", dv, dv)))
        speed = (np.sqrt(np.einsum("ij,ij->i", v1, v1))
                 + np.sqrt(np.einsum("ij,ij->i", w1, w1)) * self._radius)
        margin = np.where(self._fixed, 0.0, h * speed) + m.slop
        pairs = broad_phase(x, self._radius, margin, self._fixed)
        if self._has_colliders or pairs.any():
            ints, floats = find_contacts(self._contact_points, self._owner, self._local, x, rot,
                                         v1, w1, self._fixed, self._radius, margin,
                                         self._colliders, self._restitution, self._friction,
                                         self._sdfs, pairs, m.slop, m.slop / h, self._n_local)
        else:
            ints, floats = np.zeros((0, 3), dtype=np.int64), np.zeros((0, 9))
        v_push = np.zeros_like(x)
        w_push = np.zeros_like(x)
        k = ints.shape[0]
        impulses = np.zeros((k, 4))
        self.last_sweeps = 0
        if k:
            warm = np.zeros((k, 4))
            keys = s.extra["contact_keys"]
            if keys.size:
                at = np.minimum(np.searchsorted(keys, ints[:, 2]), keys.size - 1)
                hit = keys[at] == ints[:, 2]
                warm[hit] = s.extra["contact_impulses"][at[hit]]
            self.last_sweeps = solve_velocities(ints, floats, x, v1, w1, self._inv_mass, inv_i,
                                                warm, threshold, h, m.iterations, impulses)
            solve_positions(ints, floats, x, self._inv_mass, inv_i, m.slop, m.separation_rate,
                            h, m.iterations, v_push, w_push)
        self.last_contacts = k
        held = impulses[:, 0] > 0.0
        order = np.argsort(ints[held, 2], kind="stable")
        s.extra["contact_keys"] = np.ascontiguousarray(ints[held, 2][order])
        s.extra["contact_impulses"] = np.ascontiguousarray(impulses[held][order])
        w_new = np.empty_like(x)
        if m.scheme == "euler":
            v_drift, w_drift = s.velocities.copy(), w.copy()
        else:
            v_drift, w_drift = v1, w1
        drift(x, q, v_drift, w_drift, w1, v_push, w_push, self._moments, self._principal,
              self._fixed, h, w_new)
        s.velocities[:] = v1
        w[:] = w_new
        self._check_speed(s.time + h)

    def _check_speed(self, time):
        s = self.state
        w = s.extra["angular_velocities"]
        q = s.extra["orientations"]
        if not (np.isfinite(s.positions).all() and np.isfinite(q).all()
                and np.isfinite(s.velocities).all() and np.isfinite(w).all()):
            raise SimulationUnstableError(time, "non-finite body position or velocity",
                                          self.instability_hint)
        speed = (np.sqrt(np.einsum("ij,ij->i", s.velocities, s.velocities))
                 + np.sqrt(np.einsum("ij,ij->i", w, w)) * self._radius)
        worst = float(speed.max())
        if not worst <= self.model.max_speed:
            raise SimulationUnstableError(
                time, f"body {int(speed.argmax())} moves at up to {worst:.3g} m/s > max_speed "
                f"{self.model.max_speed:g}", self.instability_hint)

    def check_finite(self) -> None:
        """Raise :class:`SimulationUnstableError` if any part of the state is not finite."""
        super().check_finite()
        for name in ("orientations", "angular_velocities"):
            if not np.isfinite(self.state.extra[name]).all():
                raise SimulationUnstableError(self.state.time, f"non-finite {name}",
                                              self.instability_hint)

    def set_state(self, state: State) -> None:
        """Restore a state (copied) of this simulation, e.g. a checkpoint; checked first.

        Raises
        ------
        ValueError
            If its shapes do not match, an orientation is not a unit quaternion, or the
            contact cache is inconsistent.
        """
        if not isinstance(state, State):
            raise TypeError(f"state must be a State, got {type(state).__name__}")
        n = self.n_bodies
        if state.positions.shape != (n, 3):
            raise ValueError(f"state has {state.n_points} bodies, this simulation has {n}")
        missing = {"orientations", "angular_velocities", "contact_keys",
                   "contact_impulses"} - set(state.extra)
        if missing:
            raise ValueError(f"state is missing the extra arrays {sorted(missing)}")
        state = state.copy()
        extra = state.extra
        extra["orientations"] = check_quaternions(
            "orientations", np.asarray(extra["orientations"]).reshape(-1, 4), n,
            normalize=False)
        w = np.asarray(extra["angular_velocities"], dtype=np.float64).reshape(-1, 3)
        extra["angular_velocities"] = _body_rows("angular_velocities", w, n, None)
        keys = np.ascontiguousarray(extra["contact_keys"], dtype=np.int64).ravel()
        imp = np.ascontiguousarray(extra["contact_impulses"], dtype=np.float64).reshape(-1, 4)
        if imp.shape[0] != keys.size or (keys.size > 1 and (np.diff(keys) <= 0).any()):
            raise ValueError("contact_keys must be increasing with one row of contact_impulses "
                             "each")
        extra["contact_keys"] = keys
        extra["contact_impulses"] = imp
        self.state = state
        self._pending[:] = 0.0

    # -- output -----------------------------------------------------------------------------
    def to_world(self, points: ArrayLike, bodies: ArrayLike) -> NDArray[np.float64]:
        """World positions and velocities of body-frame points for the current state.

        Parameters
        ----------
        points : (N, 3) array_like
            Points in their bodies' frames (m).
        bodies : (N,) array_like of int
            Their bodies, in ``[0, B)``.

        Returns
        -------
        positions, velocities : (N, 3) float64 arrays
            ``x_b + R_b X`` (m) and ``v_b + w_b x (R_b X)`` (m/s).
        """
        p = check_points("points", points)
        idx = np.ascontiguousarray(bodies, dtype=np.int64)
        if idx.shape != (p.shape[0],):
            raise ValueError(f"bodies must have shape ({p.shape[0]},), got {idx.shape}")
        if idx.size and (idx.min() < 0 or idx.max() >= self.n_bodies):
            raise ValueError(f"bodies must be in [0, {self.n_bodies - 1}]")
        s = self.state
        out_x = np.empty_like(p)
        out_v = np.empty_like(p)
        if p.shape[0]:
            with serial_below(p.shape[0], PARALLEL_MIN_POINTS):
                points_to_world(p, idx, s.positions, self._rotations(), s.velocities,
                                np.ascontiguousarray(s.extra["angular_velocities"]), out_x,
                                out_v)
        return out_x, out_v

    def surface_samples(self) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
        """The bodies' samples (:attr:`RigidBody.samples`, their outer layers) for the current
        state.

        Returns
        -------
        positions, velocities : (S, 3) float64 arrays
            World positions (m) and velocities ``v + w x r`` (m/s).
        bodies : (S,) int64 array
            Body of every sample.
        volumes : (S,) float64 array
            Their SPH volumes (m^3), fixed.
        """
        x, v = self.to_world(self._samples, self._sample_body)
        return x, v, self._sample_body, self._sample_volumes

    @property
    def output_spec(self) -> OutputSpec:
        return OutputSpec(point_arrays=(("velocity", 3), ("id", 1), ("body", 1)),
                          topology="polys", fixed_topology=True)

    def frame(self) -> Frame:
        """All bodies' meshes where they are: points (M, 3), point data ``velocity`` (m/s),
        ``id`` and ``body``; triangles; field data: per body (B rows) its centre of mass
        ``body_position``, orientation ``body_orientation`` (w, x, y, z), the translation of its
        mesh ``body_translation`` (``x = R(q) X + t`` for the mesh as given), velocity and
        angular velocity, then the energy account and ``contact_count`` (the contacts that pushed
        in the last step)."""
        s = self.state
        x, v = self.to_world(self._vertices, self._vertex_body)
        q = s.extra["orientations"]
        rot = self._rotations()
        translation = s.positions - np.einsum("bij,bj->bi", rot,
                                              np.array([b.center for b in self.model.bodies]))
        tri = self._triangles
        field = {"body_position": s.positions.copy(), "body_orientation": q.copy(),
                 "body_translation": translation, "body_velocity": s.velocities.copy(),
                 "body_angular_velocity": s.extra["angular_velocities"].copy()}
        field.update(self.energies().field_data())
        field["contact_count"] = np.array([s.extra["contact_keys"].size], dtype=np.int64)
        return Frame(time=s.time, points=x,
                     point_data={"velocity": v, "id": np.arange(x.shape[0], dtype=np.int64),
                                 "body": self._vertex_body.copy()},
                     connectivity=(np.arange(0, 3 * tri.shape[0] + 1, 3, dtype=np.int64),
                                   tri.ravel().copy()),
                     field_data=field)

    # -- diagnostics ------------------------------------------------------------------------
    def _angular_momenta(self):
        """World angular momenta ``I_w w`` about each centre of mass, (B, 3)."""
        rot = self._rotations()
        inertia = np.array([b.inertia for b in self.model.bodies])
        world = np.einsum("bij,bjk,blk->bil", rot, inertia, rot)
        return np.einsum("bij,bj->bi", world, self.state.extra["angular_velocities"])

    def energies(self) -> EnergyAccount:
        """Energy account (J) of the moving bodies: kinetic (translation and rotation) and
        gravitational (``-m g . x``); no elastic or contact energy is stored.  Fixed bodies
        are left out."""
        s = self.state
        free = ~self._fixed
        m = self._mass[free]
        v = s.velocities[free]
        spin = self._angular_momenta()[free]
        w = s.extra["angular_velocities"][free]
        kinetic = 0.5 * float(np.einsum("i,ij,ij->", m, v, v) + np.einsum("ij,ij->", spin, w))
        gravitational = -float(np.einsum("i,ij,j->", m, s.positions[free], self._gravity))
        return EnergyAccount(kinetic, gravitational, 0.0, 0.0)

    def energy(self) -> float:
        """Total energy (J) of the current state (:meth:`energies`)."""
        return self.energies().total

    def momentum(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Total linear momentum (kg m/s) and angular momentum about the origin (kg m^2/s) of
        the moving bodies, each (3,)."""
        s = self.state
        free = ~self._fixed
        p = self._mass[free, None] * s.velocities[free]
        spin = self._angular_momenta()[free]
        return p.sum(axis=0), (np.cross(s.positions[free], p) + spin).sum(axis=0)
