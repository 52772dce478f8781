"""Curl noise (Bridson, Hourihan & Nordenstam 2007, "Curl-noise for procedural fluid flow"),
as Numba kernels.

``v = curl psi`` with three decorrelated fBm potentials (kernel tables of seeds ``seed``,
``seed + 1``, ``seed + 2``), analytic derivatives, the potential ``(b x x) / 2`` of a uniform
base flow ``b``, and optionally the paper's boundary ramp ``psi' = a psi + (1 - a) n (n . psi)``,
``a = ramp(d / d0)``, with ``d`` the signed distance to the nearest packed shape
(:func:`filters.geometry.packed_distance`): it makes the velocity tangent to the shapes'
surfaces while keeping it exactly divergence-free. :func:`curl_point` and
:func:`curl_jacobian_point` are the point kernels (the field term
:class:`filters.fields.CurlNoise` calls them); :func:`curl_velocities`,
:func:`curl_jacobians` and :func:`curl_potentials` evaluate arrays of points, the velocities
octave by octave over blocks (bitwise equal to :func:`curl_point` at every point).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..geometry import packed_distance, packed_hessian
from .fractal import (
    BLOCK,
    DRIFT,
    OCTAVE_SHIFT,
    fbm_value,
    fbm_value_grad,
    fbm_value_grad_hess,
    octave_accumulate,
)

__all__ = ["curl_point", "curl_jacobian_point", "curl_velocities", "curl_jacobians",
           "curl_potentials"]


@njit(cache=True, inline="always")
def _ramp(r):
    """Bridson et al.'s smooth ramp: 15/8 r - 10/8 r^3 + 3/8 r^5 on (-1, 1), sign(r) outside.

    Returns the ramp and its derivative.
    """
    if r >= 1.0:
        return 1.0, 0.0
    if r <= -1.0:
        return -1.0, 0.0
    r2 = r * r
    return r * (1.875 - r2 * (1.25 - 0.375 * r2)), 1.875 * (1.0 - r2) * (1.0 - r2)

@njit(cache=True, inline="always")
def _curl_from_potentials(colliders, x, y, z, ramp_distance, bx, by, bz, p0, p0x, p0y, p0z,
                          p1, p1x, p1y, p1z, p2, p2x, p2y, p2z):
    """Velocity from the scaled noise potentials and their gradients: base flow, ramp, curl."""
    if bx != 0.0 or by != 0.0 or bz != 0.0:
        # potential of the uniform flow b: psi = (b x x) / 2, curl psi = b
        p0 += 0.5 * (by * z - bz * y)
        p0y -= 0.5 * bz
        p0z += 0.5 * by
        p1 += 0.5 * (bz * x - bx * z)
        p1x += 0.5 * bz
        p1z -= 0.5 * bx
        p2 += 0.5 * (bx * y - by * x)
        p2x -= 0.5 * by
        p2y += 0.5 * bx
    if ramp_distance > 0.0 and colliders.shape[0] > 0:
        d, nx, ny, nz, c = packed_distance(colliders, x, y, z)
        if d < ramp_distance:
            a, da = _ramp(d / ramp_distance)
            da /= ramp_distance
            hxx, hyy, hzz, hxy, hxz, hyz = packed_hessian(colliders, c, x, y, z, nx, ny, nz)
            q = nx * p0 + ny * p1 + nz * p2
            # dq/dx_j = sum_k H_kj psi_k + n_k dpsi_k/dx_j
            qx = hxx * p0 + hxy * p1 + hxz * p2 + nx * p0x + ny * p1x + nz * p2x
            qy = hxy * p0 + hyy * p1 + hyz * p2 + nx * p0y + ny * p1y + nz * p2y
            qz = hxz * p0 + hyz * p1 + hzz * p2 + nx * p0z + ny * p1z + nz * p2z
            b = 1.0 - a
            # d psi'_i / d x_j = da n_j psi_i + a dpsi_i/dx_j - da n_j n_i q
            #                    + (1 - a) (H_ij q + n_i dq/dx_j); only the off-diagonal
            # entries the curl needs are formed.
            d2y = da * ny * p2 + a * p2y - da * ny * nz * q + b * (hyz * q + nz * qy)
            d1z = da * nz * p1 + a * p1z - da * nz * ny * q + b * (hyz * q + ny * qz)
            d0z = da * nz * p0 + a * p0z - da * nz * nx * q + b * (hxz * q + nx * qz)
            d2x = da * nx * p2 + a * p2x - da * nx * nz * q + b * (hxz * q + nz * qx)
            d1x = da * nx * p1 + a * p1x - da * nx * ny * q + b * (hxy * q + ny * qx)
            d0y = da * ny * p0 + a * p0y - da * ny * nx * q + b * (hxy * q + nx * qy)
            return d2y - d1z, d0z - d2x, d1x - d0y
    return p2y - p1z, p0z - p2x, p1x - p0y

@njit(cache=True)
def curl_point(tables, colliders, x, y, z, t, amplitude, frequency, octaves, lacunarity, gain,
               time_scale, ramp_distance, bx, by, bz):
    """Curl-noise velocity (m/s) at one point.

    ``psi = (amplitude / frequency) * (N0, N1, N2) + (b x x) / 2`` with three fBm potentials from
    the first three rows of ``tables`` and the potential of the uniform base flow
    ``b = (bx, by, bz)`` (m/s); near colliders (when ``ramp_distance > 0`` and ``colliders`` has
    rows) the potential is ramped as in Bridson et al. (2007) so that the normal velocity
    vanishes on the surfaces (the base flow goes around them too).  Returns (vx, vy, vz).
    """
    s = t * time_scale
    p0, p0x, p0y, p0z = fbm_value_grad(tables[0], x, y, z, frequency, octaves, lacunarity, gain,
                                       s * DRIFT[0, 0], s * DRIFT[0, 1], s * DRIFT[0, 2], False)
    p1, p1x, p1y, p1z = fbm_value_grad(tables[1], x, y, z, frequency, octaves, lacunarity, gain,
                                       s * DRIFT[1, 0], s * DRIFT[1, 1], s * DRIFT[1, 2], False)
    p2, p2x, p2y, p2z = fbm_value_grad(tables[2], x, y, z, frequency, octaves, lacunarity, gain,
                                       s * DRIFT[2, 0], s * DRIFT[2, 1], s * DRIFT[2, 2], False)
    scale = amplitude / frequency
    p0 *= scale
    p0x *= scale
    p0y *= scale
    p0z *= scale
    p1 *= scale
    p1x *= scale
    p1y *= scale
    p1z *= scale
    p2 *= scale
    p2x *= scale
    p2y *= scale
    p2z *= scale
    return _curl_from_potentials(colliders, x, y, z, ramp_distance, bx, by, bz, p0, p0x, p0y,
                                 p0z, p1, p1x, p1y, p1z, p2, p2x, p2y, p2z)

@njit(cache=True)
def curl_jacobian_point(tables, colliders, x, y, z, t, amplitude, frequency, octaves, lacunarity,
                        gain, time_scale, ramp_distance, bx, by, bz):
    """Velocity (3,) and its Jacobian ``J[i, j] = dv_i/dx_j`` (3, 3) of curl noise at one point.

    Analytic from the potentials' Hessians away from colliders; inside a collider's ramp band
    the Jacobian is the central difference of the analytic velocity (step ``1e-5 / frequency``).
    """
    J = np.empty((3, 3))
    vel = np.empty(3)
    near = False
    if ramp_distance > 0.0 and colliders.shape[0] > 0:
        d, _, _, _, _ = packed_distance(colliders, x, y, z)
        near = d < ramp_distance * (1.0 + 1e-3) + 2e-5 / frequency
    if near:
        vel[0], vel[1], vel[2] = curl_point(tables, colliders, x, y, z, t, amplitude, frequency,
                                            octaves, lacunarity, gain, time_scale, ramp_distance,
                                            bx, by, bz)
        h = 1e-5 / frequency
        for j in range(3):
            ex = h if j == 0 else 0.0
            ey = h if j == 1 else 0.0
            ez = h if j == 2 else 0.0
            a0, a1, a2 = curl_point(tables, colliders, x + ex, y + ey, z + ez, t, amplitude,
                                    frequency, octaves, lacunarity, gain, time_scale,
                                    ramp_distance, bx, by, bz)
            b0, b1, b2 = curl_point(tables, colliders, x - ex, y - ey, z - ez, t, amplitude,
                                    frequency, octaves, lacunarity, gain, time_scale,
                                    ramp_distance, bx, by, bz)
            J[0, j] = (a0 - b0) / (2.0 * h)
            J[1, j] = (a1 - b1) / (2.0 * h)
            J[2, j] = (a2 - b2) / (2.0 * h)
        return vel, J
    s = t * time_scale
    H = np.empty((3, 10))
    for q in range(3):
        r = fbm_value_grad_hess(tables[q], x, y, z, frequency, octaves, lacunarity, gain,
                                s * DRIFT[q, 0], s * DRIFT[q, 1], s * DRIFT[q, 2])
        for m in range(10):
            H[q, m] = r[m]
    scale = amplitude / frequency
    # gradient entries 1..3, Hessian entries: xx 4, yy 5, zz 6, xy 7, xz 8, yz 9
    vel[0] = scale * (H[2, 2] - H[1, 3]) + bx
    vel[1] = scale * (H[0, 3] - H[2, 1]) + by
    vel[2] = scale * (H[1, 1] - H[0, 2]) + bz
    # v0 = d psi2/dy - d psi1/dz
    J[0, 0] = scale * (H[2, 7] - H[1, 8])
    J[0, 1] = scale * (H[2, 5] - H[1, 9])
    J[0, 2] = scale * (H[2, 9] - H[1, 6])
    # v1 = d psi0/dz - d psi2/dx
    J[1, 0] = scale * (H[0, 8] - H[2, 4])
    J[1, 1] = scale * (H[0, 9] - H[2, 7])
    J[1, 2] = scale * (H[0, 6] - H[2, 8])
    # v2 = d psi1/dx - d psi0/dy
    J[2, 0] = scale * (H[1, 4] - H[0, 7])
    J[2, 1] = scale * (H[1, 7] - H[0, 5])
    J[2, 2] = scale * (H[1, 8] - H[0, 9])
    return vel, J

@njit(parallel=True, cache=True)
def _curl_combine(colliders, flat, start, count, acc, scale, ramp_distance, bx, by, bz, out):
    """Velocities of points ``start .. start + count`` from accumulated potentials (12, B)."""
    for j in prange(count):
        i = start + j
        out[i, 0], out[i, 1], out[i, 2] = _curl_from_potentials(
            colliders, flat[3 * i], flat[3 * i + 1], flat[3 * i + 2], ramp_distance, bx, by, bz,
            acc[0, j] * scale, acc[1, j] * scale, acc[2, j] * scale, acc[3, j] * scale,
            acc[4, j] * scale, acc[5, j] * scale, acc[6, j] * scale, acc[7, j] * scale,
            acc[8, j] * scale, acc[9, j] * scale, acc[10, j] * scale, acc[11, j] * scale)


def curl_velocities(tables: np.ndarray, colliders: np.ndarray, pts: np.ndarray, t: float,
                    amplitude: float, frequency: float, octaves: int, lacunarity: float,
                    gain: float, time_scale: float, ramp_distance: float, bx: float, by: float,
                    bz: float, out: np.ndarray) -> None:
    """Curl noise on (N, 3) points, octave by octave over blocks so that the inner loops
    vectorise; bitwise equal to :func:`curl_point` at every point."""
    n = pts.shape[0]
    flat = pts.reshape(-1)
    block = min(BLOCK, max(n, 1))
    acc = np.empty((12, block))
    s = t * time_scale
    scale = amplitude / frequency
    for start in range(0, n, block):
        count = min(block, n - start)
        for q in range(3):
            ox, oy, oz = s * DRIFT[q, 0], s * DRIFT[q, 1], s * DRIFT[q, 2]
            f = frequency
            amp = 1.0
            for k in range(octaves):
                octave_accumulate(tables[q], flat, start, count, f, amp, OCTAVE_SHIFT[k, 0],
                                   OCTAVE_SHIFT[k, 1], OCTAVE_SHIFT[k, 2], ox, oy, oz, k == 0,
                                   False, acc[4 * q], acc[4 * q + 1], acc[4 * q + 2],
                                   acc[4 * q + 3])
                amp *= gain
                f *= lacunarity
        _curl_combine(colliders, flat, start, count, acc, scale, ramp_distance, bx, by, bz, out)


@njit(parallel=True, cache=True)
def curl_jacobians(tables, colliders, pts, t, amplitude, frequency, octaves, lacunarity, gain,
                   time_scale, ramp_distance, bx, by, bz, vel, jac):
    """Velocities ``vel`` (N, 3) and Jacobians ``jac`` (N, 3, 3) of curl noise at ``pts``
    (see :func:`curl_jacobian_point`)."""
    flat = pts.reshape(pts.shape[0] * 3)  # flat indexing vectorises better
    for i in prange(pts.shape[0]):
        v, J = curl_jacobian_point(tables, colliders, flat[3 * i], flat[3 * i + 1],
                                   flat[3 * i + 2], t,
                                   amplitude, frequency, octaves, lacunarity, gain, time_scale,
                                   ramp_distance, bx, by, bz)
        for a in range(3):
            vel[i, a] = v[a]
            for b in range(3):
                jac[i, a, b] = J[a, b]


@njit(cache=True)
def curl_potentials(tables, colliders, pts, t, amplitude, frequency, octaves, lacunarity, gain,
                    time_scale, ramp_distance, bx, by, bz, out):
    """The ramped vector potentials psi (m^2/s) at ``pts`` into ``out`` (N, 3)."""
    scale = amplitude / frequency
    s = t * time_scale
    flat = pts.reshape(pts.shape[0] * 3)  # flat indexing vectorises better
    for i in range(pts.shape[0]):
        x = flat[3 * i]
        y = flat[3 * i + 1]
        z = flat[3 * i + 2]
        psi = np.empty(3)
        for q in range(3):
            psi[q] = fbm_value(tables[q], x, y, z, frequency, octaves, lacunarity, gain,
                               s * DRIFT[q, 0], s * DRIFT[q, 1], s * DRIFT[q, 2], False)
            psi[q] *= scale
        psi[0] += 0.5 * (by * z - bz * y)
        psi[1] += 0.5 * (bz * x - bx * z)
        psi[2] += 0.5 * (bx * y - by * x)
        if ramp_distance > 0.0 and colliders.shape[0] > 0:
            d, nx, ny, nz, _ = packed_distance(colliders, x, y, z)
            a, _ = _ramp(d / ramp_distance)
            proj = nx * psi[0] + ny * psi[1] + nz * psi[2]
            psi[0] = a * psi[0] + (1.0 - a) * nx * proj
            psi[1] = a * psi[1] + (1.0 - a) * ny * proj
            psi[2] = a * psi[2] + (1.0 - a) * nz * proj
        for k in range(3):
            out[i, k] = psi[k]
