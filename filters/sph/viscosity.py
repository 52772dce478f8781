"""Implicit viscosity of Weiler, Koschier, Brand & Bender (2018), "A physically consistent
implicit viscosity solver for SPH fluids" (CGF 37(2)): ``(I - dt L) v' = v`` solved by
preconditioned conjugate gradients on the DFSPH solver's neighbour data (Numba, matrix free,
deterministic: gathers only, dot products summed serially)."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

__all__ = ["ImplicitViscosity"]


@njit(parallel=True, cache=True, error_model="numpy")
def _visc_apply(u, x, ntab, ncnt, fw, bvis, cf, cb, h, out):
    """``out = u - dt L u`` for the implicit viscosity of Weiler et al. (2018), with
    ``cf = 10 nu dt`` and ``cb = 10 nu_b dt`` (``2 (d + 2) = 10``)::

        (L u)_i = 10 nu sum_j V_j (u_ij . x_ij) / (r^2 + 0.01 h'^2) grad W_ij
                + 10 nu_b sum_b V_b (u_i . x_ib) / (r^2 + 0.01 h'^2) grad W_ib .
    """
    eps = 0.01 * 0.25 * h * h
    for i in prange(u.shape[0]):
        ux = u[i, 0]
        uy = u[i, 1]
        uz = u[i, 2]
        sx = 0.0
        sy = 0.0
        sz = 0.0
        for k in range(ncnt[i]):
            j = ntab[i, k]
            dx = x[i, 0] - x[j, 0]
            dy = x[i, 1] - x[j, 1]
            dz = x[i, 2] - x[j, 2]
            q = fw[i, k] * ((ux - u[j, 0]) * dx + (uy - u[j, 1]) * dy + (uz - u[j, 2]) * dz) / (
                dx * dx + dy * dy + dz * dz + eps)
            sx += q * dx
            sy += q * dy
            sz += q * dz
        b = bvis[i]
        out[i, 0] = ux - cf * sx - cb * (b[0] * ux + b[3] * uy + b[4] * uz)
        out[i, 1] = uy - cf * sy - cb * (b[3] * ux + b[1] * uy + b[5] * uz)
        out[i, 2] = uz - cf * sz - cb * (b[4] * ux + b[5] * uy + b[2] * uz)


@njit(parallel=True, cache=True, error_model="numpy")
def _visc_precond(fsum, bvis, cf, cb, pinv):
    """Inverse of the 3x3 blocks ``(1 - cf fsum_i / 3) I - cb bvis_i``, which approximate the
    diagonal blocks of ``I - dt L`` (the fluid part by its trace, ``sum_j fw_ij r^2 / (r^2 +
    0.01 h'^2) / 3`` with the factor ``r^2 / (r^2 + 0.01 h'^2) >= 0.99`` at the distances where
    neighbours sit dropped): a block-Jacobi preconditioner (``fsum``, ``bvis`` from
    :func:`filters.sph.neighbourhood.neighbourhood_pass`)."""
    for i in prange(fsum.shape[0]):
        d = 1.0 - cf * fsum[i] / 3.0
        a00 = d - cb * bvis[i, 0]
        a11 = d - cb * bvis[i, 1]
        a22 = d - cb * bvis[i, 2]
        a01 = -cb * bvis[i, 3]
        a02 = -cb * bvis[i, 4]
        a12 = -cb * bvis[i, 5]
        c00 = a11 * a22 - a12 * a12
        c01 = a02 * a12 - a01 * a22
        c02 = a01 * a12 - a02 * a11
        det = a00 * c00 + a01 * c01 + a02 * c02
        inv = 1.0 / det
        pinv[i, 0] = c00 * inv
        pinv[i, 1] = (a00 * a22 - a02 * a02) * inv
        pinv[i, 2] = (a00 * a11 - a01 * a01) * inv
        pinv[i, 3] = c01 * inv
        pinv[i, 4] = c02 * inv
        pinv[i, 5] = (a02 * a01 - a00 * a12) * inv


@njit(parallel=True, cache=True, error_model="numpy")
def _precond_apply(pinv, r, z):
    for i in prange(r.shape[0]):
        p = pinv[i]
        z[i, 0] = p[0] * r[i, 0] + p[3] * r[i, 1] + p[4] * r[i, 2]
        z[i, 1] = p[3] * r[i, 0] + p[1] * r[i, 1] + p[5] * r[i, 2]
        z[i, 2] = p[4] * r[i, 0] + p[5] * r[i, 1] + p[2] * r[i, 2]


@njit(cache=True, error_model="numpy")
def _dot(a, b):
    """Serial dot product of two (N, 3) arrays (fixed order: deterministic)."""
    s = 0.0
    for i in range(a.shape[0]):
        s += a[i, 0] * b[i, 0] + a[i, 1] * b[i, 1] + a[i, 2] * b[i, 2]
    return s


@njit(parallel=True, cache=True, error_model="numpy")
def _axpy(y, alpha, x):
    """``y += alpha x``."""
    for i in prange(y.shape[0]):
        for c in range(3):
            y[i, c] += alpha * x[i, c]


@njit(parallel=True, cache=True, error_model="numpy")
def _xpby(z, beta, p):
    """``p = z + beta p``."""
    for i in prange(p.shape[0]):
        for c in range(3):
            p[i, c] = z[i, c] + beta * p[i, c]


class ImplicitViscosity:
    """Workspace and conjugate-gradient loop of the implicit viscosity solve.

    Rest volumes make ``I - dt L`` symmetric positive definite; the boundary acts as a no-slip
    wall with its own viscosity, moving with its particles' velocities.  The preconditioner is block
    Jacobi on approximate
    diagonal blocks (:func:`_visc_precond`).
    """

    def __init__(self):
        self._n = -1

    def solve(self, v: np.ndarray, x: np.ndarray, dt: float, nu: float, nu_b: float,
              ntab: np.ndarray, ncnt: np.ndarray, fw: np.ndarray, fsum: np.ndarray,
              bvis: np.ndarray, h: float, tolerance: float = 1e-3, max_iterations: int = 100,
              bvv: np.ndarray | None = None) -> int:
        """Replace the velocities ``v`` (N, 3, m/s) by the solution of ``(I - dt L) v' = v``.

        Parameters
        ----------
        v, x : (N, 3) float64
            Velocities (m/s), updated, and the positions the neighbour data belong to (m).
        dt : float
            Step (s).
        nu, nu_b : float
            Kinematic viscosity of the fluid and against the boundary (m^2/s).
        ntab, ncnt, fw, fsum, bvis : arrays
            Neighbour rows, pair weights ``V W'(r) / r``, their sums and the boundary blocks
            (:func:`filters.sph.neighbourhood.neighbourhood_pass`).
        h : float
            Support radius (m).
        tolerance : float
            Stop at ``|r| <= tolerance |b|`` (relative residual).
        max_iterations : int
            Most CG iterations.
        bvv : (N, 3) float64, optional
            The moving boundary's velocity term ``sum_b f_b V_b (W'(r) / r) (v_b . x_ib) x_ib /
            (r^2 + 0.01 h'^2)`` (1/s) of the neighbourhood pass; None: a static boundary.

        Returns
        -------
        int
            CG iterations done.
        """
        n = v.shape[0]
        if n == 0 or (nu <= 0.0 and nu_b <= 0.0):
            return 0
        cf = 10.0 * nu * dt
        cb = 10.0 * nu_b * dt
        if self._n != n:
            self._pinv = np.empty((n, 6))
            self._r = np.empty((n, 3))
            self._z = np.empty((n, 3))
            self._p = np.empty((n, 3))
            self._q = np.empty((n, 3))
            self._n = n
        pinv, r, z, p, q = self._pinv, self._r, self._z, self._p, self._q
        b = v.copy()
        if bvv is not None:  # (I - dt L) v' = v with the boundary moving: b = v - cb bvv
            _axpy(b, -cb, bvv)
        _visc_precond(fsum, bvis, cf, cb, pinv)
        _visc_apply(v, x, ntab, ncnt, fw, bvis, cf, cb, h, q)
        r[:] = b
        r -= q
        bnorm2 = _dot(b, b)
        _precond_apply(pinv, r, z)
        p[:] = z
        rz = _dot(r, z)
        it = 0
        tol2 = tolerance * tolerance * bnorm2
        while it < max_iterations and _dot(r, r) > tol2:
            _visc_apply(p, x, ntab, ncnt, fw, bvis, cf, cb, h, q)
            pq = _dot(p, q)
            if not pq > 0.0:
                break
            alpha = rz / pq
            _axpy(v, alpha, p)
            _axpy(r, -alpha, q)
            _precond_apply(pinv, r, z)
            rz_new = _dot(r, z)
            _xpby(z, rz_new / rz, p)
            rz = rz_new
            it += 1
        return it
