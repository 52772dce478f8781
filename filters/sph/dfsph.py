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
0) / rho0``) is below the tolerance, after at least two iterations (one for divergence, as in
SPlisHSPlasH).  This is the "pressure-as-unknown" form of the DFSPH iteration that SPlisHSPlasH
2.x uses; it is equivalent to the paper's stiffness-increment form but keeps a non-negative total
pressure, which is what the frames report.

**Warm start** (Bender & Koschier 2017, Sec. 4.4): each solve starts from half of the previous
step's converged pressure (IISPH's and SPlisHSPlasH's choice; starting from all of it converges
in half the iterations but lets a resting column slosh, because the pressure then lags the
motion).  The divergence solve stores ``kappa_v = pi_v dt`` (its pressure scales with 1/dt), the
density solve stores ``pi`` itself: SPlisHSPlasH stores ``pi dt^2``, which rescales the warm
start by ``(dt_old / dt_new)^2`` whenever the step changes, while the pressure that holds a
resting fluid up does not depend on the step.  Both live in the simulation state, so a
checkpoint resumes bit for bit.  The warm starts are capped (``pi dt^2 <= 2.5e-4``, ``kappa_v <=
0.5``, SPlisHSPlasH's values) and skipped where the particle is not compressed.

One fused pass per step (:func:`filters.sph.neighbourhood.neighbourhood_pass`) finds the neighbours of the cell-sorted
particles afresh (a DFSPH step moves particles farther than a Verlet skin could cover) and
computes densities, ``alpha_i`` and the kernel gradients, stored as one float32 scalar per pair.

All loops are gathers over the particle's own fixed-order neighbour list inside ``prange`` (no
scatter, no atomics) and every reduction is a per-particle array summed serially, so results are
bit-identical for any thread count.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .neighbourhood import boundary_reach_mask, neighbourhood_pass
from .viscosity import ImplicitViscosity

__all__ = ["DFSPHSolver", "boundary_reach_mask", "DFSPH_WARM_START_CAP", "DFSPH_WARM_START_CAP_V",
           "DFSPH_MIN_NEIGHBOURS"]

#: Cap of the density solver's warm start, as ``pi dt^2`` (dimensionless).
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
def _density_rate(v, x, ntab, ncnt, fw, gsum, out):
    """``(D rho_i / D t) / rho0 = sum_j V_j (v_i - v_j) . grad W_ij + v_i . sum_b V_b grad
    W_ib = v_i . gsum_i - sum_j fw_ij v_j . (x_i - x_j)`` (1/s); the boundary is static."""
    for i in prange(v.shape[0]):
        xi = x[i, 0]
        yi = x[i, 1]
        zi = x[i, 2]
        s = v[i, 0] * gsum[i, 0] + v[i, 1] * gsum[i, 1] + v[i, 2] * gsum[i, 2]
        for k in range(ncnt[i]):
            j = ntab[i, k]
            s -= fw[i, k] * (v[j, 0] * (xi - x[j, 0]) + v[j, 1] * (yi - x[j, 1])
                             + v[j, 2] * (zi - x[j, 2]))
        out[i] = s


@njit(parallel=True, cache=True, error_model="numpy")
def _pressure_accel(pi, x, ntab, ncnt, fw, gsum, a):
    """``a_i = -sum_j (pi_i + pi_j) V_j grad W_ij - pi_i sum_b V_b grad W_ib
    = -pi_i gsum_i - sum_j pi_j fw_ij (x_i - x_j)`` (m/s^2)."""
    for i in prange(pi.shape[0]):
        xi = x[i, 0]
        yi = x[i, 1]
        zi = x[i, 2]
        p = pi[i]
        ax = -p * gsum[i, 0]
        ay = -p * gsum[i, 1]
        az = -p * gsum[i, 2]
        for k in range(ncnt[i]):
            j = ntab[i, k]
            f = pi[j] * fw[i, k]
            ax -= f * (xi - x[j, 0])
            ay -= f * (yi - x[j, 1])
            az -= f * (zi - x[j, 2])
        a[i, 0] = ax
        a[i, 1] = ay
        a[i, 2] = az


@njit(parallel=True, cache=True, error_model="numpy")
def _jacobi(a, x, src, pi, factor, active, ntab, ncnt, fw, gsum, scale, omega, err):
    """One relaxed Jacobi update of ``pi`` (see the module docstring); ``err[i]`` gets the
    predicted compression before the update.  Returns the mean of ``err`` (serial sum)."""
    n = pi.shape[0]
    inv = 1.0 / scale
    for i in prange(n):
        xi = x[i, 0]
        yi = x[i, 1]
        zi = x[i, 2]
        s = a[i, 0] * gsum[i, 0] + a[i, 1] * gsum[i, 1] + a[i, 2] * gsum[i, 2]
        for k in range(ncnt[i]):
            j = ntab[i, k]
            s -= fw[i, k] * (a[j, 0] * (xi - x[j, 0]) + a[j, 1] * (yi - x[j, 1])
                             + a[j, 2] * (zi - x[j, 2]))
        r = src[i] - scale * s
        err[i] = -r if (r < 0.0 and active[i]) else 0.0
        pi[i] = max(pi[i] - omega * r * factor[i] * inv, 0.0)
    total = 0.0
    for i in range(n):
        total += err[i]
    return total / n if n else 0.0


@njit(parallel=True, cache=True, error_model="numpy")
def _density_start(rho, rate, rho0, dt, pi_prev, cap, src, pi, active):
    """Density solve set-up: source ``1 - rho*/rho0`` with ``rho* = rho + dt D rho / D t`` and
    the warm start ``pi = 0.5 min(pi_prev, cap / dt^2)`` where compressed, else 0."""
    inv2 = 1.0 / (dt * dt)
    for i in prange(rho.shape[0]):
        adv = rho[i] / rho0 + dt * rate[i]
        src[i] = 1.0 - adv
        active[i] = True
        pi[i] = 0.5 * min(pi_prev[i], cap * inv2) if adv > 1.0 else 0.0


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
    """``kappa = pi * scale`` (the stored warm start)."""
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
        Kernel id (:data:`filters.kernels.SMOOTHING_KERNELS`).
    max_density_error : float
        Tolerance of the mean predicted compression (fraction of ``rho0``).
    max_divergence_error : float
        Tolerance of the mean compression rate times ``dt`` (fraction of ``rho0`` per step).
    max_iterations : int
        Most iterations of each solve.
    min_iterations : int
        Fewest iterations of the density solve (2).
    min_divergence_iterations : int
        Fewest iterations of the divergence solve (1).

    Attributes
    ----------
    density_iterations, divergence_iterations : int
        Iterations of the last solves.
    density_error, divergence_error : float
        Mean errors the last solves reached (same units as the tolerances).
    """

    def __init__(self, rest_volume, support, kind, max_density_error, max_divergence_error,
                 max_iterations, min_iterations=2, min_divergence_iterations=2):
        self.volume = float(rest_volume)
        self.support = float(support)
        self.kind = int(kind)
        self.max_density_error = float(max_density_error)
        self.max_divergence_error = float(max_divergence_error)
        self.max_iterations = int(max_iterations)
        self.min_iterations = int(min_iterations)
        self.min_divergence_iterations = int(min_divergence_iterations)
        self.density_iterations = 0
        self.divergence_iterations = 0
        self.density_error = 0.0
        self.divergence_error = 0.0
        self.viscosity_iterations = 0
        self._n = -1
        self._cap = 40
        self._viscosity = ImplicitViscosity()

    def _allocate(self, n, cap):
        if n != self._n:
            self.factor = np.empty(n)
            self.gsum = np.empty((n, 3))
            self.nnb = np.empty(n, dtype=np.int32)
            self.ncnt = np.empty(n, dtype=np.int32)
            self.rho = np.empty(n)
            self.rate = np.empty(n)
            self.src = np.empty(n)
            self.pi = np.zeros(n)
            self.pi_v = np.zeros(n)
            self.active = np.empty(n, dtype=np.bool_)
            self.err = np.empty(n)
            self.a = np.empty((n, 3))
            self.fsum = np.empty(n)
            self.bvis = np.empty((n, 6))
            self._n = n
            self.ntab = None
        if self.ntab is None or self.ntab.shape[1] != cap + 1:
            self.ntab = np.empty((n, cap + 1), dtype=np.int32)  # + a spare column
            self.fw = np.empty((n, cap), dtype=np.float32)

    def neighbourhood(self, x, start, origin, cell, dims, boundary, mass):
        """Neighbours, kernel gradients, densities and ``alpha_i`` at positions ``x``.

        Parameters
        ----------
        x : (N, 3) float64
            Fluid positions (m), sorted by the grid described by the next four arguments.
        start : (C + 1,) int64
            Cell ranges of ``x`` (a stable counting sort of ``x`` by cell).
        origin : (3,) float64
            Lower corner of the grid (m).
        cell : float
            Cell edge (m), ``h / 2`` slightly padded.
        dims : (3,) int64
            Cells per axis.
        boundary : tuple
            ``(points, start, origin, cell, dims, mask, volumes, psi)`` of the boundary
            particles, sorted by their own grid of the same cell edge (``psi = rho0 V_b``, kg;
            ``mask`` from :func:`boundary_reach_mask`).
        mass : float
            Fluid particle mass (kg).

        Returns
        -------
        rho : (N,) float64
            Densities (kg/m^3), an internal array overwritten by the next call.
        """
        n = x.shape[0]
        xb, bstart, borigin, bcell, bdims, bmask, bvol, bpsi = boundary
        while True:
            self._allocate(n, self._cap)
            best = neighbourhood_pass(x, start, origin, cell, dims, xb, bstart, borigin, bcell,
                                  bdims, bmask, bvol, bpsi, self.volume, mass, self.support, self.kind,
                                  self.ntab, self.ncnt, self.fw, self.gsum, self.factor,
                                  self.nnb, self.rho, self.fsum, self.bvis)
            if best <= self._cap:
                break
            self._cap = int(best) + 8  # rare: a compressed particle has more neighbours
        self._x = x  # the solves of this step use these positions (the drift comes last)
        return self.rho

    def density_rate(self, v):
        """``(D rho_i / D t) / rho0`` (1/s) for velocities ``v`` (after :meth:`neighbourhood`)."""
        _density_rate(v, self._x, self.ntab, self.ncnt, self.fw, self.gsum, self.rate)
        return self.rate

    def _iterate(self, pi, scale, tol, min_iterations):
        it = 0
        err = math.inf
        while it < self.max_iterations and (it < min_iterations or err > tol):
            _pressure_accel(pi, self._x, self.ntab, self.ncnt, self.fw, self.gsum, self.a)
            err = _jacobi(self.a, self._x, self.src, pi, self.factor, self.active, self.ntab,
                          self.ncnt, self.fw, self.gsum, scale, _OMEGA, self.err)
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
        it, err = self._iterate(self.pi_v, dt, self.max_divergence_error / dt,
                               self.min_divergence_iterations)
        _pressure_accel(self.pi_v, self._x, self.ntab, self.ncnt, self.fw, self.gsum, self.a)
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

    def density_solve(self, v, rho, rho0, dt, pi_prev):
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
        pi_prev : (N,) float64
            The previous step's ``pi`` in (warm start), this step's out (m^2/s^2).
        """
        self.density_rate(v)
        _density_start(rho, self.rate, rho0, dt, pi_prev, DFSPH_WARM_START_CAP, self.src,
                       self.pi, self.active)
        it, err = self._iterate(self.pi, dt * dt, self.max_density_error, self.min_iterations)
        _pressure_accel(self.pi, self._x, self.ntab, self.ncnt, self.fw, self.gsum, self.a)
        _kick(v, self.a, dt)
        pi_prev[:] = self.pi
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
        it = self._viscosity.solve(v, x, dt, nu, nu_b, self.ntab, self.ncnt, self.fw,
                                   self.fsum, self.bvis, self.support, tolerance, max_iterations)
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
