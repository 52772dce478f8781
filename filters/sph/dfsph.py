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
pressure term, as SPlisHSPlasH does.  A moving boundary's velocity ``v_b`` enters the density
rate as ``sum_b V_b (v_i - v_b) . grad W_ib``.

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
0) / rho0``) is below the tolerance, after at least two iterations (one for divergence), as in
SPlisHSPlasH.  This is the "pressure-as-unknown" form of the DFSPH iteration that SPlisHSPlasH
2.x uses; it is equivalent to the paper's stiffness-increment form but keeps a non-negative total
pressure, which is what the frames report.

The density solve also iterates until no particle is predicted compressed by more than
:data:`DFSPH_PEAK_ERROR` (10) times the tolerance (1 % at the default 0.1 %).  The average alone
lets a few particles keep a large compression while it hardly moves: those pressed onto a wall
at an impact, and in a tall released column, which sags in its first steps (its pressure far
under hydrostatic: the Jacobi sweeps carry it up one layer at a time), the bottom layers next to
the back wall when the column recompresses (the 118-layer bench column: pressure there from
about 0 to three times hydrostatic within 5 ms, 0.11-0.13 s after the release).  The peak
condition does not remove the sag (a 50-layer column at 4 mm: 1 % of hydrostatic a quarter of
the way up at 0.01 s, as without it), but the solve no longer stops with those particles
compressed.  Measured on the bench dam break, worst particle after the first 50 ms at 10k / 200k
particles: 1.6 / 6.5 % with the average alone, 1.6 / 0.93 % with both (SPlisHSPlasH 1.6 / 4.0
%), for -1.5 / +6.7 % density sweeps a step and +2.5 / -2 % steps.  With 5 times the tolerance:
1.4 / 0.70 %, for 13 / 10 % more sweeps.  Tried and not kept: Chebyshev weights on the sweeps
(Wang 2015, "A Chebyshev semi-iterative approach for accelerating projective and position-based
dynamics", ACM TOG 34(6)) reached the same tolerances in 40 % fewer sweeps, but the pressure
they stop at is rough: a settled column's pressure gradient spread 0.049 from frame to frame
instead of 0.028, and its particles jittered at four times the speed.

**Walls that hold.**  Clamped at zero, the pressure cannot keep a particle that lacks fluid
neighbours off a wall: a lone particle, or one in a sheet a particle thick, has a density below
``rho0`` until it overlaps the wall by a third of a spacing, and sinks into it (measured: the
dam break's thin front leaked 855 particles through the floor and walls of a 10k-particle tank
in 0.5 s; Akinci's pressure mirroring, Band et al. 2018's extrapolated boundary pressures and
volume maps (Koschier & Bender 2017) all act through that same clamped pressure).  The density
solve therefore carries, for every particle within reach of the boundary, one-sided wall
constraints solved by the same Jacobi sweeps: the part of the kernel a wall fills,
``phi_ik = sum_{b in k} V_b W_ib``, read as an equivalent distance ``d_ik`` to a flat wall
(:mod:`filters.sph.wall_profile`), must stay at least ``d_min`` after the step::

    dt (v_i - v_b) . grad phi_ik  <=  (d_ik - d_min) g(d_ik),

linearised with the exact slope ``g`` of a flat wall, so that next to a flat wall the constraint
is exact in the distance.  It is enforced by a **wall pressure** ``pw_ik >= 0`` that acts
between particle ``i`` and that wall only, ``a_i -= pw_ik sum_{b in k} V_b grad W_ib`` (the
boundary's mirrored pressure raised where the fluid's is too low), updated like ``pi`` with the
diagonal ``scale |grad phi_ik|^2``.  The walls ``k`` of a particle are the whole boundary
(``d_min`` 0.1 spacings; in a three-wall corner of the fluid lattice the equivalent distance is
0.15) and each single wall, told apart by the boundary particles' normals (``d_min`` 0.3
spacings; a particle next to one wall sits at 0.58 on the lattice), so that a particle sliding
up one wall cannot trade its distance to the floor for a smaller one to the wall.  Wherever the
fluid pressure keeps the particle away the wall pressures stay zero; a liquid at rest is not
such a place everywhere: its layer next to each wall rests at 0.2-0.4 spacings from it, about
the single-wall minimum, and the constraints carry part of its weight (measured in a settled
12 x 12 x 10 pool at 1 cm: 26-29 % of the particles with a wall pressure in every step, their
sum up to 0.47 of the largest fluid pressure).  The solve also iterates until no wall
constraint is violated by more than 1 % of the kernel.
The constraints read a wall through the fraction of the kernel it fills, which reaches 1/2 at
the surface of a boundary at least a support radius thick (the layers of
:func:`filters.sph.boundary.box_boundary` and :func:`~filters.sph.boundary.mesh_boundary`);
one layer of samples on a surface (a cloth, :func:`~filters.sph.boundary.boundary_volumes`)
fills at most 0.22 of it, as a flat wall half a spacing away, so there the constraints do not
act, and neither does the pressure, clamped at zero below rest density: a pool resting on such
a sheet falls through it (measured).  Walls on opposite sides of a particle (a
film between a landing body and the floor) are told apart: normals match in either orientation,
except two that both face the particle from opposite sides
(:func:`~filters.sph.neighbourhood.wall_of`); the particle cannot keep its distance to both, so
two such single-wall constraints are dropped together
(:data:`~filters.sph.dfsph_kernels.OPPOSED_WALLS`) and the density solve alone squeezes the film
out, and a constraint whose gradient is below a tenth of the flat-wall slope
(:data:`~filters.sph.dfsph_kernels.DEGENERATE_WALL`: opposite walls cancelling in the whole
boundary's cluster) is dropped, since enforcing it would kick the particle by ``slack / |grad
phi_ik|``.  Measured: as the ``floating`` scene's heavy box and the ``jello_splash`` jello
landed, a particle of the film under them was put 3-5 mm into the floor at 4.6-5.8 m/s while the
floor and the body's underside made one cluster; with the two walls apart but both enforced, the
film at 2 cm spacing launched the heavy box 3.7 cm; now neither.

**Warm start** (Bender & Koschier 2017, Sec. 4.4): each solve starts from half of the previous
step's converged pressure (IISPH's and SPlisHSPlasH's choice; starting from all of it converges
in half the iterations but lets a resting column slosh, because the pressure then lags the
motion).  The divergence solve stores ``kappa_v = pi_v dt`` (its pressure scales with 1/dt), the
density solve stores ``pi`` itself: SPlisHSPlasH stores ``pi dt^2``, which rescales the warm
start by ``(dt_old / dt_new)^2`` whenever the step changes, while the pressure that holds a
resting fluid up does not depend on the step.  Both live in the simulation state, so a
checkpoint resumes bit for bit.  The warm starts are capped (``pi dt^2 <= 2.5e-4``, ``kappa_v <=
0.5``, SPlisHSPlasH's values) and skipped where the particle is not compressed.

One fused pass per step (:func:`filters.sph.neighbourhood.neighbourhood_pass`) finds the
neighbours of the cell-sorted particles afresh (a DFSPH step moves particles farther than a
Verlet skin could cover) and computes densities, ``alpha_i``, the kernel gradients (stored as
one float32 scalar per pair) and the walls.  The kernels (:mod:`filters.sph.dfsph_kernels`) are
gathers only, so results are bit-identical for any thread count.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from . import dfsph_kernels as K
from .neighbourhood import WALL_CLUSTERS, neighbourhood_pass
from .viscosity import ImplicitViscosity

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = ["DFSPHSolver", "DFSPH_WARM_START", "DFSPH_WARM_START_CAP", "DFSPH_WARM_START_CAP_V",
           "DFSPH_MIN_NEIGHBOURS", "DFSPH_WALL_GAP", "DFSPH_WALL_GAP_SINGLE",
           "DFSPH_WALL_TOLERANCE", "DFSPH_PEAK_ERROR"]

#: Fraction of the previous step's pressure each solve starts from (see the module notes).
DFSPH_WARM_START = 0.5
#: Cap of the density solver's warm start, as ``pi dt^2`` (dimensionless).
DFSPH_WARM_START_CAP = 2.5e-4
#: Cap of the divergence solver's warm start ``kappa_v = pi_v dt`` (m^2/s).
DFSPH_WARM_START_CAP_V = 0.5
#: Fewer neighbours (fluid plus boundary within the support) than this: no divergence solve for
#: that particle (particle deficiency at the free surface; SPlisHSPlasH uses 20 in 3D).
DFSPH_MIN_NEIGHBOURS = 20
#: Smallest equivalent distance to the boundary as a whole, in particle spacings.
DFSPH_WALL_GAP = 0.1
#: Smallest equivalent distance to any single wall, in particle spacings.
DFSPH_WALL_GAP_SINGLE = 0.3
#: Largest wall violation the density solve stops at (fraction of the kernel, ~0.015 spacings).
DFSPH_WALL_TOLERANCE = 0.01
#: The density solve also iterates until no particle is predicted compressed by more than this
#: many times its mean tolerance (see the module notes).
DFSPH_PEAK_ERROR = 10.0
_OMEGA = 0.5


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
    walls : tuple, optional
        ``(spacing, inverse_distance, inverse_slope)``: the particle spacing (m) and the tables
        of :class:`filters.sph.wall_profile.WallProfile`; None: no wall constraints (a liquid
        without boundary).

    Attributes
    ----------
    density_iterations, divergence_iterations : int
        Iterations of the last solves.
    density_error, divergence_error : float
        Mean errors the last solves reached (same units as the tolerances).
    wall_violation : float
        Largest wall violation the last density solve left (fraction of the kernel).
    wall_pressure : (N, 4) float64
        The last density solve's wall pressures ``pw`` (m^2/s^2, like ``pi``).
    """

    def __init__(self, rest_volume: float, support: float, kind: int, max_density_error: float,
                 max_divergence_error: float, max_iterations: int, min_iterations: int = 2,
                 min_divergence_iterations: int = 1, walls: tuple | None = None):
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
        self.wall_violation = 0.0
        self.walls = None
        if walls is not None:
            spacing, inv_d, inv_s = walls
            self.walls = (np.array([DFSPH_WALL_GAP, DFSPH_WALL_GAP_SINGLE]) * spacing,
                          float(spacing), inv_d, inv_s)
        self._n = -1
        self._cap = 40
        self._viscosity = ImplicitViscosity()
        #: Bodies moved inside the density solve (:class:`filters.coupling.strong.RigidLink`),
        #: or None: every boundary particle keeps its velocity through the solve.
        self.link = None

    def _allocate(self, n, cap):
        if n != self._n:
            k = WALL_CLUSTERS
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
            self.bvv = np.zeros((n, 3))
            self.vrate = np.zeros(n)
            self.ncl = np.zeros(n, dtype=np.int32)
            self.cphi = np.zeros((n, k))
            self.cgb = np.zeros((n, k, 3))
            self.cvb = np.zeros((n, k))
            self.cn = np.zeros((n, k, 3))
            self.wsrc = np.zeros((n, k))
            self.wall_pressure = np.zeros((n, k))
            self.werr = np.zeros(n)
            self._n = n
            self.ntab = None
        if self.ntab is None or self.ntab.shape[1] != cap + 1:
            self.ntab = np.empty((n, cap + 1), dtype=np.int32)  # + a spare column
            self.fw = np.empty((n, cap), dtype=np.float32)

    def neighbourhood(self, x: np.ndarray, start: np.ndarray, origin: np.ndarray, cell: float,
                      dims: np.ndarray, boundary: tuple, mass: float) -> NDArray[np.float64]:
        """Neighbours, kernel gradients, densities, ``alpha_i`` and walls at positions ``x``.

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
            :meth:`filters.sph.boundary_set.BoundarySet.arrays`, sorted by a grid of the same
            cell edge.
        mass : float
            Fluid particle mass (kg).

        Returns
        -------
        rho : (N,) float64
            Densities (kg/m^3), an internal array overwritten by the next call.
        """
        n = x.shape[0]
        self._moving = bool(boundary[-1])
        while True:
            self._allocate(n, self._cap)
            best = neighbourhood_pass(x, start, origin, cell, dims, boundary, self.volume, mass,
                                      self.support, self.kind, self.ntab, self.ncnt, self.fw,
                                      self.gsum, self.factor, self.nnb, self.rho, self.fsum,
                                      self.bvis, self.bvv, self.vrate, self.ncl, self.cphi,
                                      self.cgb, self.cvb, self.cn)
            if best <= self._cap:
                break
            self._cap = int(best) + 8  # rare: a compressed particle has more neighbours
        self._x = x  # the solves of this step use these positions (the drift comes last)
        return self.rho

    def density_rate(self, v: np.ndarray) -> NDArray[np.float64]:
        """``(D rho_i / D t) / rho0`` (1/s) for velocities ``v`` (after :meth:`neighbourhood`)."""
        K.density_rate(v, self._x, self.ntab, self.ncnt, self.fw, self.gsum, self.vrate,
                       self.rate)
        return self.rate

    def _iterate(self, pi, scale, tol, min_iterations, peak_tol=math.inf):
        it = 0
        err = math.inf
        peak = math.inf
        while it < self.max_iterations and (it < min_iterations or err > tol
                                            or peak > peak_tol):
            K.pressure_accel(pi, self._x, self.ntab, self.ncnt, self.fw, self.gsum, self.a)
            err, peak = K.jacobi(self.a, self._x, self.src, pi, self.factor, self.active,
                                 self.ntab, self.ncnt, self.fw, self.gsum, scale, _OMEGA,
                                 self.err)
            it += 1
            if not math.isfinite(err):
                break
        return it, err

    def _iterate_walls(self, pi, scale, tol):
        pw = self.wall_pressure
        it = 0
        err = math.inf
        peak = math.inf
        worst = math.inf
        link = self.link
        while it < self.max_iterations and (it < self.min_iterations or err > tol
                                            or peak > DFSPH_PEAK_ERROR * tol
                                            or worst > DFSPH_WALL_TOLERANCE):
            if link is not None:
                link.update(pi, pw, scale)
            K.pressure_accel_wall(pi, pw, self._x, self.ntab, self.ncnt, self.fw, self.gsum,
                                  self.ncl, self.cgb, self.a)
            err, peak, worst = K.jacobi_wall(self.a, self._x, self.src, pi, self.factor,
                                             self.ntab, self.ncnt, self.fw, self.gsum, scale,
                                             _OMEGA, self.err, self.wsrc, pw, self.ncl, self.cgb,
                                             self.werr)
            it += 1
            if not (math.isfinite(err) and math.isfinite(worst)):
                break
        self.wall_violation = float(worst)
        return it, err

    def divergence_solve(self, v: np.ndarray, dt: float, kappa_v: np.ndarray) -> None:
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
        K.divergence_start(self.rate, self.nnb, DFSPH_MIN_NEIGHBOURS, dt, kappa_v,
                           DFSPH_WARM_START_CAP_V, self.src, self.pi_v, self.active)
        # err is a mean rate (1/s); the tolerance is per step.
        it, err = self._iterate(self.pi_v, dt, self.max_divergence_error / dt,
                               self.min_divergence_iterations)
        K.pressure_accel(self.pi_v, self._x, self.ntab, self.ncnt, self.fw, self.gsum, self.a)
        K.kick(v, self.a, dt)
        K.store(self.pi_v, dt, kappa_v)
        self.divergence_iterations = it
        self.divergence_error = float(err) * dt

    def skip_divergence(self, kappa_v: np.ndarray) -> None:
        """No divergence solve this step: zero pressure and warm start."""
        self.pi_v[:] = 0.0
        kappa_v[:] = 0.0
        self.divergence_iterations = 0
        self.divergence_error = 0.0

    def density_solve(self, v: np.ndarray, rho: np.ndarray, rho0: float, dt: float,
                      pi_prev: np.ndarray, fraction: float = 1.0) -> None:
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
        fraction : float
            Fraction of the density error the particles start with that this step removes, in
            (0, 1]: below 1 in a sliver of a step (see :data:`filters.sph.dfsph_step.SLIVER`).
        """
        self.density_rate(v)
        K.density_start(rho, self.rate, rho0, dt, fraction, pi_prev, DFSPH_WARM_START_CAP,
                        DFSPH_WARM_START, self.src, self.pi, self.active)
        if self.walls is None:
            it, err = self._iterate(self.pi, dt * dt, self.max_density_error, self.min_iterations,
                                    DFSPH_PEAK_ERROR * self.max_density_error)
            K.pressure_accel(self.pi, self._x, self.ntab, self.ncnt, self.fw, self.gsum, self.a)
        else:
            gaps, spacing, inv_d, inv_s = self.walls
            K.wall_start(v, self.ncl, self.cphi, self.cgb, self.cvb, dt, fraction, gaps, spacing,
                         inv_d, inv_s, self.wsrc, self.wall_pressure)
            if self.link is not None:
                self.link.begin(self, self.pi_v, v)
            it, err = self._iterate_walls(self.pi, dt * dt, self.max_density_error)
            K.pressure_accel_wall(self.pi, self.wall_pressure, self._x, self.ntab, self.ncnt,
                                  self.fw, self.gsum, self.ncl, self.cgb, self.a)
        K.kick(v, self.a, dt)
        pi_prev[:] = self.pi
        self.density_iterations = it
        self.density_error = float(err)

    def viscosity_solve(self, v: np.ndarray, x: np.ndarray, dt: float, nu: float, nu_b: float,
                        tolerance: float = 1e-3, max_iterations: int = 100) -> int:
        """Implicit viscosity (Weiler, Koschier, Brand & Bender 2018, "A physically consistent
        implicit viscosity solver for SPH fluids", CGF 37(2)): solve ``(I - dt L) v' = v`` by
        conjugate gradients with a block-Jacobi preconditioner, in place.

        Rest volumes make the matrix symmetric positive definite; the boundary acts as a no-slip
        wall with ``nu_b`` (times each boundary particle's friction factor) that moves with its
        particles' velocities.  Stops at ``|r| <= tolerance |b|`` (relative residual).  Returns
        the number of iterations.

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
                                   self.fsum, self.bvis, self.support, tolerance, max_iterations,
                                   self.bvv if self._moving else None)
        self.viscosity_iterations = it
        return it

    @staticmethod
    def kick(v: np.ndarray, a: np.ndarray, dt: float) -> None:
        """``v += dt a`` in parallel (m/s)."""
        K.kick(v, a, dt)

    @staticmethod
    def drift(x: np.ndarray, v: np.ndarray, dt: float) -> float:
        """``x += dt v`` in parallel; returns ``max |v|`` (m/s)."""
        return float(K.drift(x, v, dt))
