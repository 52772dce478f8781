"""The first-order form for particles advected by a velocity field: one linearised backward
Euler step per particle."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..linalg.dense3 import implicit_step3
from ..validation import check_points
from .common import check_h

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["implicit_advection"]


@njit(parallel=True, cache=True)
def _implicit_advection(x, v, jac, h, out):
    """New positions ``out`` (N, 3); returns the number of singular particles."""
    bad = 0
    for i in prange(v.shape[0]):
        out[i, 0], out[i, 1], out[i, 2], det = implicit_step3(
            jac[i], h, x[i, 0], x[i, 1], x[i, 2], v[i, 0], v[i, 1], v[i, 2])
        if not (abs(det) > 1e-12):
            bad += 1
    return bad


def implicit_advection(positions: ArrayLike, velocity: ArrayLike, jacobian: ArrayLike,
                       h: float) -> NDArray[np.float64]:
    """Linearised backward Euler for particles in a velocity field ``dx/dt = v(x)``.

    Solves ``(I - h dv/dx) dx = h v(x^n)`` per particle by Cramer's rule (the solve of
    :class:`filters.advect.NoiseAdvection`'s ``"linearized_backward_euler"``,
    :func:`filters.linalg.dense3.implicit_step3`).  For a linear
    field ``v = A x`` this is exactly backward Euler, ``x^{n+1} = (I - h A)^{-1} x^n``.

    Parameters
    ----------
    positions : (N, 3) array_like
        Particle positions ``x^n`` (m).
    velocity : (N, 3) array_like
        Field velocity ``v(x^n)`` (m/s) at the particles.
    jacobian : (N, 3, 3) array_like
        Field gradient ``dv/dx`` (1/s) at the particles, ``jacobian[i, p, q] = dv_p/dx_q``.
    h : float
        Time step (s), > 0.

    Returns
    -------
    (N, 3) float64 array
        New positions ``x^n + dx`` (m).

    Raises
    ------
    ValueError
        If ``I - h dv/dx`` is singular for some particle, or shapes disagree.
    """
    x = check_points("positions", positions)
    v = check_points("velocity", velocity)
    jac = np.ascontiguousarray(jacobian, dtype=np.float64)
    if v.shape != x.shape or jac.shape != (x.shape[0], 3, 3):
        raise ValueError("velocity must be (N, 3) and jacobian (N, 3, 3) with N = len(positions)")
    h = check_h(h)
    out = np.empty_like(x)
    if _implicit_advection(x, v, jac, h, out):
        raise ValueError("I - h dv/dx is singular for some particle: reduce h")
    return out

