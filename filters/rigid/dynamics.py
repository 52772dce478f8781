"""Rigid-body motion without contact: the kick, the drift, and forces applied at points.

A step of ``symplectic_euler`` is a *kick* -- ``v += h (g + F / m)``, ``L += h tau`` (world
angular momentum ``L = I_w w``, ``I_w = R I_b R^T``), contact impulses -- then a *drift* with
the new velocities: ``x += h v`` and the orientation moved along the exact flow of the
torque-free body with the new ``L``, approximated by the symmetric splitting of its kinetic
energy ``T = sum_k Pi_k^2 / (2 I_k)`` (``Pi = R^T L`` in the principal axes) into rotations
about the principal axes, ``k = 1, 2, 3, 2, 1`` for ``h/2, h/2, h, h/2, h/2`` (McLachlan 1993,
"Explicit Lie-Poisson integration and the Euler equations", Phys. Rev. Lett. 71; Reich 1994;
Dullweber, Leimkuhler & McLachlan 1997, "Symplectic splitting methods for rigid body molecular
dynamics", J. Chem. Phys. 107).  Each rotation about a principal axis is exact: ``Pi_k`` and
the world ``L`` stay constant through it.  The gyroscopic term ``w x I w`` is thus integrated
without linearisation: torque-free, ``L`` is conserved to round-off and the energy error is
bounded, of second order in ``h`` (no drift), for any step.  ``euler`` drifts with the velocities
of the start of the step instead.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..elastic.threads import serial_below
from .quaternion import (
    quat_axis_rotation,
    quat_conjugate,
    quat_multiply,
    quat_normalize,
    quat_to_matrix,
)

__all__ = ["body_rotations", "world_inverse_inertia", "kick", "drift", "points_to_world",
           "point_force_sums", "FORCE_CHUNKS", "PARALLEL_MIN_POINTS"]

#: Fixed number of partial sums of :func:`point_force_sums`: the summation order, hence the
#: result to the bit, does not depend on the thread count.
FORCE_CHUNKS = 64

#: Below this many points the point kernels run on one thread.
PARALLEL_MIN_POINTS = 20_000


@njit(cache=True)
def body_rotations(orientations, out):
    """Rotation matrices ``out`` (B, 3, 3) of the orientations (B, 4)."""
    for b in range(orientations.shape[0]):
        quat_to_matrix(orientations[b], out[b])


@njit(cache=True)
def world_inverse_inertia(rotations, inverse_inertia, fixed, out):
    """``R I_b^-1 R^T`` (B, 3, 3) for every body; zero for fixed bodies."""
    for b in range(rotations.shape[0]):
        r = rotations[b]
        for i in range(3):
            for j in range(3):
                s = 0.0
                if not fixed[b]:
                    for k in range(3):
                        for m in range(3):
                            s += r[i, k] * inverse_inertia[b, k, m] * r[j, m]
                out[b, i, j] = s


@njit(cache=True)
def kick(velocities, angular, inverse_mass, inverse_inertia_world, forces, torques, gravity, h,
         fixed, out_v, out_w):
    """Velocities after the forces of a step: ``v + h (g + F / m)``, ``w + h I_w^-1 tau``."""
    for b in range(velocities.shape[0]):
        for k in range(3):
            if fixed[b]:
                out_v[b, k] = 0.0
                out_w[b, k] = 0.0
            else:
                out_v[b, k] = velocities[b, k] + h * (gravity[k] + forces[b, k] * inverse_mass[b])
                s = 0.0
                for m in range(3):
                    s += inverse_inertia_world[b, k, m] * torques[b, m]
                out_w[b, k] = angular[b, k] + h * s


@njit(cache=True)
def _free_rotation(qp, pi, moments, h):
    """Move the principal-frame orientation ``qp`` and body angular momentum ``pi`` along the
    torque-free flow for ``h`` by the splitting 1, 2, 3, 2, 1."""
    axes = (0, 1, 2, 1, 0)
    fractions = (0.5, 0.5, 1.0, 0.5, 0.5)
    for s in range(5):
        k = axes[s]
        theta = fractions[s] * h * pi[k] / moments[k]
        c = math.cos(theta)
        sn = math.sin(theta)
        i = (k + 1) % 3
        j = (k + 2) % 3
        # Pi <- Rot_k(-theta) Pi ; q <- q Rot_k(theta)
        a = pi[i]
        b = pi[j]
        pi[i] = c * a + sn * b
        pi[j] = -sn * a + c * b
        qp = quat_multiply(qp, quat_axis_rotation(k, theta))
    return qp


@njit(cache=True)
def drift(positions, orientations, v_drift, w_drift, w_new, v_push, w_push, moments,
          principal, fixed, h, out_w):
    """Move positions and orientations (B, 3), (B, 4) in place by one step ``h`` (s).

    ``x += h (v_drift + v_push)``; the orientation follows the torque-free flow of the angular
    momentum of ``w_drift`` (world, rad/s), then turns by ``h w_push``; ``out_w`` (B, 3) gets
    the angular velocity of the angular momentum of ``w_new`` in the new orientation.
    ``v_push``/``w_push`` are the pseudo-velocities that separate overlapping bodies; they move
    the bodies but are not kept.  ``moments`` (B, 3) and ``principal`` (B, 4) are the principal
    moments and the rotation from the principal axes to the body frame.
    """
    rp = np.empty((3, 3))
    pi = np.empty(3)
    lw = np.empty(3)
    for b in range(positions.shape[0]):
        if fixed[b]:
            for k in range(3):
                out_w[b, k] = 0.0
            continue
        for k in range(3):
            positions[b, k] += h * (v_drift[b, k] + v_push[b, k])
        qp = quat_multiply(orientations[b], principal[b])
        quat_to_matrix(qp, rp)
        # world angular momentum of w_new, and body (principal) momentum of w_drift
        for i in range(3):
            s_new = 0.0
            s_drift = 0.0
            for k in range(3):
                s_new += rp[k, i] * w_new[b, k]
                s_drift += rp[k, i] * w_drift[b, k]
            pi[i] = moments[b, i] * s_drift
            lw[i] = moments[b, i] * s_new   # body components for now
        for i in range(3):
            out_w[b, i] = rp[i, 0] * lw[0] + rp[i, 1] * lw[1] + rp[i, 2] * lw[2]
        for i in range(3):
            lw[i] = out_w[b, i]             # world angular momentum of w_new
        qp = _free_rotation(qp, pi, moments[b], h)
        wx, wy, wz = w_push[b, 0], w_push[b, 1], w_push[b, 2]
        wn = math.sqrt(wx * wx + wy * wy + wz * wz)
        if wn > 0.0:
            half = 0.5 * h * wn
            dq = np.empty(4)
            dq[0] = math.cos(half)
            sn = math.sin(half) / wn
            dq[1] = sn * wx
            dq[2] = sn * wy
            dq[3] = sn * wz
            qp = quat_multiply(dq, qp)
        qp = quat_normalize(qp)
        quat_to_matrix(qp, rp)
        for i in range(3):
            pi[i] = (rp[0, i] * lw[0] + rp[1, i] * lw[1] + rp[2, i] * lw[2]) / moments[b, i]
        for i in range(3):
            out_w[b, i] = rp[i, 0] * pi[0] + rp[i, 1] * pi[1] + rp[i, 2] * pi[2]
        q = quat_normalize(quat_multiply(qp, quat_conjugate(principal[b])))
        for k in range(4):
            orientations[b, k] = q[k]


@njit(parallel=True, cache=True)
def points_to_world(points, bodies, positions, rotations, velocities, angular, out_x, out_v):
    """World positions ``x_b + R_b X`` and velocities ``v_b + w_b x (R_b X)`` (N, 3) of
    body-frame points ``X`` (N, 3) of bodies ``bodies`` (N,)."""
    for i in prange(points.shape[0]):
        b = bodies[i]
        r = rotations[b]
        rx = r[0, 0] * points[i, 0] + r[0, 1] * points[i, 1] + r[0, 2] * points[i, 2]
        ry = r[1, 0] * points[i, 0] + r[1, 1] * points[i, 1] + r[1, 2] * points[i, 2]
        rz = r[2, 0] * points[i, 0] + r[2, 1] * points[i, 1] + r[2, 2] * points[i, 2]
        out_x[i, 0] = positions[b, 0] + rx
        out_x[i, 1] = positions[b, 1] + ry
        out_x[i, 2] = positions[b, 2] + rz
        wx, wy, wz = angular[b, 0], angular[b, 1], angular[b, 2]
        out_v[i, 0] = velocities[b, 0] + wy * rz - wz * ry
        out_v[i, 1] = velocities[b, 1] + wz * rx - wx * rz
        out_v[i, 2] = velocities[b, 2] + wx * ry - wy * rx


@njit(parallel=True, cache=True)
def _partial_sums(points, forces, bodies, centers, partial):
    n = points.shape[0]
    chunks = partial.shape[0]
    for c in prange(chunks):
        lo = (n * c) // chunks
        hi = (n * (c + 1)) // chunks
        for i in range(lo, hi):
            b = bodies[i]
            fx, fy, fz = forces[i, 0], forces[i, 1], forces[i, 2]
            rx = points[i, 0] - centers[b, 0]
            ry = points[i, 1] - centers[b, 1]
            rz = points[i, 2] - centers[b, 2]
            partial[c, b, 0] += fx
            partial[c, b, 1] += fy
            partial[c, b, 2] += fz
            partial[c, b, 3] += ry * fz - rz * fy
            partial[c, b, 4] += rz * fx - rx * fz
            partial[c, b, 5] += rx * fy - ry * fx


def point_force_sums(points: np.ndarray, forces: np.ndarray, bodies: np.ndarray,
                     centers: np.ndarray) -> np.ndarray:
    """Total force and torque about each body's centre of forces applied at points.

    Parameters
    ----------
    points : (N, 3) float64 C-contiguous array
        World points of application (m).
    forces : (N, 3) float64 C-contiguous array
        Forces (N).
    bodies : (N,) int64 array
        Body of each point, in ``[0, B)``.
    centers : (B, 3) float64 array
        Centres of mass (m).

    Returns
    -------
    (B, 6) float64 array
        Force (N) and torque (N m) ``sum (x_i - c_b) x f_i`` per body, summed in
        :data:`FORCE_CHUNKS` fixed partial sums (bitwise the same on any number of threads).
    """
    partial = np.zeros((FORCE_CHUNKS, centers.shape[0], 6))
    if points.shape[0]:
        with serial_below(points.shape[0], PARALLEL_MIN_POINTS):
            _partial_sums(points, forces, bodies, centers, partial)
    return partial.sum(axis=0)
