"""Composable velocity and force fields, evaluable from Python and from inside Numba kernels.

A *field* maps positions ``x`` (m), time ``t`` (s) and, for velocity-dependent forces, particle
velocities ``u`` (m/s) to a vector: a velocity (m/s) for advection, or an acceleration (m/s^2,
force per unit mass) for dynamics.  Which one is the caller's choice; each class documents the
unit of its parameters.

Every field is a small frozen dataclass with

* ``evaluate(points, t=0.0, velocities=None) -> (N, 3)``,
* ``jacobian(points, t=0.0, velocities=None) -> (values (N, 3), d value / d x (N, 3, 3))``,
* ``pack() -> PackedField``, and ``+`` to build a :class:`FieldSum`.

The packed form is plain arrays (an int kind code and a row of float parameters per term, the
permutation tables of the noise terms, the collider rows of the curl-noise ramps), which any
``@njit`` kernel can evaluate with :func:`field_point` / :func:`field_point_jacobian`::

    packed = (Gravity() + Drag(0.5) + CurlNoiseVelocity(amplitude=0.3)).pack()

    @njit
    def kernel(x, v, t, kinds, params, tables, colliders):
        for i in range(x.shape[0]):
            ax, ay, az = field_point(kinds, params, tables, colliders,
                                     x[i, 0], x[i, 1], x[i, 2], v[i, 0], v[i, 1], v[i, 2], t)

so SPH, springs and advection share one implementation, without first-class functions (which
would defeat Numba's on-disk cache).

Terms: :class:`Uniform` (constant vector: wind, gravity), :class:`Gravity`, :class:`Drag`
(linear drag towards an air velocity), :class:`RigidRotation` (``w x (x - c)``),
:class:`Vortex` (Lamb-Oseen vortex line; Lamb 1932, Oseen 1912), :class:`NoiseWind` (three fBm
components; Perlin 2002), :class:`CurlNoiseVelocity` (divergence-free; Bridson, Hourihan &
Nordenstam 2007).  :func:`noise_variation` gives per-particle attributes (size, colour, lifetime)
from noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from .noise.perlin import (
    MAX_OCTAVES,
    _DRIFT,
    _is_colliders_object,
    _tables,
    check_top_frequency,
    curl_jacobian_point,
    curl_point,
    fbm_value,
    fbm_value_grad,
    pack_colliders,
)
from .validation import check_finite, check_finite_vector, check_int, check_points, check_range

__all__ = [
    "Field",
    "FieldSum",
    "PackedField",
    "Uniform",
    "Gravity",
    "Drag",
    "RigidRotation",
    "Vortex",
    "NoiseWind",
    "CurlNoiseVelocity",
    "field_point",
    "field_point_jacobian",
    "evaluate_packed",
    "jacobian_packed",
    "noise_variation",
]

KIND_UNIFORM = 0
KIND_DRAG = 1
KIND_ROTATION = 2
KIND_VORTEX = 3
KIND_NOISE_WIND = 4
KIND_CURL = 5

#: Floats per term in the packed parameter rows.
N_PARAMS = 16


class PackedField(NamedTuple):
    """A field as plain arrays for Numba kernels.

    Attributes
    ----------
    kinds : (K,) int64
        Kind code of each term.
    params : (K, 16) float64
        Parameters of each term (layout private to this module).
    tables : (T, 512) int32
        Permutation tables used by the noise terms (at least one row).
    colliders : (C, 8) float64
        Collider rows used by curl-noise boundary ramps.
    """

    kinds: np.ndarray
    params: np.ndarray
    tables: np.ndarray
    colliders: np.ndarray


# ---------------------------------------------------------------------------------------------
# Point kernels
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _vortex_profile(s, rc2):
    """g(s) = (1 - exp(-s / rc^2)) / s and g'(s) for the Lamb-Oseen velocity, s = r^2."""
    q = s / rc2
    if q < 1e-6:
        # series: g = (1 - q/2 + q^2/6) / rc^2, g' = (-1/2 + q/3) / rc^4
        return (1.0 - 0.5 * q + q * q / 6.0) / rc2, (-0.5 + q / 3.0) / (rc2 * rc2)
    e = math.exp(-q)
    g = -math.expm1(-q) / s
    return g, (e / rc2 - g) / s


@njit(cache=True)
def _term(kind, prm, tables, colliders, x, y, z, vx, vy, vz, t):
    if kind == KIND_UNIFORM:
        return prm[0], prm[1], prm[2]
    if kind == KIND_DRAG:
        k = prm[0]
        return -k * (vx - prm[1]), -k * (vy - prm[2]), -k * (vz - prm[3])
    if kind == KIND_ROTATION:
        rx = x - prm[3]
        ry = y - prm[4]
        rz = z - prm[5]
        return prm[1] * rz - prm[2] * ry, prm[2] * rx - prm[0] * rz, prm[0] * ry - prm[1] * rx
    if kind == KIND_VORTEX:
        ax, ay, az = prm[3], prm[4], prm[5]
        rx = x - prm[0]
        ry = y - prm[1]
        rz = z - prm[2]
        along = rx * ax + ry * ay + rz * az
        rx -= along * ax
        ry -= along * ay
        rz -= along * az
        g, _ = _vortex_profile(rx * rx + ry * ry + rz * rz, prm[7] * prm[7])
        c = prm[6] / (2.0 * math.pi) * g
        return c * (ay * rz - az * ry), c * (az * rx - ax * rz), c * (ax * ry - ay * rx)
    if kind == KIND_NOISE_WIND:
        base = np.int64(prm[7])
        octaves = np.int64(prm[4])
        s = t * prm[8]
        out0 = 0.0
        out1 = 0.0
        out2 = 0.0
        for q in range(3):
            val = fbm_value(tables[base + q], x, y, z, prm[3], octaves, prm[5], prm[6],
                            s * _DRIFT[q, 0], s * _DRIFT[q, 1], s * _DRIFT[q, 2], False)
            if q == 0:
                out0 = prm[0] * val
            elif q == 1:
                out1 = prm[1] * val
            else:
                out2 = prm[2] * val
        return out0, out1, out2
    if kind == KIND_CURL:
        base = np.int64(prm[7])
        c0 = np.int64(prm[8])
        c1 = np.int64(prm[9])
        return curl_point(tables[base:base + 3], colliders[c0:c1], x, y, z, t, prm[0], prm[1],
                          np.int64(prm[2]), prm[3], prm[4], prm[5], prm[6], prm[10], prm[11],
                          prm[12])
    return 0.0, 0.0, 0.0


@njit(cache=True)
def field_point(kinds, params, tables, colliders, x, y, z, vx, vy, vz, t):
    """Value of a packed field at one point: returns (fx, fy, fz).

    Parameters
    ----------
    kinds, params, tables, colliders : arrays of a :class:`PackedField`
    x, y, z : float
        Position (m).
    vx, vy, vz : float
        Particle velocity (m/s) for velocity-dependent terms (drag); 0 otherwise.
    t : float
        Time (s).
    """
    fx = 0.0
    fy = 0.0
    fz = 0.0
    for k in range(kinds.shape[0]):
        a, b, c = _term(kinds[k], params[k], tables, colliders, x, y, z, vx, vy, vz, t)
        fx += a
        fy += b
        fz += c
    return fx, fy, fz


@njit(cache=True)
def _term_jacobian(kind, prm, tables, colliders, x, y, z, vx, vy, vz, t, J):
    """Add term's value to the returned tuple and its d/dx to J (3, 3) in place."""
    if kind == KIND_ROTATION:
        # d (w x r) / dr = [w]_x
        J[0, 1] -= prm[2]
        J[0, 2] += prm[1]
        J[1, 0] += prm[2]
        J[1, 2] -= prm[0]
        J[2, 0] -= prm[1]
        J[2, 1] += prm[0]
    elif kind == KIND_VORTEX:
        ax, ay, az = prm[3], prm[4], prm[5]
        rx = x - prm[0]
        ry = y - prm[1]
        rz = z - prm[2]
        along = rx * ax + ry * ay + rz * az
        rx -= along * ax
        ry -= along * ay
        rz -= along * az
        g, dg = _vortex_profile(rx * rx + ry * ry + rz * rz, prm[7] * prm[7])
        c = prm[6] / (2.0 * math.pi)
        cx = ay * rz - az * ry
        cy = az * rx - ax * rz
        cz = ax * ry - ay * rx
        # v = c g(|rho|^2) (a x rho); d(a x rho)/dx = [a]_x (a x a = 0); d g / dx = 2 g' rho
        cg = c * g
        J[0, 1] -= cg * az
        J[0, 2] += cg * ay
        J[1, 0] += cg * az
        J[1, 2] -= cg * ax
        J[2, 0] -= cg * ay
        J[2, 1] += cg * ax
        w = 2.0 * c * dg
        J[0, 0] += w * cx * rx
        J[0, 1] += w * cx * ry
        J[0, 2] += w * cx * rz
        J[1, 0] += w * cy * rx
        J[1, 1] += w * cy * ry
        J[1, 2] += w * cy * rz
        J[2, 0] += w * cz * rx
        J[2, 1] += w * cz * ry
        J[2, 2] += w * cz * rz
    elif kind == KIND_NOISE_WIND:
        base = np.int64(prm[7])
        octaves = np.int64(prm[4])
        s = t * prm[8]
        for q in range(3):
            _, gx, gy, gz = fbm_value_grad(tables[base + q], x, y, z, prm[3], octaves, prm[5],
                                           prm[6], s * _DRIFT[q, 0], s * _DRIFT[q, 1],
                                           s * _DRIFT[q, 2], False)
            J[q, 0] += prm[q] * gx
            J[q, 1] += prm[q] * gy
            J[q, 2] += prm[q] * gz
    elif kind == KIND_CURL:
        base = np.int64(prm[7])
        c0 = np.int64(prm[8])
        c1 = np.int64(prm[9])
        _, Jc = curl_jacobian_point(tables[base:base + 3], colliders[c0:c1], x, y, z, t, prm[0],
                                    prm[1], np.int64(prm[2]), prm[3], prm[4], prm[5], prm[6],
                                    prm[10], prm[11], prm[12])
        for i in range(3):
            for j in range(3):
                J[i, j] += Jc[i, j]
    # uniform and drag do not depend on x


@njit(cache=True)
def field_point_jacobian(kinds, params, tables, colliders, x, y, z, vx, vy, vz, t, J):
    """Value (fx, fy, fz) of a packed field at one point; writes ``J[i, j] = df_i/dx_j`` (3, 3).

    ``J`` is overwritten.  Velocity-dependent terms contribute no ``d/dx``.
    """
    for i in range(3):
        for j in range(3):
            J[i, j] = 0.0
    fx = 0.0
    fy = 0.0
    fz = 0.0
    for k in range(kinds.shape[0]):
        a, b, c = _term(kinds[k], params[k], tables, colliders, x, y, z, vx, vy, vz, t)
        fx += a
        fy += b
        fz += c
        _term_jacobian(kinds[k], params[k], tables, colliders, x, y, z, vx, vy, vz, t, J)
    return fx, fy, fz


@njit(parallel=True, cache=True)
def _evaluate_many(kinds, params, tables, colliders, pts, vel, has_vel, t, out):
    for i in prange(pts.shape[0]):
        vx = vel[i, 0] if has_vel else 0.0
        vy = vel[i, 1] if has_vel else 0.0
        vz = vel[i, 2] if has_vel else 0.0
        out[i, 0], out[i, 1], out[i, 2] = field_point(kinds, params, tables, colliders, pts[i, 0],
                                                      pts[i, 1], pts[i, 2], vx, vy, vz, t)


@njit(parallel=True, cache=True)
def _jacobian_many(kinds, params, tables, colliders, pts, vel, has_vel, t, out, jac):
    for i in prange(pts.shape[0]):
        vx = vel[i, 0] if has_vel else 0.0
        vy = vel[i, 1] if has_vel else 0.0
        vz = vel[i, 2] if has_vel else 0.0
        J = np.empty((3, 3))
        out[i, 0], out[i, 1], out[i, 2] = field_point_jacobian(
            kinds, params, tables, colliders, pts[i, 0], pts[i, 1], pts[i, 2], vx, vy, vz, t, J)
        for a in range(3):
            for b in range(3):
                jac[i, a, b] = J[a, b]


def _inputs(points, t, velocities):
    pts = check_points("points", points)
    t = check_finite("t", t)
    if velocities is None:
        vel = np.zeros((1, 3))
        has_vel = False
    else:
        vel = check_points("velocities", velocities)
        if vel.shape[0] != pts.shape[0]:
            raise ValueError(
                f"velocities must have {pts.shape[0]} rows to match points, got {vel.shape[0]}")
        has_vel = True
    return pts, t, vel, has_vel


def evaluate_packed(packed: PackedField, points, t: float = 0.0, velocities=None) -> np.ndarray:
    """Evaluate a :class:`PackedField` at (N, 3) points (m), time ``t`` (s); returns (N, 3)."""
    pts, t, vel, has_vel = _inputs(points, t, velocities)
    out = np.empty((pts.shape[0], 3))
    _evaluate_many(packed.kinds, packed.params, packed.tables, packed.colliders, pts, vel,
                   has_vel, t, out)
    return out


def jacobian_packed(packed: PackedField, points, t: float = 0.0, velocities=None):
    """Values (N, 3) and Jacobians ``d f_i / d x_j`` (N, 3, 3) of a :class:`PackedField`."""
    pts, t, vel, has_vel = _inputs(points, t, velocities)
    n = pts.shape[0]
    out = np.empty((n, 3))
    jac = np.empty((n, 3, 3))
    _jacobian_many(packed.kinds, packed.params, packed.tables, packed.colliders, pts, vel,
                   has_vel, t, out, jac)
    return out, jac


# ---------------------------------------------------------------------------------------------
# Field classes
# ---------------------------------------------------------------------------------------------
class Field:
    """Base of the field terms: evaluation, Jacobian, packing and ``+``."""

    def _terms(self):
        """Yield (kind, params (16,), tables (T, 512) or None, colliders (C, 8) or None)."""
        raise NotImplementedError

    def pack(self) -> PackedField:
        """The field as a :class:`PackedField` (arrays for Numba kernels)."""
        kinds, rows, tables, colliders = [], [], [np.zeros((1, 512), np.int32)], []
        n_tables, n_colliders = 1, 0
        for kind, prm, tab, col in self._terms():
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

    def evaluate(self, points, t: float = 0.0, velocities=None) -> np.ndarray:
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

    def jacobian(self, points, t: float = 0.0, velocities=None):
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

    def _terms(self):
        for f in self.fields:
            yield from f._terms()


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

    def _terms(self):
        yield KIND_UNIFORM, _row(*self.vector), None, None


@dataclass(frozen=True, eq=False)
class Gravity(Field):
    """Uniform gravitational acceleration (m/s^2), default ``(0, 0, -9.81)`` (z up)."""

    acceleration: tuple = (0.0, 0.0, -9.81)

    def __post_init__(self):
        object.__setattr__(self, "acceleration",
                           tuple(check_finite_vector("acceleration", self.acceleration, 3)))

    def _terms(self):
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

    def _terms(self):
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

    def _terms(self):
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

    def _terms(self):
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
    (use :class:`CurlNoiseVelocity` to advect without clumping); good as a gusty force.

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

    def _terms(self):
        prm = _row(*self.amplitude, self.frequency, self.octaves, self.lacunarity, self.gain,
                   0.0, self.time_scale)
        yield KIND_NOISE_WIND, prm, _tables(self.seed, 3), None


@dataclass(frozen=True, eq=False)
class CurlNoiseVelocity(Field):
    """Divergence-free curl-noise velocity (m/s) (Bridson, Hourihan & Nordenstam 2007).

    The field of :class:`filters.noise.CurlNoise` as a composable term; see it for the
    parameters.  With ``colliders`` and ``ramp_distance > 0`` the flow is tangent to the
    colliders' surfaces.

    Parameters
    ----------
    amplitude : float
        Velocity scale (m/s), >= 0.
    frequency : float
        Lattice cells per metre, > 0.
    octaves, lacunarity, gain : int, float, float
        Fractal sum of the potentials.
    seed : int
        Seed of the first potential, >= 0.
    time_scale : float
        Drift of the potentials (lattice cells per second).
    colliders : tuple of SDF primitives (filters.noise.PlaneSDF, SphereSDF, InsideSphereSDF),
        or a filters.elastic.contact.Colliders (planes and spheres)
    ramp_distance : float
        Width of the boundary ramp (m), >= 0.
    base_velocity : sequence of 3 float
        Uniform flow (m/s) added through its potential, so it goes around the colliders too.
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

    def __post_init__(self):
        object.__setattr__(self, "amplitude",
                           check_finite("amplitude", self.amplitude, 0.0, math.inf))
        _check_noise(self)
        object.__setattr__(self, "ramp_distance",
                           check_finite("ramp_distance", self.ramp_distance, 0.0, math.inf))
        object.__setattr__(self, "base_velocity", tuple(
            check_finite_vector("base_velocity", self.base_velocity, 3).tolist()))
        colliders = self.colliders
        colliders = (colliders,) if _is_colliders_object(colliders) else tuple(colliders)
        object.__setattr__(self, "colliders", colliders)
        object.__setattr__(self, "_packed_colliders", pack_colliders(colliders))

    def _terms(self):
        prm = _row(self.amplitude, self.frequency, self.octaves, self.lacunarity, self.gain,
                   self.time_scale, self.ramp_distance, 0.0, 0.0, 0.0, *self.base_velocity)
        yield KIND_CURL, prm, _tables(self.seed, 3), self._packed_colliders


# ---------------------------------------------------------------------------------------------
# Per-particle variation
# ---------------------------------------------------------------------------------------------
_ID_STEP = (0.6180339887498949, 0.3819660112501051, 0.7548776662466927)


@njit(parallel=True, cache=True)
def _variation_many(table, pts, ids, has_ids, frequency, octaves, low, high, out):
    norm = 0.0
    amp = 1.0
    for _ in range(octaves):
        norm += amp
        amp *= 0.5
    for i in prange(pts.shape[0]):
        ox = 0.0
        oy = 0.0
        oz = 0.0
        if has_ids:
            k = np.float64(ids[i] % 1048576)
            ox = k * _ID_STEP[0]
            oy = k * _ID_STEP[1]
            oz = k * _ID_STEP[2]
        n = fbm_value(table, pts[i, 0], pts[i, 1], pts[i, 2], frequency, octaves, 2.0, 0.5,
                      ox, oy, oz, False) / norm
        s = 0.5 + 0.5 * n * 1.6  # improved noise rarely exceeds +-0.6: stretch, then clip
        if s < 0.0:
            s = 0.0
        elif s > 1.0:
            s = 1.0
        out[i] = low + (high - low) * s


def noise_variation(points, low: float, high: float, *, ids=None, frequency: float = 1.0,
                    octaves: int = 1, seed: int = 0) -> np.ndarray:
    """Per-particle attributes (size, colour, lifetime...) in ``[low, high]`` from noise.

    Noise sampled at each particle's position (spatially coherent variation: neighbours look
    alike) and, when ``ids`` are given, shifted by an irrational multiple of the id so that
    particles born at the same place still differ.  Deterministic.

    Parameters
    ----------
    points : (N, 3) array_like
        Positions (m), e.g. where the particles were born.
    low, high : float
        Range of the attribute (any unit), ``low <= high``.
    ids : (N,) int array_like, optional
        Particle ids.
    frequency : float
        Lattice cells per metre, > 0.
    octaves : int
        1 to 16.
    seed : int
        Permutation seed.

    Returns
    -------
    (N,) float64 in [low, high]
    """
    pts = check_points("points", points)
    low = check_range("low", low)
    high = check_range("high", high, low, math.inf)
    frequency = check_finite("frequency", frequency, 0.0, math.inf, low_inclusive=False)
    octaves = check_int("octaves", octaves, 1, MAX_OCTAVES)
    check_top_frequency(frequency, octaves, 2.0)
    seed = check_int("seed", seed, 0, (1 << 63) - 1)
    if ids is None:
        id_array = np.zeros(1, dtype=np.int64)
    else:
        id_array = np.ascontiguousarray(ids, dtype=np.int64).ravel()
        if id_array.shape[0] != pts.shape[0]:
            raise ValueError(f"ids must have {pts.shape[0]} entries, got {id_array.shape[0]}")
    out = np.empty(pts.shape[0])
    _variation_many(_tables(seed, 1)[0], pts, id_array, ids is not None, frequency, octaves, low,
                    high, out)
    return out
