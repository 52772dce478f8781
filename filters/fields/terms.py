"""Composable velocity and force fields, evaluable from Python and from inside Numba kernels.

A *field* maps positions ``x`` (m), time ``t`` (s) and, for velocity-dependent forces, particle
velocities ``u`` (m/s) to a vector: a velocity (m/s) for advection, or an acceleration (m/s^2,
force per unit mass) for dynamics.  Which one is the caller's choice; each class documents the
unit of its parameters.

Every field is a small frozen dataclass with

* ``evaluate(points, t=0.0, velocities=None) -> (N, 3)``,
* ``jacobian(points, t=0.0, velocities=None) -> (values (N, 3), d value / d x (N, 3, 3))``,
* ``pack() -> PackedField`` (:mod:`filters.fields.packed`), and ``+`` to build a
  :class:`FieldSum`::

    packed = (Gravity() + Drag(0.5) + CurlNoise(amplitude=0.3)).pack()

Terms: :class:`Uniform` (constant vector: wind, gravity), :class:`Gravity`, :class:`Drag`
(linear drag towards an air velocity), :class:`RigidRotation` (``w x (x - c)``),
:class:`Vortex` (Lamb-Oseen vortex line; Lamb 1932, Oseen 1912), :class:`NoiseWind` (three fBm
components; Perlin 2002), :class:`CurlNoise` (divergence-free; Bridson, Hourihan & Nordenstam
2007).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..geometry import Shape, pack_shapes
from ..noise.curl import curl_jacobians, curl_potentials, curl_velocities
from ..noise.fractal import MAX_OCTAVES, check_top_frequency
from ..noise.perlin import kernel_tables
from ..validation import check_finite, check_finite_vector, check_int, check_points, check_range
from .packed import (
    KIND_CURL,
    KIND_DRAG,
    KIND_NOISE_WIND,
    KIND_ROTATION,
    KIND_UNIFORM,
    KIND_VORTEX,
    N_PARAMS,
    PackedField,
    evaluate_packed,
    jacobian_packed,
)

if TYPE_CHECKING:
    from collections.abc import Iterator

    from numpy.typing import ArrayLike, NDArray

__all__ = [
    "Field",
    "FieldSum",
    "Uniform",
    "Gravity",
    "Drag",
    "RigidRotation",
    "Vortex",
    "NoiseWind",
    "CurlNoise",
]

class Field:
    """Base of the field terms: evaluation, Jacobian, packing and ``+``."""

    def terms(self) -> Iterator[tuple[int, np.ndarray, np.ndarray | None,
                                      np.ndarray | None]]:  # pragma: no cover - abstract
        """Yield the packed terms: ``(kind, params (16,), tables (T, 512) or None, colliders
        (C, 8) or None)``."""
        raise NotImplementedError

    def pack(self) -> PackedField:
        """The field as a :class:`PackedField` (arrays for Numba kernels)."""
        kinds, rows, tables, colliders = [], [], [np.zeros((1, 512), np.int32)], []
        n_tables, n_colliders = 1, 0
        for kind, prm, tab, col in self.terms():
            prm = np.array(prm, dtype=np.float64, copy=True)
            if tab is not None:
                if kind == KIND_NOISE_WIND or kind == KIND_CURL:
                    prm[7] = n_tables
                tables.append(tab)
                n_tables += tab.shape[0]
            if kind == KIND_CURL:
                m = 0 if col is None else col.shape[0]
                prm[8], prm[9] = n_colliders, n_colliders + m
                if m:
                    colliders.append(col)
                    n_colliders += m
            kinds.append(kind)
            rows.append(prm)
        packed = PackedField(
            np.array(kinds, dtype=np.int64),
            np.array(rows, dtype=np.float64).reshape(-1, N_PARAMS),
            np.ascontiguousarray(np.concatenate(tables), dtype=np.int32),
            np.ascontiguousarray(np.concatenate(colliders) if colliders else np.zeros((0, 8))),
        )
        for array in packed:
            array.setflags(write=False)
        return packed

    @property
    def packed(self) -> PackedField:
        """Cached :meth:`pack`."""
        cached = self.__dict__.get("_packed_cache")
        if cached is None:
            cached = self.pack()
            object.__setattr__(self, "_packed_cache", cached)
        return cached

    def evaluate(self, points: ArrayLike, t: float = 0.0,
                 velocities: ArrayLike | None = None) -> np.ndarray:
        """Field value at ``points`` (N, 3) (m), time ``t`` (s).

        Parameters
        ----------
        points : (N, 3) array_like
            Positions (m).
        t : float
            Time (s).
        velocities : (N, 3) array_like, optional
            Particle velocities (m/s) for velocity-dependent terms (drag); zeros if omitted.

        Returns
        -------
        (N, 3) float64
            Velocity (m/s) or acceleration (m/s^2), depending on the terms.
        """
        return evaluate_packed(self.packed, points, t, velocities)

    __call__ = evaluate

    def jacobian(self, points: ArrayLike, t: float = 0.0,
                 velocities: ArrayLike | None = None) -> tuple[NDArray[np.float64],
                                                               NDArray[np.float64]]:
        """Values (N, 3) and spatial Jacobians ``d f_i / d x_j`` (N, 3, 3) (1/s for velocities)."""
        return jacobian_packed(self.packed, points, t, velocities)

    def __add__(self, other):
        if not isinstance(other, Field):
            return NotImplemented
        return FieldSum((self, other))


def _flatten(fields):
    for f in fields:
        if isinstance(f, FieldSum):
            yield from _flatten(f.fields)
        elif isinstance(f, Field):
            yield f
        else:
            raise TypeError(f"fields must be Field instances, got {type(f).__name__}")

@dataclass(frozen=True, eq=False)
class FieldSum(Field):
    """The sum of several fields (``a + b + c`` builds one).

    Parameters
    ----------
    fields : sequence of Field
        Terms, flattened (a sum of sums is one sum).
    """

    fields: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "fields", tuple(_flatten(self.fields)))

    def terms(self) -> Iterator[tuple[int, np.ndarray, np.ndarray | None, np.ndarray | None]]:
        for f in self.fields:
            yield from f.terms()

def _row(*values):
    row = np.zeros(N_PARAMS)
    row[:len(values)] = values
    return row

@dataclass(frozen=True, eq=False)
class Uniform(Field):
    """A constant vector: wind velocity (m/s) or a uniform acceleration (m/s^2).

    Parameters
    ----------
    vector : sequence of 3 float
    """

    vector: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        object.__setattr__(self, "vector", tuple(check_finite_vector("vector", self.vector, 3)))

    def terms(self) -> Iterator[tuple[int, np.ndarray, np.ndarray | None, np.ndarray | None]]:
        yield KIND_UNIFORM, _row(*self.vector), None, None

@dataclass(frozen=True, eq=False)
class Gravity(Field):
    """Uniform gravitational acceleration (m/s^2), default ``(0, 0, -9.81)`` (z up)."""

    acceleration: tuple = (0.0, 0.0, -9.81)

    def __post_init__(self):
        object.__setattr__(self, "acceleration",
                           tuple(check_finite_vector("acceleration", self.acceleration, 3)))

    def terms(self) -> Iterator[tuple[int, np.ndarray, np.ndarray | None, np.ndarray | None]]:
        yield KIND_UNIFORM, _row(*self.acceleration), None, None

@dataclass(frozen=True, eq=False)
class Drag(Field):
    """Linear drag ``a = -k (u - w)`` towards the air velocity ``w``.

    Parameters
    ----------
    coefficient : float
        ``k`` (1/s), >= 0: the inverse relaxation time of a particle to the air's velocity.
    air_velocity : sequence of 3 float
        ``w`` (m/s).
    """

    coefficient: float = 1.0
    air_velocity: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        object.__setattr__(self, "coefficient",
                           check_range("coefficient", self.coefficient, 0.0, math.inf))
        object.__setattr__(self, "air_velocity",
                           tuple(check_finite_vector("air_velocity", self.air_velocity, 3)))

    def terms(self) -> Iterator[tuple[int, np.ndarray, np.ndarray | None, np.ndarray | None]]:
        yield KIND_DRAG, _row(self.coefficient, *self.air_velocity), None, None

@dataclass(frozen=True, eq=False)
class RigidRotation(Field):
    """Rigid-body rotation velocity ``v = omega x (x - center)``.

    Parameters
    ----------
    omega : sequence of 3 float
        Angular velocity (rad/s).
    center : sequence of 3 float
        A point on the axis (m).
    """

    omega: tuple = (0.0, 0.0, 1.0)
    center: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        object.__setattr__(self, "omega", tuple(check_finite_vector("omega", self.omega, 3)))
        object.__setattr__(self, "center", tuple(check_finite_vector("center", self.center, 3)))

    def terms(self) -> Iterator[tuple[int, np.ndarray, np.ndarray | None, np.ndarray | None]]:
        yield KIND_ROTATION, _row(*self.omega, *self.center), None, None

@dataclass(frozen=True, eq=False)
class Vortex(Field):
    """Lamb-Oseen vortex line: azimuthal speed ``G / (2 pi r) (1 - exp(-r^2 / rc^2))``.

    A smooth vortex (Lamb 1932): rigid rotation at ``G / (2 pi rc^2)`` near the axis, a potential
    vortex ``G / (2 pi r)`` far from it; divergence-free.

    Parameters
    ----------
    center : sequence of 3 float
        A point on the axis (m).
    axis : sequence of 3 float
        Axis direction (normalised); the flow turns counter-clockwise about it for ``G > 0``.
    circulation : float
        ``G`` (m^2/s).
    core_radius : float
        ``rc`` (m), > 0.
    """

    center: tuple = (0.0, 0.0, 0.0)
    axis: tuple = (0.0, 0.0, 1.0)
    circulation: float = 1.0
    core_radius: float = 0.1

    def __post_init__(self):
        axis = check_finite_vector("axis", self.axis, 3)
        norm = float(np.linalg.norm(axis))
        if norm == 0.0:
            raise ValueError("axis must be a non-zero vector")
        object.__setattr__(self, "axis", tuple(axis / norm))
        object.__setattr__(self, "center", tuple(check_finite_vector("center", self.center, 3)))
        object.__setattr__(self, "circulation", check_range("circulation", self.circulation))
        object.__setattr__(self, "core_radius", check_range(
            "core_radius", self.core_radius, 0.0, math.inf, low_inclusive=False))

    def terms(self) -> Iterator[tuple[int, np.ndarray, np.ndarray | None, np.ndarray | None]]:
        yield (KIND_VORTEX, _row(*self.center, *self.axis, self.circulation, self.core_radius),
               None, None)

def _check_noise(obj):
    object.__setattr__(obj, "frequency", check_finite("frequency", obj.frequency, 0.0, math.inf,
                                                      low_inclusive=False))
    object.__setattr__(obj, "octaves", check_int("octaves", obj.octaves, 1, MAX_OCTAVES))
    object.__setattr__(obj, "lacunarity", check_range("lacunarity", obj.lacunarity, 1.0, 16.0))
    object.__setattr__(obj, "gain", check_range("gain", obj.gain, 0.0, 1.0))
    object.__setattr__(obj, "seed", check_int("seed", obj.seed, 0, (1 << 63) - 3))
    object.__setattr__(obj, "time_scale", check_finite("time_scale", obj.time_scale))
    check_top_frequency(obj.frequency, obj.octaves, obj.lacunarity)

@dataclass(frozen=True, eq=False)
class NoiseWind(Field):
    """A smooth random vector field: ``f_i = amplitude_i * fBm_i(x, t)``, i = x, y, z.

    The three components use the permutations of seeds ``seed, seed + 1, seed + 2``
    (decorrelated) and drift in time as described in :mod:`filters.noise`.  Not divergence-free
    (use :class:`CurlNoise` to advect without clumping); good as a gusty force.

    Parameters
    ----------
    amplitude : sequence of 3 float
        Per-component scale (m/s or m/s^2).
    frequency : float
        Lattice cells per metre, > 0.
    octaves, lacunarity, gain : int, float, float
        Fractal sum (see :func:`filters.noise.fbm3`).
    seed : int
        Seed of the first component, >= 0.
    time_scale : float
        Drift (lattice cells per second).
    """

    amplitude: tuple = (1.0, 1.0, 1.0)
    frequency: float = 1.0
    octaves: int = 2
    lacunarity: float = 2.0
    gain: float = 0.5
    seed: int = 0
    time_scale: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "amplitude",
                           tuple(check_finite_vector("amplitude", self.amplitude, 3)))
        _check_noise(self)

    def terms(self) -> Iterator[tuple[int, np.ndarray, np.ndarray | None, np.ndarray | None]]:
        prm = _row(*self.amplitude, self.frequency, self.octaves, self.lacunarity, self.gain,
                   0.0, self.time_scale)
        yield KIND_NOISE_WIND, prm, kernel_tables(self.seed, 3), None


@dataclass(frozen=True, eq=False)
class CurlNoise(Field):
    """Divergence-free curl-noise velocity (m/s) (Bridson, Hourihan & Nordenstam 2007).

    ``v = curl psi``, ``psi = (amplitude / frequency) (N0, N1, N2)`` where ``N0..N2`` are fBm of
    improved noise with the permutations of seeds ``seed``, ``seed + 1``, ``seed + 2``
    (decorrelated potentials; :mod:`filters.noise.curl`).  With ``colliders`` and
    ``ramp_distance > 0`` the potential is modulated within ``ramp_distance`` of the nearest
    collider surface, ``psi' = a psi + (1 - a) n (n . psi)``, ``a = ramp(d / ramp_distance)``,
    which makes the velocity tangent to the surface there (the paper's Section 3.2); the field
    stays exactly divergence-free because it is still a curl.

    Parameters
    ----------
    amplitude : float
        Velocity scale (m/s), >= 0; typical speeds are ``~ amplitude``.
    frequency : float
        Lattice cells per metre of the first octave, > 0 (eddies ~ ``1 / frequency`` m).
    octaves, lacunarity, gain : int, float, float
        Fractal sum of the potentials (see :func:`filters.noise.fbm3`).
    seed : int
        Seed of the first potential, in [0, 2**63 - 3].
    time_scale : float
        Drift of the potentials (lattice cells per second); 0 for a steady field.
    colliders : Shape or tuple of Shape
        Surfaces the flow must not cross: :class:`filters.geometry.Plane`,
        :class:`~filters.geometry.Sphere` or spherical containers ``~Sphere`` (see
        :func:`filters.geometry.pack_shapes`).
    ramp_distance : float
        Width of the boundary ramp (m), >= 0; 0 disables the ramp.
    base_velocity : sequence of 3 float
        A uniform flow ``b`` (m/s) added through its potential ``(b x x) / 2`` before the ramp,
        so that it too goes around the colliders (Bridson et al. 2007).
    """

    amplitude: float = 1.0
    frequency: float = 1.0
    octaves: int = 1
    lacunarity: float = 2.0
    gain: float = 0.5
    seed: int = 0
    time_scale: float = 0.0
    colliders: tuple = ()
    ramp_distance: float = 0.0
    base_velocity: tuple = (0.0, 0.0, 0.0)
    _packed_colliders: np.ndarray = field(init=False, repr=False, compare=False)
    _tables: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "amplitude",
                           check_finite("amplitude", self.amplitude, 0.0, math.inf))
        _check_noise(self)
        object.__setattr__(self, "ramp_distance",
                           check_finite("ramp_distance", self.ramp_distance, 0.0, math.inf))
        object.__setattr__(self, "base_velocity", tuple(
            check_finite_vector("base_velocity", self.base_velocity, 3).tolist()))
        colliders = self.colliders
        colliders = (colliders,) if isinstance(colliders, Shape) else tuple(colliders)
        try:
            packed = pack_shapes(colliders)
        except TypeError as exc:
            raise TypeError(f"colliders: {exc}") from None
        object.__setattr__(self, "colliders", colliders)
        object.__setattr__(self, "_packed_colliders", packed)
        tables = kernel_tables(self.seed, 3)
        tables.setflags(write=False)
        object.__setattr__(self, "_tables", tables)

    def terms(self) -> Iterator[tuple[int, np.ndarray, np.ndarray | None, np.ndarray | None]]:
        prm = _row(self.amplitude, self.frequency, self.octaves, self.lacunarity, self.gain,
                   self.time_scale, self.ramp_distance, 0.0, 0.0, 0.0, *self.base_velocity)
        yield KIND_CURL, prm, self._tables, self._packed_colliders

    @property
    def tables(self) -> np.ndarray:
        """(3, 512) int32 kernel tables of the three potentials."""
        return self._tables

    @property
    def packed_colliders(self) -> np.ndarray:
        """(C, 8) float64 collider rows (see :func:`filters.geometry.pack_shapes`)."""
        return self._packed_colliders

    def _args(self):
        return (self.amplitude, self.frequency, self.octaves, self.lacunarity, self.gain,
                self.time_scale, self.ramp_distance, *self.base_velocity)

    def velocity(self, points: ArrayLike, t: float = 0.0) -> np.ndarray:
        """Velocity (m/s) at ``points`` (N, 3) (m) and time ``t`` (s); returns (N, 3).

        Evaluated octave by octave over blocks of points (vectorised), bitwise equal to
        :meth:`evaluate`."""
        pts = check_points("points", points)
        t = check_finite("t", t)
        out = np.empty((pts.shape[0], 3))
        curl_velocities(self._tables, self._packed_colliders, pts, t, *self._args(), out)
        return out

    def jacobian(self, points: ArrayLike, t: float = 0.0,
                 velocities: ArrayLike | None = None) -> tuple[NDArray[np.float64],
                                                               NDArray[np.float64]]:
        """Velocity (N, 3) (m/s) and its Jacobian ``dv_i/dx_j`` (N, 3, 3) (1/s); ``velocities``
        is ignored (the field does not depend on them)."""
        pts = check_points("points", points)
        t = check_finite("t", t)
        n = pts.shape[0]
        vel = np.empty((n, 3))
        jac = np.empty((n, 3, 3))
        curl_jacobians(self._tables, self._packed_colliders, pts, t, *self._args(), vel, jac)
        return vel, jac

    def potential(self, points: ArrayLike, t: float = 0.0) -> np.ndarray:
        """The (ramped) vector potential psi (m^2/s) at ``points``; returns (N, 3)."""
        pts = check_points("points", points)
        t = check_finite("t", t)
        out = np.empty((pts.shape[0], 3))
        curl_potentials(self._tables, self._packed_colliders, pts, t, *self._args(), out)
        return out
