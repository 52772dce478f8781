"""Particles emitted in a box and advected by a velocity field, ``dx/dt = v(x, t)``.

:class:`NoiseAdvection` is a :class:`~filters.simulation.Simulation` whose particles carry no
inertia: they follow a velocity field from :mod:`filters.fields` (typically curl noise, Bridson,
Hourihan & Nordenstam 2007, plus a rising wind) with one of four integrators

* ``"euler"``: forward Euler, ``x += h v(x, t)`` (first order; spirals *out* of a rotation),
* ``"rk2"``: the explicit midpoint rule (second order),
* ``"rk4"``: the classical Runge-Kutta method (fourth order),
* ``"linearized_backward_euler"``: the linearised backward Euler step of Baraff & Witkin
  (1998), ``(I - h dv/dx) dx = h v(x, t + h)``, one 3x3 solve per particle with the field's
  analytic Jacobian (first order, unconditionally stable; spirals *in* a rotation).

Particles come from a :class:`BoxEmitter` (a rate in particles per second, lifetimes, birth
times jittered within the step so that the stream does not come out in layers), die when their
age exceeds their lifetime, and are pushed out of colliders (plane, sphere and spherical
container shapes of :mod:`filters.geometry`).  Per-particle ``size`` and
``color`` come from noise at the birth position (:func:`filters.noise.noise_variation`).

Everything random comes from a counter-based generator (SplitMix64; Steele, Lea & Flood 2014)
whose seed and counter live in the state (``extra["rng"]``), together with the emitter's
fractional particle carry and the next id, so a run restored from any checkpoint continues
bit-identically.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from .fields import Field, field_point, field_point_jacobian
from .geometry import pack_shapes, packed_distance
from .linalg.dense3 import implicit_step3
from .noise import noise_variation
from .simulation import Frame, OutputSpec, Simulation, SimulationUnstableError, State
from .validation import check_choice, check_finite_vector, check_int, check_range

if TYPE_CHECKING:
    from collections.abc import Sequence

    from numpy.typing import ArrayLike

    from .geometry import Shape

__all__ = ["BoxEmitter", "NoiseAdvection", "INTEGRATORS", "check_integrator"]

#: Names of the integrators, in the order of their kernel codes.
#: The names of :mod:`filters.integrators` where they are the same scheme; a full backward Euler
#: solve (``"backward_euler"``) is not offered for advection.
INTEGRATORS = ("euler", "rk2", "rk4", "linearized_backward_euler")


def check_integrator(name: str) -> str:
    """Return ``name`` if it is one of :data:`INTEGRATORS`, else ValueError (naming the current
    name of the former ``"backward_euler"`` of advection, ``"linearized_backward_euler"``)."""
    if name == "backward_euler":
        raise ValueError("integrator 'backward_euler' (a step solved to convergence) is not "
                         "offered for advection; the linearised step is "
                         "'linearized_backward_euler' (formerly 'backward_euler'); integrator "
                         f"must be one of {', '.join(map(repr, INTEGRATORS))}")
    return check_choice("integrator", name, INTEGRATORS)


# ---------------------------------------------------------------------------------------------
# Random numbers: counter-based SplitMix64
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _mix64(z):
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit(cache=True)
def _uniforms(seed, counter, count):
    """``count`` doubles in [0, 1): SplitMix64 outputs number ``counter, counter + 1, ...``."""
    out = np.empty(count)
    for k in range(count):
        z = seed + (counter + np.uint64(k + 1)) * np.uint64(0x9E3779B97F4A7C15)
        out[k] = np.float64(_mix64(z) >> np.uint64(11)) * (1.0 / 9007199254740992.0)
    return out


# ---------------------------------------------------------------------------------------------
# Integration kernels
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _vel(kinds, params, tables, colliders, x, y, z, t):
    return field_point(kinds, params, tables, colliders, x, y, z, 0.0, 0.0, 0.0, t)


@njit(parallel=True, cache=True)
def _advect(kinds, params, tables, colliders, pos, h, t0, method):
    """Advance every particle ``i`` from time ``t0[i]`` by ``h[i]`` in place.

    Returns the number of particles whose backward-Euler matrix was singular (0 otherwise).
    """
    bad = 0
    for i in prange(pos.shape[0]):
        hi = h[i]
        if hi <= 0.0:
            continue
        t = t0[i]
        x = pos[i, 0]
        y = pos[i, 1]
        z = pos[i, 2]
        if method == 0:
            a0, a1, a2 = _vel(kinds, params, tables, colliders, x, y, z, t)
            pos[i, 0] = x + hi * a0
            pos[i, 1] = y + hi * a1
            pos[i, 2] = z + hi * a2
        elif method == 1:
            a0, a1, a2 = _vel(kinds, params, tables, colliders, x, y, z, t)
            hh = 0.5 * hi
            b0, b1, b2 = _vel(kinds, params, tables, colliders, x + hh * a0, y + hh * a1,
                              z + hh * a2, t + hh)
            pos[i, 0] = x + hi * b0
            pos[i, 1] = y + hi * b1
            pos[i, 2] = z + hi * b2
        elif method == 2:
            hh = 0.5 * hi
            a0, a1, a2 = _vel(kinds, params, tables, colliders, x, y, z, t)
            b0, b1, b2 = _vel(kinds, params, tables, colliders, x + hh * a0, y + hh * a1,
                              z + hh * a2, t + hh)
            c0, c1, c2 = _vel(kinds, params, tables, colliders, x + hh * b0, y + hh * b1,
                              z + hh * b2, t + hh)
            d0, d1, d2 = _vel(kinds, params, tables, colliders, x + hi * c0, y + hi * c1,
                              z + hi * c2, t + hi)
            s = hi / 6.0
            pos[i, 0] = x + s * (a0 + 2.0 * b0 + 2.0 * c0 + d0)
            pos[i, 1] = y + s * (a1 + 2.0 * b1 + 2.0 * c1 + d1)
            pos[i, 2] = z + s * (a2 + 2.0 * b2 + 2.0 * c2 + d2)
        else:
            J = np.empty((3, 3))
            v0, v1, v2 = field_point_jacobian(kinds, params, tables, colliders, x, y, z, 0.0,
                                              0.0, 0.0, t + hi, J)
            # (I - h J) dx = h v by Cramer's rule
            x1, y1, z1, det = implicit_step3(J, hi, x, y, z, v0, v1, v2)
            if not (abs(det) > 1e-12):
                bad += 1
                continue
            pos[i, 0] = x1
            pos[i, 1] = y1
            pos[i, 2] = z1
    return bad


@njit(parallel=True, cache=True)
def _push_out(colliders, pos, margin):
    """Move particles closer than ``margin`` to a collider onto the ``d = margin`` surface."""
    for i in prange(pos.shape[0]):
        for _ in range(4):  # a few passes resolve corners between colliders
            d, nx, ny, nz, c = packed_distance(colliders, pos[i, 0], pos[i, 1], pos[i, 2])
            if c < 0 or d >= margin:
                break
            pos[i, 0] += (margin - d) * nx
            pos[i, 1] += (margin - d) * ny
            pos[i, 2] += (margin - d) * nz


@njit(parallel=True, cache=True)
def _velocities(kinds, params, tables, colliders, pos, t, out):
    for i in prange(pos.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = _vel(kinds, params, tables, colliders, pos[i, 0],
                                               pos[i, 1], pos[i, 2], t)


# ---------------------------------------------------------------------------------------------
# Emitter and simulation
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BoxEmitter:
    """Emits particles uniformly at random in an axis-aligned box.

    Parameters
    ----------
    lower, upper : sequence of 3 float
        Opposite corners of the box (m), ``lower <= upper`` componentwise (a flat box emits from
        a rectangle).
    rate : float
        Particles per second, >= 0.  Fractions carry over between steps.
    lifetime : float
        Mean lifetime (s), > 0.
    lifetime_jitter : float
        Lifetimes are uniform in ``lifetime * [1 - j, 1 + j]``, ``j`` in [0, 1).
    jitter : float
        In [0, 1]: the birth times of a step's particles are stratified over the last
        ``jitter * dt`` of the step and each newborn is advected for its age, so that a stream
        does not come out in layers one step apart.  0 gives every newborn the step's end time.
    """

    lower: tuple = (-0.5, -0.5, 0.0)
    upper: tuple = (0.5, 0.5, 0.1)
    rate: float = 1000.0
    lifetime: float = 2.0
    lifetime_jitter: float = 0.25
    jitter: float = 1.0

    def __post_init__(self):
        lower = check_finite_vector("lower", self.lower, 3)
        upper = check_finite_vector("upper", self.upper, 3)
        if np.any(upper < lower):
            raise ValueError(f"upper must be >= lower componentwise, got lower={lower.tolist()}, "
                             f"upper={upper.tolist()}")
        object.__setattr__(self, "lower", tuple(lower.tolist()))
        object.__setattr__(self, "upper", tuple(upper.tolist()))
        object.__setattr__(self, "rate", check_range("rate", self.rate, 0.0, math.inf))
        object.__setattr__(self, "lifetime", check_range("lifetime", self.lifetime, 0.0, math.inf,
                                                         low_inclusive=False))
        object.__setattr__(self, "lifetime_jitter", check_range(
            "lifetime_jitter", self.lifetime_jitter, 0.0, 1.0, high_inclusive=False))
        object.__setattr__(self, "jitter", check_range("jitter", self.jitter, 0.0, 1.0))


@dataclass(frozen=True)
class AdvectionModel:
    """Fixed parameters of :class:`NoiseAdvection` (see there); ``colliders`` packed (C, 8)."""

    field: Field
    emitter: BoxEmitter | None
    integrator: str
    colliders: np.ndarray
    collider_margin: float
    max_particles: int
    size_range: tuple
    color_range: tuple
    variation_frequency: float
    seed: int


class NoiseAdvection(Simulation):
    """Massless particles emitted in a box and advected through a velocity field.

    Parameters
    ----------
    field : filters.fields.Field
        Velocity field ``v(x, t)`` (m/s); velocity-dependent terms see zero velocity.
    emitter : BoxEmitter, optional
        Source of new particles; ``None`` for a fixed set.
    positions : (M, 3) array_like, optional
        Particles present at t = 0 (m); they live forever unless ``initial_lifetime`` is given.
    initial_lifetime : float
        Lifetime (s) of the initial particles, > 0 (default: infinite).
    integrator : {"euler", "rk2", "rk4", "linearized_backward_euler"}
        Time integrator (see the module docstring).
    colliders : Shape or sequence of filters.geometry.Plane / Sphere / ~Sphere
        Solids the particles are pushed out of after each step (to ``collider_margin``).  Give
        the same colliders to a :class:`~filters.fields.CurlNoise` with a
        ``ramp_distance`` to make the flow itself go around them.
    collider_margin : float
        Distance (m) >= 0 kept from collider surfaces.
    max_dt : float
        Largest step (s) :meth:`advance_to` takes, > 0.
    max_particles : int
        Emission stops while this many particles are alive, >= 1.
    size_range, color_range : pair of float
        Ranges of the per-particle ``size`` (m) and ``color`` (scalar) point arrays, drawn from
        noise at the birth position.
    variation_frequency : float
        Frequency (1/m) of that noise, > 0.
    seed : int
        Seed of the emitter's random numbers and of the variation noise, in [0, 2**63).

    Notes
    -----
    The state holds ``positions``, ``velocities`` (the field at each particle, m/s) and the
    extra arrays ``id`` (int64), ``age`` (s), ``lifetime`` (s), ``size``, ``color``, ``rng``
    (uint64 seed and counter), ``carry`` (fractional particles owed by the emitter) and
    ``next_id``.  Frames carry the point arrays ``velocity``, ``id``, ``age``, ``size`` and
    ``color``.  Particles stay in ``id`` order: the newborn of a step get the next ids (from
    ``next_id``, so ids are never reused) and are appended, the dead are removed without
    reordering the others, so frames list the survivors of the previous frame in their order,
    then the newborn.
    """

    variable_count = True
    instability_hint = "the velocity field is too strong for the step, or its Jacobian is singular"

    def __init__(self, field: Field, emitter: BoxEmitter | None = None, *,
                 positions: ArrayLike | None = None, initial_lifetime: float = math.inf,
                 integrator: str = "rk4", colliders: Shape | Sequence[Shape] = (),
                 collider_margin: float = 0.0, max_dt: float = 1.0 / 60.0,
                 max_particles: int = 1_000_000, size_range: tuple[float, float] = (1.0, 1.0),
                 color_range: tuple[float, float] = (0.0, 1.0), variation_frequency: float = 1.0,
                 seed: int = 0):
        if not isinstance(field, Field):
            raise TypeError(f"field must be a filters.fields.Field, got {type(field).__name__}")
        if emitter is not None and not isinstance(emitter, BoxEmitter):
            raise TypeError(f"emitter must be a BoxEmitter or None, got {type(emitter).__name__}")
        check_integrator(integrator)
        check_range("initial_lifetime", initial_lifetime, 0.0, math.inf, low_inclusive=False)
        check_range("collider_margin", collider_margin, 0.0, math.inf)
        self.max_dt = check_range("max_dt", max_dt, 0.0, math.inf, low_inclusive=False)
        check_int("max_particles", max_particles, 1)
        size_range = tuple(check_finite_vector("size_range", size_range, 2).tolist())
        color_range = tuple(check_finite_vector("color_range", color_range, 2).tolist())
        for name, rng in (("size_range", size_range), ("color_range", color_range)):
            if rng[1] < rng[0]:
                raise ValueError(f"{name} must be (low, high) with low <= high, got {rng}")
        check_range("variation_frequency", variation_frequency, 0.0, math.inf,
                    low_inclusive=False)
        seed = check_int("seed", seed, 0, (1 << 63) - 1)
        packed_colliders = pack_shapes(colliders)
        self.model = AdvectionModel(field, emitter, integrator, packed_colliders,
                                    float(collider_margin), int(max_particles), size_range,
                                    color_range, float(variation_frequency), seed)
        self._packed = field.packed
        self._colliders = packed_colliders
        self._method = INTEGRATORS.index(integrator)

        if positions is None:
            positions = np.zeros((0, 3))
        state = State(positions)
        n = state.n_points
        if n > max_particles:
            raise ValueError(f"positions has {n} rows, more than max_particles = {max_particles}")
        ids = np.arange(n, dtype=np.int64)
        state.extra = {
            "id": ids,
            "age": np.zeros(n),
            "lifetime": np.full(n, float(initial_lifetime)),
            "size": noise_variation(state.positions, *size_range, ids=ids,
                                    frequency=variation_frequency, seed=seed),
            "color": noise_variation(state.positions, *color_range, ids=ids,
                                     frequency=variation_frequency, seed=seed + 1),
            "rng": np.array([seed, 0], dtype=np.uint64),
            "carry": np.zeros(1),
            "next_id": np.array([n], dtype=np.int64),
        }
        self.state = state
        if n and packed_colliders.shape[0]:
            _push_out(self._colliders, state.positions, self.model.collider_margin)
        self._update_velocities()

    # -- protocol ------------------------------------------------------------------------------
    @property
    def output_spec(self) -> OutputSpec:
        return OutputSpec(point_arrays=(("velocity", 3), ("id", 1), ("age", 1), ("size", 1),
                                        ("color", 1)),
                          topology="vertices", fixed_topology=False)

    def frame(self) -> Frame:
        s = self.state
        return Frame(time=s.time, points=s.positions.copy(), point_data={
            "velocity": s.velocities.copy(),
            "id": s.extra["id"].copy(),
            "age": s.extra["age"].copy(),
            "size": s.extra["size"].copy(),
            "color": s.extra["color"].copy(),
        })

    def set_state(self, state: State) -> None:
        missing = {"id", "age", "lifetime", "size", "color", "rng", "carry", "next_id"} - set(
            state.extra)
        if missing:
            raise ValueError(f"state lacks the extra arrays {sorted(missing)} of NoiseAdvection")
        super().set_state(state)

    # -- stepping -------------------------------------------------------------------------------
    def _update_velocities(self):
        s = self.state
        p = self._packed
        vel = np.empty((s.n_points, 3))
        _velocities(p.kinds, p.params, p.tables, p.colliders, s.positions, s.time, vel)
        s.velocities = vel

    def _advance(self, pos, h, t0):
        p = self._packed
        bad = _advect(p.kinds, p.params, p.tables, p.colliders, pos, h, t0, self._method)
        if bad:
            raise SimulationUnstableError(
                self.state.time, "backward Euler matrix I - h dv/dx",
                f"singular for {bad} particles; reduce the step")

    def _step(self, dt: float) -> None:
        s = self.state
        m = self.model
        t = s.time
        ex = s.extra
        pos = s.positions
        # 1. advect the living particles over [t, t + dt]
        if pos.shape[0]:
            self._advance(pos, np.full(pos.shape[0], dt), np.full(pos.shape[0], t))
        age = ex["age"] + dt
        alive = age < ex["lifetime"]
        keep = {k: ex[k][alive] for k in ("id", "lifetime", "size", "color")}
        pos = pos[alive]
        age = age[alive]
        # 2. emit: stratified birth times over the last jitter * dt of the step
        e = m.emitter
        new = None
        if e is not None and e.rate > 0.0:
            carry = float(ex["carry"][0]) + e.rate * dt
            n_new = int(math.floor(carry))
            carry -= n_new
            n_new = max(0, min(n_new, m.max_particles - pos.shape[0]))
            ex["carry"] = np.array([carry])
            if n_new:
                # (a checkpoint read back from disk may carry the counter as another integer
                # type: the same bits as uint64 keep the stream identical)
                rng = np.asarray(ex["rng"]).astype(np.uint64)
                u = _uniforms(rng[0], rng[1], 5 * n_new).reshape(n_new, 5)
                ex["rng"] = np.array([rng[0], rng[1] + np.uint64(5 * n_new)], dtype=np.uint64)
                lower = np.array(e.lower)
                upper = np.array(e.upper)
                p_new = lower + u[:, :3] * (upper - lower)
                born_age = e.jitter * dt * (np.arange(n_new) + u[:, 3]) / n_new
                life = e.lifetime * (1.0 + e.lifetime_jitter * (2.0 * u[:, 4] - 1.0))
                self._advance(p_new, born_age.copy(), t + dt - born_age)
                next_id = int(ex["next_id"][0])
                ids = np.arange(next_id, next_id + n_new, dtype=np.int64)
                ex["next_id"] = np.array([next_id + n_new], dtype=np.int64)
                birth = lower + u[:, :3] * (upper - lower)
                new = {
                    "pos": p_new, "age": born_age, "id": ids, "lifetime": life,
                    "size": noise_variation(birth, *m.size_range, ids=ids,
                                            frequency=m.variation_frequency, seed=m.seed),
                    "color": noise_variation(birth, *m.color_range, ids=ids,
                                             frequency=m.variation_frequency, seed=m.seed + 1),
                }
        if new is not None:
            pos = np.concatenate([pos, new["pos"]])
            age = np.concatenate([age, new["age"]])
            for k in keep:
                keep[k] = np.concatenate([keep[k], new[k]])
        pos = np.ascontiguousarray(pos)
        if self._colliders.shape[0] and pos.shape[0]:
            _push_out(self._colliders, pos, m.collider_margin)
        s.positions = pos
        ex["age"] = age
        ex.update(keep)
        p = self._packed
        vel = np.empty((pos.shape[0], 3))
        _velocities(p.kinds, p.params, p.tables, p.colliders, pos, t + dt, vel)
        s.velocities = vel
