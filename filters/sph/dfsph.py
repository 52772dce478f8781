"""Divergence-free SPH (DFSPH) pressure solvers in Numba, used by :class:`filters.sph.SPHLiquid`.

Bender & Koschier (2015) "Divergence-free smoothed particle hydrodynamics" (SCA) and (2017)
"Divergence-free SPH for incompressible and viscous fluids" (IEEE TVCG 23(3)) replace the stiff
equation of state of WCSPH by two implicit pressure solves per step, which allows steps bounded
by the velocity CFL condition alone (ten to twenty times larger than WCSPH's acoustic step):

* a **divergence-free solver** that makes ``D rho / D t = 0`` for the velocities at the start of
  the step, and
* a **constant-density solver** that makes the density predicted after the step equal to
  ``rho0`` once the non-pressure accelerations (gravity, viscosity, ...) are applied.

Both share the per-particle factor (Bender & Koschier 2017, eq. 11, in rest volumes
``V_j = m_j / rho0`` so that densities are ratios)::

    alpha_i = 1 / ( |sum_j V_j grad W_ij + sum_b V_b grad W_ib|^2 + sum_j |V_j grad W_ij|^2 )

computed once per step after the neighbourhood update.  Boundary particles (Akinci et al. 2012)
contribute to the density and to the first sum, and are pushed by the fluid particle's own
pressure term, as SPlisHSPlasH does.

The unknown of both solves is ``pi_i = rho0 p_i / rho_i^2`` (Bender & Koschier's ``kappa_i /
rho_i`` up to ``rho0``); the pressure acceleration is::

    a_i = - sum_j V_j (pi_i + pi_j) grad W_ij - pi_i sum_b V_b grad W_ib .

Each iteration is a relaxed Jacobi step on the pressure Poisson equation with the DFSPH
diagonal ``-scale / alpha_i`` (``scale = dt^2`` for density, ``dt`` for divergence)::

    pi_i <- max(pi_i - omega (s_i - (A pi)_i) alpha_i / scale, 0),   omega = 1/2,

with source ``s_i = 1 - rho*_i / rho0`` (density) or ``-(D rho_i / D t) / rho0`` (divergence)
and ``(A pi)_i = scale (sum_j V_j (a_i - a_j) . grad W_ij + a_i . sum_b V_b grad W_ib)``, the
change of the density ratio that the current pressures cause.  Clamping ``pi >= 0`` keeps the
free surface free of tension.  The solvers stop when the **average** predicted compression
``mean_i max(-(s_i - (A pi)_i), 0)`` (for divergence: per step, i.e. ``dt mean max(D rho / D t,
0) / rho0``) is below the tolerance, after at least ``min_iterations``.  This is the
"pressure-as-unknown" form of the DFSPH iteration that SPlisHSPlasH 2.x uses; it is equivalent
to the paper's stiffness-increment form but keeps a non-negative total pressure, which is what the
frames report.

**Warm start** (Bender & Koschier 2017, Sec. 4.4): each solve starts from half of the previous
step's converged pressure, stored time-step independent as ``kappa = pi dt^2`` (density) and
``kappa_v = pi_v dt`` (divergence) in the simulation state, so a checkpoint resumes bit for bit.
The warm start is capped (``kappa <= 2.5e-4``, ``kappa_v <= 0.5``, the values SPlisHSPlasH uses)
and skipped where the particle is not compressed.

All loops are gathers over the particle's own fixed-order neighbour list inside ``prange`` (no
scatter, no atomics) and every reduction is a per-particle array summed serially, so results are
bit-identical for any thread count.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..kernels import kernel_dw

__all__ = ["DFSPHSolver", "DFSPH_WARM_START_CAP", "DFSPH_WARM_START_CAP_V",
           "DFSPH_MIN_NEIGHBOURS"]

#: Cap of the density solver's warm start ``kappa = pi dt^2`` (dimensionless).
DFSPH_WARM_START_CAP = 2.5e-4
#: Cap of the divergence solver's warm start ``kappa_v = pi_v dt`` (m^2/s).
DFSPH_WARM_START_CAP_V = 0.5
#: Fewer neighbours (fluid plus boundary within the support) than this: no divergence solve for
#: that particle (particle deficiency at the free surface; SPlisHSPlasH uses 20 in 3D).
DFSPH_MIN_NEIGHBOURS = 20
_OMEGA = 0.5


# --------------------------------------------------------------------------------------------
# Numba kernels.
# --------------------------------------------------------------------------------------------
@njit(parallel=True, cache=True, error_model="numpy")
def _prepare(x, tab, cnt, xb, btab, bcnt, bvol, vol, h, kind, ntab, ncnt, grad, gb, factor,
             nnb, bvis):
    """Compact the Verlet lists to pairs within ``h`` and precompute per pair ``V_j grad W_ij``
    (1/m), per particle ``gb_i = sum_b V_b grad W_ib`` (1/m), the factor ``alpha_i`` (m^2),
    the number of neighbours within ``h`` (fluid plus boundary) and the boundary's viscosity
    block ``sum_b V_b (dW/dr / r) x_ib x_ib^T / (r^2 + 0.01 (h/2)^2)`` (1/m^3, xx yy zz xy xz
    yz)."""
    h2 = h * h
    eps = 0.01 * 0.25 * h2
    for i in prange(x.shape[0]):
        k2 = 0
        sx = 0.0
        sy = 0.0
        sz = 0.0
        sq = 0.0
        for k in range(cnt[i]):
            j = tab[i, k]
            dx = x[i, 0] - x[j, 0]
            dy = x[i, 1] - x[j, 1]
            dz = x[i, 2] - x[j, 2]
            r2 = dx * dx + dy * dy + dz * dz
            if r2 == 0.0 or r2 >= h2:
                continue
            r = math.sqrt(r2)
            f = vol * kernel_dw(kind, r, h) / r
            gx = f * dx
            gy = f * dy
            gz = f * dz
            ntab[i, k2] = j
            grad[i, k2, 0] = gx
            grad[i, k2, 1] = gy
            grad[i, k2, 2] = gz
            k2 += 1
            sx += gx
            sy += gy
            sz += gz
            sq += gx * gx + gy * gy + gz * gz
        ncnt[i] = k2
        bx = 0.0
        by = 0.0
        bz = 0.0
        nb = 0
        for c in range(6):
            bvis[i, c] = 0.0
        for k in range(bcnt[i]):
            b = btab[i, k]
            dx = x[i, 0] - xb[b, 0]
            dy = x[i, 1] - xb[b, 1]
            dz = x[i, 2] - xb[b, 2]
            r2 = dx * dx + dy * dy + dz * dz
            if r2 == 0.0 or r2 >= h2:
                continue
            r = math.sqrt(r2)
            f = bvol[b] * kernel_dw(kind, r, h) / r
            bx += f * dx
            by += f * dy
            bz += f * dz
            nb += 1
            q = f / (r2 + eps)
            bvis[i, 0] += q * dx * dx
            bvis[i, 1] += q * dy * dy
            bvis[i, 2] += q * dz * dz
            bvis[i, 3] += q * dx * dy
            bvis[i, 4] += q * dx * dz
            bvis[i, 5] += q * dy * dz
        gb[i, 0] = bx
        gb[i, 1] = by
        gb[i, 2] = bz
        nnb[i] = k2 + nb
        sx += bx
        sy += by
        sz += bz
        den = sx * sx + sy * sy + sz * sz + sq
        factor[i] = 1.0 / den if den > 1e-9 / (h * h) else 0.0


@njit(parallel=True, cache=True, error_model="numpy")
def _density_rate(v, ntab, ncnt, grad, gb, out):
    """``(D rho_i / D t) / rho0 = sum_j V_j (v_i - v_j) . grad W_ij + v_i . gb_i`` (1/s); the
    boundary is static."""
    for i in prange(v.shape[0]):
        vx = v[i, 0]
        vy = v[i, 1]
        vz = v[i, 2]
        s = vx * gb[i, 0] + vy * gb[i, 1] + vz * gb[i, 2]
        for k in range(ncnt[i]):
            j = ntab[i, k]
            s += ((vx - v[j, 0]) * grad[i, k, 0] + (vy - v[j, 1]) * grad[i, k, 1]
                  + (vz - v[j, 2]) * grad[i, k, 2])
        out[i] = s


@njit(parallel=True, cache=True, error_model="numpy")
def _pressure_accel(pi, ntab, ncnt, grad, gb, a):
    """``a_i = -sum_j (pi_i + pi_j) V_j grad W_ij - pi_i gb_i`` (m/s^2)."""
    for i in prange(pi.shape[0]):
        p = pi[i]
        ax = -p * gb[i, 0]
        ay = -p * gb[i, 1]
        az = -p * gb[i, 2]
        for k in range(ncnt[i]):
            f = p + pi[ntab[i, k]]
            ax -= f * grad[i, k, 0]
            ay -= f * grad[i, k, 1]
            az -= f * grad[i, k, 2]
        a[i, 0] = ax
        a[i, 1] = ay
        a[i, 2] = az


@njit(parallel=True, cache=True, error_model="numpy")
def _jacobi(a, src, pi, factor, active, ntab, ncnt, grad, gb, scale, omega, err):
    """One relaxed Jacobi update of ``pi`` (see the module docstring); ``err[i]`` gets the
    predicted compression before the update.  Returns the mean of ``err`` (serial sum)."""
    n = pi.shape[0]
    inv = 1.0 / scale
    for i in prange(n):
        ax = a[i, 0]
        ay = a[i, 1]
        az = a[i, 2]
        s = ax * gb[i, 0] + ay * gb[i, 1] + az * gb[i, 2]
        for k in range(ncnt[i]):
            j = ntab[i, k]
            s += ((ax - a[j, 0]) * grad[i, k, 0] + (ay - a[j, 1]) * grad[i, k, 1]
                  + (az - a[j, 2]) * grad[i, k, 2])
        r = src[i] - scale * s
        err[i] = -r if (r < 0.0 and active[i]) else 0.0
        pi[i] = max(pi[i] - omega * r * factor[i] * inv, 0.0)
    total = 0.0
    for i in range(n):
        total += err[i]
    return total / n if n else 0.0


@njit(parallel=True, cache=True, error_model="numpy")
def _density_start(rho, rate, rho0, dt, kappa, cap, src, pi, active):
    """Density solve set-up: source ``1 - rho*/rho0`` with ``rho* = rho + dt D rho / D t`` and
    the warm start ``pi = 0.5 min(kappa, cap) / dt^2`` where compressed, else 0."""
    inv2 = 1.0 / (dt * dt)
    for i in prange(rho.shape[0]):
        adv = rho[i] / rho0 + dt * rate[i]
        src[i] = 1.0 - adv
        active[i] = True
        pi[i] = 0.5 * min(kappa[i], cap) * inv2 if adv > 1.0 else 0.0


@njit(parallel=True, cache=True, error_model="numpy")
def _divergence_start(rate, nnb, min_nb, dt, kappa_v, cap, src, pi, active):
    """Divergence solve set-up: source ``-max(D rho / D t, 0) / rho0`` (0 for particles with
    fewer than ``min_nb`` neighbours) and the warm start ``pi = 0.5 min(kappa_v, cap) / dt``."""
    inv = 1.0 / dt
    for i in prange(rate.shape[0]):
        ok = nnb[i] >= min_nb
        d = max(rate[i], 0.0) if ok else 0.0
        src[i] = -d
        active[i] = ok
        pi[i] = 0.5 * min(kappa_v[i], cap) * inv if d > 0.0 else 0.0


@njit(parallel=True, cache=True, error_model="numpy")
def _kick(v, a, dt):
    """``v += dt a``."""
    for i in prange(v.shape[0]):
        for c in range(3):
            v[i, c] += dt * a[i, c]


@njit(parallel=True, cache=True, error_model="numpy")
def _store(pi, scale, kappa):
    """``kappa = pi * scale`` (time-step independent warm start)."""
    for i in prange(pi.shape[0]):
        kappa[i] = pi[i] * scale


@njit(parallel=True, cache=True, error_model="numpy")
def _drift(x, v, dt):
    """``x += dt v``; returns ``max |v|`` (m/s)."""
    n = x.shape[0]
    vmax = np.zeros(n)
    for i in prange(n):
        s = 0.0
        for c in range(3):
            x[i, c] += dt * v[i, c]
            s += v[i, c] * v[i, c]
        vmax[i] = s
    best = 0.0
    for i in range(n):
        best = max(best, vmax[i])
    return math.sqrt(best)


@njit(parallel=True, cache=True, error_model="numpy")
def _visc_apply(u, x, ntab, ncnt, grad, bvis, cf, cb, h, out):
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
            q = ((ux - u[j, 0]) * dx + (uy - u[j, 1]) * dy + (uz - u[j, 2]) * dz) / (
                dx * dx + dy * dy + dz * dz + eps)
            sx += q * grad[i, k, 0]
            sy += q * grad[i, k, 1]
            sz += q * grad[i, k, 2]
        b = bvis[i]
        out[i, 0] = ux - cf * sx - cb * (b[0] * ux + b[3] * uy + b[4] * uz)
        out[i, 1] = uy - cf * sy - cb * (b[3] * ux + b[1] * uy + b[5] * uz)
        out[i, 2] = uz - cf * sz - cb * (b[4] * ux + b[5] * uy + b[2] * uz)


@njit(parallel=True, cache=True, error_model="numpy")
def _visc_precond(x, ntab, ncnt, grad, bvis, cf, cb, h, pinv):
    """Inverse of the 3x3 diagonal blocks of ``I - dt L`` (block-Jacobi preconditioner)."""
    eps = 0.01 * 0.25 * h * h
    for i in prange(x.shape[0]):
        m = np.zeros(6)
        for k in range(ncnt[i]):
            j = ntab[i, k]
            dx = x[i, 0] - x[j, 0]
            dy = x[i, 1] - x[j, 1]
            dz = x[i, 2] - x[j, 2]
            q = 1.0 / (dx * dx + dy * dy + dz * dz + eps)
            gx = grad[i, k, 0] * q
            gy = grad[i, k, 1] * q
            gz = grad[i, k, 2] * q
            m[0] += gx * dx
            m[1] += gy * dy
            m[2] += gz * dz
            m[3] += gx * dy
            m[4] += gx * dz
            m[5] += gy * dz
        a00 = 1.0 - cf * m[0] - cb * bvis[i, 0]
        a11 = 1.0 - cf * m[1] - cb * bvis[i, 1]
        a22 = 1.0 - cf * m[2] - cb * bvis[i, 2]
        a01 = -cf * m[3] - cb * bvis[i, 3]
        a02 = -cf * m[4] - cb * bvis[i, 4]
        a12 = -cf * m[5] - cb * bvis[i, 5]
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


# --------------------------------------------------------------------------------------------
# The solver object.
# --------------------------------------------------------------------------------------------
class DFSPHSolver:
    """Work arrays and the two DFSPH solves for one fluid (Bender & Koschier 2015, 2017).

    Parameters
    ----------
    rest_volume : float
        ``V = m / rho0`` of a fluid particle (m^3).
    support : float
        Kernel support radius ``h`` (m).
    kind : int
        Kernel id (:data:`filters.kernels.KERNELS`).
    max_density_error : float
        Tolerance of the mean predicted compression (fraction of ``rho0``).
    max_divergence_error : float
        Tolerance of the mean compression rate times ``dt`` (fraction of ``rho0`` per step).
    max_iterations : int
        Most iterations of each solve.
    min_iterations : int
        Fewest iterations of each solve (2).

    Attributes
    ----------
    density_iterations, divergence_iterations : int
        Iterations of the last solves.
    density_error, divergence_error : float
        Mean errors the last solves reached (same units as the tolerances).
    """

    def __init__(self, rest_volume, support, kind, max_density_error, max_divergence_error,
                 max_iterations, min_iterations=2):
        self.volume = float(rest_volume)
        self.support = float(support)
        self.kind = int(kind)
        self.max_density_error = float(max_density_error)
        self.max_divergence_error = float(max_divergence_error)
        self.max_iterations = int(max_iterations)
        self.min_iterations = int(min_iterations)
        self.density_iterations = 0
        self.divergence_iterations = 0
        self.density_error = 0.0
        self.divergence_error = 0.0
        self.viscosity_iterations = 0
        self._n = -1
        self._cap = -1

    def _allocate(self, n, cap):
        if n != self._n:
            self.factor = np.empty(n)
            self.gb = np.empty((n, 3))
            self.nnb = np.empty(n, dtype=np.int32)
            self.ncnt = np.empty(n, dtype=np.int32)
            self.rate = np.empty(n)
            self.src = np.empty(n)
            self.pi = np.zeros(n)
            self.pi_v = np.zeros(n)
            self.active = np.empty(n, dtype=np.bool_)
            self.err = np.empty(n)
            self.a = np.empty((n, 3))
            self.bvis = np.empty((n, 6))
            self._n = n
            self._cap = -1
        if cap != self._cap:
            self.ntab = np.empty((n, cap), dtype=np.int32)
            self.grad = np.empty((n, cap, 3))
            self._cap = cap

    def prepare(self, x, tab, cnt, xb, btab, bcnt, bvol):
        """Compact the neighbour lists, precompute the kernel gradients and ``alpha_i``.

        Parameters
        ----------
        x : (N, 3) float64
            Fluid positions (m).
        tab, cnt : (N, K) int32, (N,) int32
            Fluid neighbour lists (any superset of the pairs within ``h``, rows sorted).
        xb : (M, 3) float64
            Boundary positions (m).
        btab, bcnt : (N, L) int32, (N,) int32
            Boundary neighbour lists of the fluid particles.
        bvol : (M,) float64
            Boundary volumes (m^3).
        """
        n = x.shape[0]
        self._allocate(n, max(int(tab.shape[1]), 1))
        _prepare(x, tab, cnt, xb, btab, bcnt, bvol, self.volume, self.support, self.kind,
                 self.ntab, self.ncnt, self.grad, self.gb, self.factor, self.nnb, self.bvis)

    def density_rate(self, v):
        """``(D rho_i / D t) / rho0`` (1/s) for velocities ``v`` (after :meth:`prepare`)."""
        _density_rate(v, self.ntab, self.ncnt, self.grad, self.gb, self.rate)
        return self.rate

    def _iterate(self, pi, scale, tol):
        it = 0
        err = math.inf
        while it < self.max_iterations and (it < self.min_iterations or err > tol):
            _pressure_accel(pi, self.ntab, self.ncnt, self.grad, self.gb, self.a)
            err = _jacobi(self.a, self.src, pi, self.factor, self.active, self.ntab, self.ncnt,
                          self.grad, self.gb, scale, _OMEGA, self.err)
            it += 1
            if not math.isfinite(err):
                break
        return it, err

    def divergence_solve(self, v, dt, kappa_v):
        """Make the velocities divergence free (Bender & Koschier 2017, Alg. 2), in place.

        Parameters
        ----------
        v : (N, 3) float64
            Velocities (m/s), updated.
        dt : float
            Step (s).
        kappa_v : (N,) float64
            Warm start in, converged ``pi_v dt`` out (m^2/s).
        """
        self.density_rate(v)
        _divergence_start(self.rate, self.nnb, DFSPH_MIN_NEIGHBOURS, dt, kappa_v,
                          DFSPH_WARM_START_CAP_V, self.src, self.pi_v, self.active)
        # err is a mean rate (1/s); the tolerance is per step.
        it, err = self._iterate(self.pi_v, dt, self.max_divergence_error / dt)
        _pressure_accel(self.pi_v, self.ntab, self.ncnt, self.grad, self.gb, self.a)
        _kick(v, self.a, dt)
        _store(self.pi_v, dt, kappa_v)
        self.divergence_iterations = it
        self.divergence_error = float(err) * dt

    def skip_divergence(self, kappa_v):
        """No divergence solve this step: zero pressure and warm start."""
        self.pi_v[:] = 0.0
        kappa_v[:] = 0.0
        self.divergence_iterations = 0
        self.divergence_error = 0.0

    def density_solve(self, v, rho, rho0, dt, kappa):
        """Make the predicted density ``rho0`` (Bender & Koschier 2017, Alg. 3), in place.

        Parameters
        ----------
        v : (N, 3) float64
            Velocities after the non-pressure accelerations (m/s), updated.
        rho : (N,) float64
            Densities at the current positions (kg/m^3).
        rho0 : float
            Rest density (kg/m^3).
        dt : float
            Step (s).
        kappa : (N,) float64
            Warm start in, converged ``pi dt^2`` out (dimensionless).
        """
        self.density_rate(v)
        _density_start(rho, self.rate, rho0, dt, kappa, DFSPH_WARM_START_CAP, self.src,
                       self.pi, self.active)
        it, err = self._iterate(self.pi, dt * dt, self.max_density_error)
        _pressure_accel(self.pi, self.ntab, self.ncnt, self.grad, self.gb, self.a)
        _kick(v, self.a, dt)
        _store(self.pi, dt * dt, kappa)
        self.density_iterations = it
        self.density_error = float(err)

    def viscosity_solve(self, v, x, dt, nu, nu_b, tolerance=1e-3, max_iterations=100):
        """Implicit viscosity (Weiler, Koschier, Brand & Bender 2018, "A physically consistent
        implicit viscosity solver for SPH fluids", CGF 37(2)): solve ``(I - dt L) v' = v`` by
        conjugate gradients with a block-Jacobi preconditioner, in place.

        Rest volumes make the matrix symmetric positive definite; the boundary acts as a static
        no-slip wall with ``nu_b``.  Stops at ``|r| <= tolerance |b|`` (relative residual).
        Returns the number of iterations.

        Parameters
        ----------
        v : (N, 3) float64
            Velocities (m/s), replaced by the solution.
        x : (N, 3) float64
            Positions (m) the neighbour data were prepared at.
        dt : float
            Step (s).
        nu, nu_b : float
            Kinematic viscosity of the fluid and against the boundary (m^2/s).
        """
        n = v.shape[0]
        if n == 0 or (nu <= 0.0 and nu_b <= 0.0):
            self.viscosity_iterations = 0
            return 0
        cf = 10.0 * nu * dt
        cb = 10.0 * nu_b * dt
        h = self.support
        if getattr(self, "_vn", -1) != n:
            self._pinv = np.empty((n, 6))
            self._r = np.empty((n, 3))
            self._z = np.empty((n, 3))
            self._p = np.empty((n, 3))
            self._q = np.empty((n, 3))
            self._vn = n
        pinv, r, z, p, q = self._pinv, self._r, self._z, self._p, self._q
        b = v.copy()
        _visc_precond(x, self.ntab, self.ncnt, self.grad, self.bvis, cf, cb, h, pinv)
        _visc_apply(v, x, self.ntab, self.ncnt, self.grad, self.bvis, cf, cb, h, q)
        r[:] = b
        r -= q
        bnorm2 = _dot(b, b)
        _precond_apply(pinv, r, z)
        p[:] = z
        rz = _dot(r, z)
        it = 0
        tol2 = tolerance * tolerance * bnorm2
        while it < max_iterations and _dot(r, r) > tol2:
            _visc_apply(p, x, self.ntab, self.ncnt, self.grad, self.bvis, cf, cb, h, q)
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
        self.viscosity_iterations = it
        return it

    @staticmethod
    def kick(v, a, dt):
        """``v += dt a`` in parallel (m/s)."""
        _kick(v, a, dt)

    @staticmethod
    def drift(x, v, dt):
        """``x += dt v`` in parallel; returns ``max |v|`` (m/s)."""
        return float(_drift(x, v, dt))
