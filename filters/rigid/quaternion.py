"""Unit quaternions for orientations: ``q = (w, x, y, z)``, Hamilton's product, ``R(q) v = q v q*``.

A body's orientation ``q`` maps body-frame vectors to the world: ``v_world = R(q) v_body``.
The Numba functions work on one quaternion (``(4,)`` arrays) and are used by the per-body
kernels; :func:`quaternion_from_axis_angle` and :func:`rotation_matrices` are the NumPy helpers
for users (initial orientations, reading frames).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from ..validation import check_finite, check_finite_vector

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["quat_multiply", "quat_conjugate", "quat_normalize", "quat_to_matrix",
           "quat_from_matrix", "quat_axis_rotation", "quaternion_from_axis_angle",
           "rotation_matrices", "check_quaternions"]


@njit(cache=True)
def quat_multiply(a, b):
    """Hamilton product ``a b`` of two ``(4,)`` quaternions: the rotation ``b`` then ``a``."""
    out = np.empty(4)
    out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3]
    out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2]
    out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1]
    out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]
    return out


@njit(cache=True)
def quat_conjugate(q):
    """``q* = (w, -x, -y, -z)``, the inverse rotation of a unit quaternion."""
    out = np.empty(4)
    out[0] = q[0]
    out[1] = -q[1]
    out[2] = -q[2]
    out[3] = -q[3]
    return out


@njit(cache=True)
def quat_normalize(q):
    """``q / |q|`` (the sign is kept, so that an orientation varies continuously in time)."""
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    s = 1.0 / n
    out = np.empty(4)
    for k in range(4):
        out[k] = q[k] * s
    return out


@njit(cache=True)
def quat_to_matrix(q, out):
    """Write the rotation matrix ``R(q)`` (3, 3) of a unit quaternion into ``out``."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    out[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    out[0, 1] = 2.0 * (x * y - w * z)
    out[0, 2] = 2.0 * (x * z + w * y)
    out[1, 0] = 2.0 * (x * y + w * z)
    out[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    out[1, 2] = 2.0 * (y * z - w * x)
    out[2, 0] = 2.0 * (x * z - w * y)
    out[2, 1] = 2.0 * (y * z + w * x)
    out[2, 2] = 1.0 - 2.0 * (x * x + y * y)


@njit(cache=True)
def quat_from_matrix(m):
    """The unit quaternion of a rotation matrix (3, 3), by Shepperd's (1978)
    choice of the largest of ``w, x, y, z`` to divide by."""
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    q = np.empty(4)
    if tr >= m[0, 0] and tr >= m[1, 1] and tr >= m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + tr)
        q[0] = 0.25 * s
        q[1] = (m[2, 1] - m[1, 2]) / s
        q[2] = (m[0, 2] - m[2, 0]) / s
        q[3] = (m[1, 0] - m[0, 1]) / s
    elif m[0, 0] >= m[1, 1] and m[0, 0] >= m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q[0] = (m[2, 1] - m[1, 2]) / s
        q[1] = 0.25 * s
        q[2] = (m[0, 1] + m[1, 0]) / s
        q[3] = (m[0, 2] + m[2, 0]) / s
    elif m[1, 1] >= m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q[0] = (m[0, 2] - m[2, 0]) / s
        q[1] = (m[0, 1] + m[1, 0]) / s
        q[2] = 0.25 * s
        q[3] = (m[1, 2] + m[2, 1]) / s
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q[0] = (m[1, 0] - m[0, 1]) / s
        q[1] = (m[0, 2] + m[2, 0]) / s
        q[2] = (m[1, 2] + m[2, 1]) / s
        q[3] = 0.25 * s
    return quat_normalize(q)


@njit(cache=True)
def quat_axis_rotation(axis, angle):
    """The quaternion of a rotation by ``angle`` (rad) about the coordinate axis ``axis``
    (0, 1 or 2)."""
    q = np.zeros(4)
    q[0] = math.cos(0.5 * angle)
    q[1 + axis] = math.sin(0.5 * angle)
    return q


def quaternion_from_axis_angle(axis: ArrayLike, angle: float) -> np.ndarray:
    """The unit quaternion ``(w, x, y, z)`` of a rotation by ``angle`` (rad) about ``axis``.

    Parameters
    ----------
    axis : (3,) array_like
        Rotation axis, non-zero (normalised here).
    angle : float
        Angle (rad), counter-clockwise looking down the axis.

    Returns
    -------
    (4,) float64 array
    """
    a = check_finite_vector("axis", axis, 3)
    norm = float(np.linalg.norm(a))
    if norm == 0.0:
        raise ValueError("axis must be a non-zero vector")
    angle = check_finite("angle", angle)
    return np.r_[math.cos(0.5 * angle), math.sin(0.5 * angle) * a / norm]


def rotation_matrices(quaternions: ArrayLike) -> np.ndarray:
    """Rotation matrices (Q, 3, 3) of unit quaternions (Q, 4) ``(w, x, y, z)``."""
    q = check_quaternions("quaternions", quaternions, None)
    w, x, y, z = q.T
    r = np.empty((q.shape[0], 3, 3))
    r[:, 0, 0] = 1 - 2 * (y * y + z * z)
    r[:, 0, 1] = 2 * (x * y - w * z)
    r[:, 0, 2] = 2 * (x * z + w * y)
    r[:, 1, 0] = 2 * (x * y + w * z)
    r[:, 1, 1] = 1 - 2 * (x * x + z * z)
    r[:, 1, 2] = 2 * (y * z - w * x)
    r[:, 2, 0] = 2 * (x * z - w * y)
    r[:, 2, 1] = 2 * (y * z + w * x)
    r[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return r


def check_quaternions(name: str, value: ArrayLike, n: int | None,
                      normalize: bool = True) -> np.ndarray:
    """Return ``value`` as ``(n, 4) float64`` unit quaternions (a copy).

    With ``normalize`` they are divided by their norms (a round-off change); without, they are
    returned bit for bit (a state being restored).

    Raises
    ------
    ValueError
        If the shape is not ``(n, 4)``, a value is not finite, or a norm is not within 1e-6
        of 1 (a quaternion that is not a rotation).
    """
    try:
        q = np.array(value, dtype=np.float64, order="C", ndmin=2)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be an (N, 4) array of numbers") from None
    if q.ndim != 2 or q.shape[1] != 4 or (n is not None and q.shape[0] != n):
        want = "(N, 4)" if n is None else f"({n}, 4)"
        raise ValueError(f"{name} must have shape {want}, got {q.shape}")
    if not np.isfinite(q).all():
        raise ValueError(f"{name} contains NaN or infinite values")
    norms = np.linalg.norm(q, axis=1)
    if q.shape[0] and np.abs(norms - 1.0).max() > 1e-6:
        raise ValueError(f"{name} must be unit quaternions (w, x, y, z) with |q| = 1 "
                         f"(within 1e-6); norms range over [{norms.min():.6g}, {norms.max():.6g}]")
    if normalize:
        q /= norms[:, None]
    return q
