"""Packed fields: the arrays a field becomes for Numba kernels, and their point kernels.

A :class:`PackedField` is plain arrays (an int kind code and a row of float parameters per
term, the permutation tables of the noise terms, the collider rows of the curl-noise ramps),
which any ``@njit`` kernel evaluates with :func:`field_point` / :func:`field_point_jacobian`
(so SPH, springs and advection share one implementation, without first-class functions, which
would defeat Numba's on-disk cache). The classes that build them are in
:mod:`filters.fields.terms`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numba import njit, prange

from ..noise.curl import curl_jacobian_point, curl_point
from ..noise.fractal import DRIFT, fbm_value, fbm_value_grad
from ..validation import check_finite, check_points

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = [
    "PackedField",
    "KIND_UNIFORM",
    "KIND_DRAG",
    "KIND_ROTATION",
    "KIND_VORTEX",
    "KIND_NOISE_WIND",
    "KIND_CURL",
    "N_PARAMS",
    "field_point",
    "field_point_jacobian",
    "evaluate_packed",
    "jacobian_packed",
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
                            s * DRIFT[q, 0], s * DRIFT[q, 1], s * DRIFT[q, 2], False)
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
                                           prm[6], s * DRIFT[q, 0], s * DRIFT[q, 1],
                                           s * DRIFT[q, 2], False)
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

def evaluate_packed(packed: PackedField, points: np.ndarray, t: float = 0.0,
                    velocities: np.ndarray | None = None) -> np.ndarray:
    """Evaluate a :class:`PackedField` at (N, 3) points (m), time ``t`` (s); returns (N, 3)."""
    pts, t, vel, has_vel = _inputs(points, t, velocities)
    out = np.empty((pts.shape[0], 3))
    _evaluate_many(packed.kinds, packed.params, packed.tables, packed.colliders, pts, vel,
                   has_vel, t, out)
    return out

def jacobian_packed(packed: PackedField, points: np.ndarray, t: float = 0.0,
                    velocities: np.ndarray | None = None) -> tuple[NDArray[np.float64],
                                                                   NDArray[np.float64]]:
    """Values (N, 3) and Jacobians ``d f_i / d x_j`` (N, 3, 3) of a :class:`PackedField`."""
    pts, t, vel, has_vel = _inputs(points, t, velocities)
    n = pts.shape[0]
    out = np.empty((n, 3))
    jac = np.empty((n, 3, 3))
    _jacobian_many(packed.kinds, packed.params, packed.tables, packed.colliders, pts, vel,
                   has_vel, t, out, jac)
    return out, jac
