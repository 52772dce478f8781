"""SPH liquid in Numba: weakly compressible (Becker & Teschner 2007) or divergence-free (DFSPH).

``SPHLiquid(..., solver="wcsph")`` (the default) is described below.  ``solver="dfsph"`` replaces
the equation of state by the two implicit pressure solves of Bender & Koschier (2015, 2017) in
:mod:`filters.sph.dfsph` (same neighbour lists, boundary particles, viscosity, surface tension,
external fields, state and checkpoints; steps from the velocity CFL condition only).

The WCSPH method (equation of state, forces, boundary pressures, the adaptive step) is
described in :mod:`filters.sph.forces`, with its references.

Neighbour lists are Verlet lists: built with a skin (radius ``h (1 + skin)``) by the uniform
grid of :mod:`filters.neighbors` and reused by every pass until some particle has moved half the
skin; each rebuild also re-sorts the particles by grid cell (a parallel counting sort) for memory
locality.  The ``id`` array in the state's extras follows the particles through these
permutations.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .boundary import lattice_volume, sort_boundary
from .dfsph import DFSPHSolver, boundary_reach_mask
from . import forces, particles
from .model import SPHModel, as_field, check_boxes, default_support_factor
from .parameters import check_liquid_parameters
from ..kernels import kernel_id
from ..binning import cell_keys, counting_sort
from ..neighbors import bounds, grid_query_padded
from ..simulation import OutputSpec, Simulation, SimulationUnstableError, State, Frame

__all__ = ["SPHModel", "SPHLiquid", "default_support_factor"]


_CELL_PAD = 1.0 + 1e-9
_DFSPH_MIN_DT = 1e-5  # s, smallest DFSPH step (a faster fluid is a blow-up here)
_DFSPH_BUSY = 20  # density-solve iterations above which the next step shrinks
_DFSPH_EASY = 10  # ... below which it may grow again
_REACH = 2  # grid cells per support radius (see filters.neighbors)


class SPHLiquid(Simulation):
    """SPH liquid with boundary particles: WCSPH (Becker & Teschner 2007) or DFSPH (Bender &
    Koschier 2015, 2017).

    Parameters
    ----------
    positions : (N, 3) array_like
        Initial fluid particle positions (m), normally a lattice of step ``spacing``.
    velocities : (N, 3) array_like, optional
        Initial velocities (m/s); zeros when omitted.
    spacing : float
        Particle spacing (m), > 0; sets the mass ``rho0 * spacing^3`` (lattice-corrected) and the
        support ``h = support_factor * spacing``.
    boundary : BoundaryParticles, optional
        Static walls / obstacles, see :mod:`filters.sph.boundary`.  None: no walls.
    rest_density : float
        ``rho0`` (kg/m^3), default 1000.
    kernel : {"cubic", "wendland"}
        Smoothing kernel (Monaghan 1992 cubic spline or Wendland C2).
    support_factor : float, optional
        ``h / spacing`` in [1.5, 4]; default :func:`default_support_factor` (2 for the cubic
        spline, as in SPlisHSPlasH; 2.5 for Wendland C2, which at 2 has too few neighbours and
        failed the dam break's impact here with a 10 % density error).
    speed_of_sound : float, optional
        ``c`` (m/s).  Default: ``10 * max(sqrt(2 |g| H), 1)`` with ``H`` the fluid's initial height.
    gamma : float
        Tait exponent, default 7.
    viscosity : float
        Monaghan's artificial viscosity ``alpha`` in [0, 1], default 0.05.
    boundary_viscosity : float, optional
        ``alpha`` against walls (friction); default ``viscosity``.
    xsph : float
        XSPH factor in [0, 1), default 0 (off).
    surface_tension : float
        Akinci et al. (2013) coefficient >= 0 (typical 0.1 - 2), default 0 (off).
    gravity : sequence of 3 float
        (m/s^2), default ``(0, 0, -9.81)``.
    external : callable or object, optional
        Extra acceleration field ``field(positions, velocities, time) -> (N, 3)`` (m/s^2), or an
        object whose ``acceleration`` method has that signature.
    cfl : float
        Courant number in (0, 1], default 0.4.  DFSPH: ``dt = cfl * spacing / max |v|``.
    max_dt : float, optional
        Largest step (s) in (0, 1]; default 1/240 (WCSPH) or 0.005 (DFSPH).
    density_error_limit : float
        Largest tolerated relative compression in (0, 1], default 0.1.  WCSPH: of any particle;
        DFSPH: of the mean over particles (what DFSPH controls; single particles squeezed at an
        impact may exceed it briefly), and of the mean error its density solver reaches.
    domain : tuple of two sequences of 3 float, optional
        ``(lower, upper)`` box (m) particles must stay inside; default: the boundary particles'
        bounding box when there is a boundary, otherwise no check.
    container : tuple of two sequences of 3 float, optional
        ``(lower, upper)`` inner walls of a box tank (m).  A particle that passes a wall plane
        in a step (possible for an isolated, fast particle: with its density below ``rho0`` it
        has no pressure to push it back) is put back on the plane with its outward velocity
        removed; :attr:`contained` counts these corrections.  The boundary particles still do
        the physical work; this only guarantees that nothing leaks.
    boundary_pressure : {"adami", "mirror"}
        ``"adami"`` (default): boundary pressures extrapolated from the fluid with the
        hydrostatic term (Adami, Hu & Adams 2012), which keeps the pressure gradient right next to
        walls; ``"mirror"``: each fluid particle's own pressure mirrored onto the boundary
        (Akinci et al. 2012), cheaper but makes narrow columns too stiff near walls.
    skin : float
        Verlet skin as a fraction of ``h`` in [0, 1], default 0.2: neighbour lists cover
        ``h (1 + skin)`` and are rebuilt (and the particles re-sorted by cell) only when some
        particle has moved ``skin h / 2`` since the last rebuild.  0 rebuilds every step.
    threads : int, optional
        Numba threads to use while stepping.  Default: 1 below 20,000 particles (on a busy
        machine, waking threads for a dozen short parallel loops per step costs more than it
        saves), otherwise as many as Numba uses when the step starts
        (``numba.get_num_threads()``, which ``numba.set_num_threads`` lowers).  The results do
        not depend on it.
    solver : {"wcsph", "dfsph"}
        ``"wcsph"`` (default): Tait equation of state, acoustic CFL step.  ``"dfsph"``:
        divergence-free SPH (Bender & Koschier 2017, :mod:`filters.sph.dfsph`), a divergence solve
        and a constant-density solve per step, steps from the velocity CFL only
        (``dt = cfl * spacing / max |v|``, between 1e-5 s and ``max_dt``).  ``speed_of_sound``
        then only scales the artificial viscosity (same ``viscosity``, same effect).
    max_density_error : float
        DFSPH: tolerance of the mean predicted compression ``mean max(rho / rho0 - 1, 0)`` in
        [1e-6, 0.1], default 0.001 (0.1 %).
    max_divergence_error : float
        DFSPH: tolerance of the mean compression rate over one step, ``dt mean max(D rho / D t,
        0) / rho0``, in [1e-6, 1], default 0.01 (1 %).
    max_iterations : int
        DFSPH: most iterations of each solve in [2, 10000], default 100 (at least 2 are done).

    Raises
    ------
    ValueError, TypeError
        For invalid parameters, before any work.
    SimulationUnstableError
        While stepping: non-finite positions or velocities, a particle outside ``domain``, or a
        compression beyond ``density_error_limit`` (DFSPH: mean compression, or a density
        solve ending above it); with the simulated time and the quantity.

    Notes
    -----
    The state holds ``positions``, ``velocities`` and the extras ``id`` (int64, the particle's
    original index; particles are re-ordered by grid cell at every list rebuild), ``anchor``
    (positions at the last rebuild, which decide the next one) and ``kinematics``
    (``[max |v|, max |a|]`` of the last step, which the adaptive step uses; DFSPH adds the last
    step), and for DFSPH the warm starts ``pi`` and ``kappa_v`` (see :mod:`filters.sph.dfsph`),
    so a restored checkpoint continues bit-identically (tested).  After each DFSPH step,
    :attr:`last_density_iterations`, :attr:`last_divergence_iterations`,
    :attr:`last_density_error` and :attr:`last_divergence_error` describe the two solves.
    """

    _HINTS = {
        "wcsph": ("reduce the time step (cfl, max_dt), increase speed_of_sound or viscosity, or "
                  "check that the fluid starts inside the walls"),
        "dfsph": ("reduce the time step (cfl, max_dt), increase max_iterations or lower "
                  "max_density_error, or check that the fluid starts inside the walls"),
    }

    @property
    def instability_hint(self) -> str:
        """What the caller can change when the simulation diverges (only settable parameters)."""
        return self._HINTS[self.model.solver]

    def __init__(self, positions, velocities=None, *, spacing, boundary=None,
                 rest_density=1000.0, kernel="cubic", support_factor=None, speed_of_sound=None,
                 gamma=7.0, viscosity=0.05, boundary_viscosity=None, xsph=0.0,
                 surface_tension=0.0, gravity=(0.0, 0.0, -9.81), external=None, cfl=0.4,
                 max_dt=None, density_error_limit=0.1, domain=None, container=None,
                 boundary_pressure="adami", skin=0.2, threads=None, solver="wcsph",
                 max_density_error=1e-3, max_divergence_error=1e-2, max_iterations=100,
                 kinematic_viscosity=None):
        (spacing, rest_density, support_factor, speed_of_sound, gamma, viscosity,
         boundary_viscosity, xsph, surface_tension, gravity, cfl, max_dt, density_error_limit,
         skin, threads, max_density_error, max_divergence_error, max_iterations,
         kinematic_viscosity) = check_liquid_parameters(
            spacing=spacing, boundary=boundary, rest_density=rest_density, kernel=kernel,
            support_factor=support_factor, speed_of_sound=speed_of_sound, gamma=gamma,
            viscosity=viscosity, boundary_viscosity=boundary_viscosity, xsph=xsph,
            surface_tension=surface_tension, gravity=gravity, cfl=cfl, max_dt=max_dt,
            density_error_limit=density_error_limit, boundary_pressure=boundary_pressure,
            skin=skin, threads=threads, solver=solver, max_density_error=max_density_error,
            max_divergence_error=max_divergence_error, max_iterations=max_iterations,
            kinematic_viscosity=kinematic_viscosity)
        field = as_field(external)
        state = State(positions, velocities)
        if state.n_points == 0:
            raise ValueError("positions must contain at least one particle")
        x = state.positions
        domain, container = check_boxes(x, domain, container, boundary)

        h = support_factor * spacing
        volume = lattice_volume(spacing, h, kernel)
        mass = rest_density * volume
        if speed_of_sound is None:
            height = float(np.ptp(x[:, 2])) + spacing
            gnorm = float(np.linalg.norm(gravity))
            speed_of_sound = 10.0 * max(math.sqrt(2.0 * gnorm * height), 1.0)

        # DFSPH finds its neighbours afresh every step (its steps move particles farther than
        # any affordable skin); WCSPH reuses Verlet lists of radius h (1 + 2 skin).
        reach = h if solver == "dfsph" else h * (1.0 + 2.0 * skin)
        bx, bv, blo, bdims, bstart = sort_boundary(boundary, reach * _CELL_PAD / _REACH)

        self.model = SPHModel(
            spacing=spacing, support=h, kernel=kernel, rest_density=rest_density, mass=mass,
            speed_of_sound=float(speed_of_sound), gamma=gamma, viscosity=viscosity,
            boundary_viscosity=boundary_viscosity, xsph=xsph, surface_tension=surface_tension,
            gravity=tuple(gravity), cfl=cfl, max_dt=max_dt,
            density_error_limit=density_error_limit, domain=domain, container=container,
            boundary_pressure=boundary_pressure,
            boundary_points=bx, boundary_volumes=bv, solver=solver,
            max_density_error=max_density_error, max_divergence_error=max_divergence_error,
            max_iterations=max_iterations,
        )
        self.max_dt = max_dt
        self._kind = kernel_id(kernel)
        self._gravity = np.array(gravity, dtype=np.float64)
        self._field = field
        self._bcell = (h if solver == "dfsph" else h * (1.0 + 2.0 * skin)) * _CELL_PAD / _REACH
        self._skin = skin * h
        self._tab = None
        self._bpsi = rest_density * np.asarray(bv)
        self._bpr = np.full(bx.shape[0], -1.0)
        self._bstart = bstart
        self._borigin = blo
        self._bdims = bdims
        self._border = np.arange(bx.shape[0], dtype=np.int32)
        self._stiffness = rest_density * speed_of_sound ** 2 / gamma
        if domain is not None:
            self._dlo = np.array(domain[0], dtype=np.float64)
            self._dhi = np.array(domain[1], dtype=np.float64)
        if container is not None:
            self._clo = np.array(container[0], dtype=np.float64)
            self._chi = np.array(container[1], dtype=np.float64)
        #: Number of container corrections (particles put back on a wall plane) so far.
        self.contained = 0
        state.extra["id"] = np.arange(state.n_points, dtype=np.int64)
        state.extra["kinematics"] = np.array(
            [float(np.sqrt((state.velocities ** 2).sum(axis=1)).max()),
             float(np.linalg.norm(gravity))])
        self.state = state
        #: Largest relative compression ``max (rho - rho0) / rho0`` seen at the last evaluation.
        self.density_error = 0.0
        #: Mean relative compression over particles at the last evaluation.
        self.mean_density_error = 0.0
        self._density_cache = None
        n = state.n_points
        self._rho = np.empty(n)
        self._p = np.empty(n)
        self._a = np.empty((n, 3))
        self._nrm = np.zeros((n, 3))
        self._capacity = 48
        #: DFSPH: iterations and mean errors the last step's solves reached (0 for WCSPH).
        self.last_density_iterations = 0
        self.last_divergence_iterations = 0
        self.last_density_error = 0.0
        self.last_divergence_error = 0.0
        #: DFSPH: conjugate-gradient iterations of the last implicit viscosity solve.
        self.last_viscosity_iterations = 0
        self._dfsph = None
        if solver == "dfsph":
            self._dfsph = DFSPHSolver(volume, h, self._kind, max_density_error,
                                      max_divergence_error, max_iterations)
            state.extra["pi"] = np.zeros(n)
            state.extra["kappa_v"] = np.zeros(n)
            # [.., last step, step cap]: the cap starts where gravity alone compresses the fluid
            # by the tolerance in one step and then follows the density solver's effort.
            gnorm = float(np.linalg.norm(gravity))
            cap = (min(max_dt, math.sqrt(max_density_error * spacing / gnorm)) if gnorm > 0.0
                   else max_dt)
            state.extra["kinematics"] = np.append(state.extra["kinematics"], [max_dt, cap])
            self._zero_p = np.zeros(n)
            if kinematic_viscosity is None:  # Monaghan's nu = alpha c h' / (2 (d + 2))
                self._nu = (viscosity * speed_of_sound * 0.5 * h / 10.0,
                            boundary_viscosity * speed_of_sound * 0.5 * h / 10.0)
            else:
                self._nu = (kinematic_viscosity, kinematic_viscosity)
            self._bmirror = np.full(bx.shape[0], -1.0)
            self._boundary = (bx, bstart, blo, self._bcell, bdims,
                              boundary_reach_mask(bx, blo, self._bcell, bdims), bv, self._bpsi)
            self._no_boundary = (np.zeros((n, 1), dtype=np.int32), np.zeros(n, dtype=np.int32))
        self.threads = threads  # None: decided at each step (_step_threads)
        self._bcapacity = 32

    # -- protocol -------------------------------------------------------------------------
    @property
    def output_spec(self) -> OutputSpec:
        return OutputSpec(point_arrays=(("velocity", 3), ("density", 1), ("pressure", 1),
                                        ("id", 1)), topology="vertices")

    def frame(self) -> Frame:
        """Current positions with ``velocity`` (m/s), ``density`` (kg/m^3), ``pressure`` (Pa)
        evaluated at these positions, and ``id``."""
        previous = numba.get_num_threads()
        numba.set_num_threads(self._step_threads(previous))
        try:
            if self.model.solver == "dfsph":
                self._neighbourhood()
            else:
                self._ensure_lists()
            self._evaluate_density()
        finally:
            numba.set_num_threads(previous)
        s = self.state
        return Frame(time=s.time, points=s.positions.copy(), point_data={
            "velocity": s.velocities.copy(), "density": self._rho.copy(),
            "pressure": self._p.copy(), "id": s.extra["id"].copy()})

    def max_step(self) -> float:
        """Adaptive step (s).  WCSPH: CFL with viscous term and force condition.  DFSPH: the
        velocity CFL ``cfl * spacing / max |v|``, at most ``max_dt`` and at most a cap that
        follows the density solver's effort (see :meth:`_update_step_cap`); at least 1e-5 s."""
        m = self.model
        if m.solver == "dfsph":
            kin = self.state.extra["kinematics"]
            vmax = float(kin[0])
            dt = min(self.max_dt, float(kin[3]) if kin.shape[0] > 3 else self.max_dt)
            if vmax * dt > m.cfl * m.spacing:
                dt = m.cfl * m.spacing / vmax
            return max(dt, _DFSPH_MIN_DT)
        vmax, amax = (float(v) for v in self.state.extra["kinematics"][:2])
        hs = 0.5 * m.support
        dt = m.cfl * hs / (m.speed_of_sound * (1.0 + 0.6 * m.viscosity) + vmax)
        if amax > 0.0:
            dt = min(dt, 0.25 * math.sqrt(hs / amax))
        return min(dt, self.max_dt)

    # -- internals ------------------------------------------------------------------------
    def _update_step_cap(self, cap: float, dt: float, iterations: int) -> float:
        """DFSPH step cap after a step of ``dt`` whose density solve took ``iterations``.

        The velocity CFL condition alone lets a tall resting column take ``max_dt`` steps,
        and a relaxed Jacobi solve cannot carry the missing hydrostatic pressure through
        dozens of layers in one step: the bottom compresses a little more every step until the
        flow blows up (measured: a 76-layer column at 5 ms steps).  Like SPlisHSPlasH's
        iteration-aware CFL mode, the step therefore follows the solver: it shrinks to 0.9 dt
        when the solve needed more than 20 iterations (0.5 dt when it did not converge) and
        grows by 10 % per step, up to ``max_dt``, while it needs fewer than 10.
        """
        if iterations >= self.model.max_iterations:
            return 0.5 * dt
        if iterations > _DFSPH_BUSY:
            return 0.9 * dt
        if iterations < _DFSPH_EASY:
            return min(1.1 * cap, self.max_dt)
        return cap

    def _ensure_lists(self):
        """Make the neighbour lists valid for the current positions (Verlet lists with a skin).

        Lists hold every pair within ``h + skin`` of the positions at the last rebuild (the
        ``anchor`` in the state's extras) and stay valid while no particle has moved more than
        ``skin / 2`` from its anchor.  A rebuild also sorts the particles by grid cell.  Rows are
        sorted by index and every pass skips pairs beyond ``h``, so sums do not depend on which
        valid list is used: a state restored between rebuilds (lists rebuilt without sorting,
        with radius ``h + 2 skin``) continues bit-identically.
        """
        s = self.state
        m = self.model
        anchor = s.extra.get("anchor")
        skin = self._skin
        if anchor is None or anchor.shape != s.positions.shape:
            rebuild = True
        else:
            moved2 = particles.max_displacement2(s.positions, anchor)
            rebuild = skin <= 0.0 or moved2 > (0.5 * skin) ** 2
        if rebuild:
            self._build_lists(m.support + skin, permute=True)
            s.extra["anchor"] = s.positions.copy()
        elif self._tab is None:
            self._build_lists(m.support + 2.0 * skin, permute=False)

    def _build_lists(self, radius, permute):
        s = self.state
        m = self.model
        x = s.positions
        cell = radius * _CELL_PAD / _REACH
        lo, hi, finite = bounds(x)
        if not finite:
            raise SimulationUnstableError(s.time, "non-finite positions", self.instability_hint)
        dims_f = np.floor((hi - lo) / cell) + 1.0
        if float(np.prod(dims_f)) > 2e8:
            raise SimulationUnstableError(s.time, "particle spread",
                                          "particles spread over more than 2e8 grid cells")
        dims = dims_f.astype(np.int64)
        keys = cell_keys(x, lo, 1.0 / cell, dims)
        start, order = counting_sort(keys, int(np.prod(dims)), numba.get_num_threads())
        if permute:
            xo = np.empty_like(x)
            vo = np.empty_like(s.velocities)
            io = np.empty_like(s.extra["id"])
            particles.permute(x, s.velocities, s.extra["id"], order, xo, vo, io)
            s.positions = xo
            s.velocities = vo
            s.extra["id"] = io
            for name in ("pi", "kappa_v"):  # DFSPH warm starts follow their particles
                if name in s.extra:
                    s.extra[name] = s.extra[name][order]
            sx = xo
            sorted_ids = np.arange(x.shape[0], dtype=np.int32)
        else:
            sx = np.ascontiguousarray(x[order])
            sorted_ids = order
        r2 = radius * radius
        self._tab, self._cnt, best = grid_query_padded(
            s.positions, True, False, sx, start, sorted_ids, lo, cell, dims, _REACH, r2,
            self._capacity)
        self._capacity = best + 4
        particles.sort_rows(self._tab, self._cnt)
        bcell = self._bcell
        self._btab, self._bcnt, best = grid_query_padded(
            s.positions, False, False, m.boundary_points, self._bstart, self._border,
            self._borigin, bcell, self._bdims, _REACH, r2, self._bcapacity)
        self._bcapacity = max(best, 1) + 4
        particles.sort_rows(self._btab, self._bcnt)

    def _neighbourhood(self):
        """DFSPH: sort the particles by grid cell (cells of ``h / 2``; a stable counting sort,
        the identity on already sorted particles) and compute neighbours, kernel gradients,
        densities and ``alpha_i`` in one pass (:meth:`DFSPHSolver.neighbourhood`)."""
        s = self.state
        m = self.model
        x = s.positions
        cell = m.support * _CELL_PAD / _REACH
        lo, hi, finite = bounds(x)
        if not finite:
            raise SimulationUnstableError(s.time, "non-finite positions", self.instability_hint)
        dims_f = np.floor((hi - lo) / cell) + 1.0
        if float(np.prod(dims_f)) > 2e8:
            raise SimulationUnstableError(s.time, "particle spread",
                                          "particles spread over more than 2e8 grid cells")
        dims = dims_f.astype(np.int64)
        keys = cell_keys(x, lo, 1.0 / cell, dims)
        start, order = counting_sort(keys, int(np.prod(dims)), numba.get_num_threads())
        if not particles.is_identity(order):
            xo = np.empty_like(x)
            vo = np.empty_like(s.velocities)
            io = np.empty_like(s.extra["id"])
            particles.permute(x, s.velocities, s.extra["id"], order, xo, vo, io)
            s.positions = xo
            s.velocities = vo
            s.extra["id"] = io
            for name in ("pi", "kappa_v"):  # warm starts follow their particles
                if name in s.extra and s.extra[name].shape == (x.shape[0],):
                    s.extra[name] = s.extra[name][order]
        self._rho = self._dfsph.neighbourhood(s.positions, start, lo, cell, dims,
                                              self._boundary, m.mass)

    def set_state(self, state: State) -> None:
        super().set_state(state)
        self._tab = None  # lists belong to the old state

    def _evaluate_density(self):
        m = self.model
        x = self.state.positions
        if m.solver != "dfsph":  # DFSPH: densities come from _neighbourhood
            forces.density(x, self._tab, self._cnt, m.boundary_points, self._btab, self._bcnt,
                     self._bpsi, m.mass, m.support, self._kind, self._rho)
        if m.solver == "dfsph":
            # Pressure of the last step's two solves: p = (pi + pi_v) rho^2 / rho0, with
            # pi_v = kappa_v / dt (see filters.sph.dfsph).
            ex = self.state.extra
            dt = float(ex["kinematics"][2])
            self._p[:] = ((ex["pi"] + ex["kappa_v"] / dt)
                          * self._rho ** 2 / m.rest_density)
            err = max(float((self._rho / m.rest_density - 1.0).max()), 0.0)
        else:
            err = forces.tait_pressure(self._rho, m.rest_density, self._stiffness, m.gamma, self._p)
        self.density_error = float(err)
        self.mean_density_error = float(
            np.maximum(self._rho / m.rest_density - 1.0, 0.0).mean())
        return err

    def _step_threads(self, current: int) -> int:
        if self.threads is not None:
            return self.threads
        return 1 if self.state.positions.shape[0] < 20_000 else current

    def _step(self, dt: float) -> None:
        previous = numba.get_num_threads()
        numba.set_num_threads(self._step_threads(previous))
        try:
            self._step_impl(dt)
        finally:
            numba.set_num_threads(previous)

    def _step_impl(self, dt: float) -> None:
        if self.model.solver == "dfsph":
            self._step_dfsph(dt)
            return
        s = self.state
        m = self.model
        self._ensure_lists()
        err = self._evaluate_density()
        if not math.isfinite(err) or err > m.density_error_limit:
            raise SimulationUnstableError(
                s.time, f"density error {err:.3g} > density_error_limit {m.density_error_limit:g}",
                self.instability_hint)
        x = s.positions
        v = s.velocities
        if m.surface_tension > 0.0:
            forces.normals(x, self._rho, self._tab, self._cnt, m.mass, m.support, self._kind,
                           self._nrm)
        g = self._gravity
        forces.boundary_pressures(x, self._rho, self._p, m.boundary_points, self._btab,
                                  self._bcnt, m.support, self._kind, g, m.rest_density,
                                  self._stiffness, m.gamma, m.boundary_pressure == "mirror",
                                  self._bpr)
        amax = forces.accelerations(x, v, self._rho, self._p, self._tab, self._cnt,
                                    m.boundary_points, self._btab, self._bcnt, self._bpsi,
                                    self._bpr, m.mass, m.support, self._kind, m.viscosity,
                                    m.boundary_viscosity, m.speed_of_sound, m.rest_density,
                                    m.surface_tension, self._nrm, g, self._a)
        if self._field is not None:
            extra = np.asarray(self._field(x, v, s.time), dtype=np.float64)
            if extra.shape != x.shape:
                raise ValueError(f"external field returned shape {extra.shape}, expected {x.shape}")
            self._a += extra
            amax = float(np.sqrt((self._a ** 2).sum(axis=1)).max())
        vmax = particles.integrate(x, v, self._a, dt)
        if m.xsph > 0.0:
            out = np.empty_like(v)
            forces.xsph(v, self._rho, x, self._tab, self._cnt, m.mass, m.support, self._kind,
                        m.xsph, out)
            s.velocities = out
            vmax = float(np.sqrt((out ** 2).sum(axis=1)).max())
        if m.container is not None:
            self.contained += int(particles.contain(x, s.velocities, self._clo, self._chi))
        s.extra["kinematics"] = np.array([vmax, amax])
        if not math.isfinite(vmax):
            raise SimulationUnstableError(s.time + dt, "non-finite velocities", self.instability_hint)
        if m.domain is not None:
            bad = particles.outside(x, self._dlo, self._dhi)
            if bad >= 0:
                raise SimulationUnstableError(
                    s.time + dt, f"particle {int(s.extra['id'][bad])} left the domain "
                    f"at {x[bad].tolist()}", self.instability_hint)

    def _step_dfsph(self, dt: float) -> None:
        """One DFSPH step (Bender & Koschier 2017, Alg. 1): neighbourhoods, densities and
        ``alpha_i``; divergence solve; non-pressure accelerations; density solve; drift."""
        s = self.state
        m = self.model
        solver = self._dfsph
        for name in ("pi", "kappa_v"):
            if s.extra.get(name) is None or s.extra[name].shape != (s.n_points,):
                s.extra[name] = np.zeros(s.n_points)  # e.g. a state written by a WCSPH run
        self._neighbourhood()
        self._evaluate_density()
        mean_err = self.mean_density_error
        if not math.isfinite(mean_err) or mean_err > m.density_error_limit:
            raise SimulationUnstableError(
                s.time, f"mean density error {mean_err:.3g} > density_error_limit "
                f"{m.density_error_limit:g}", self.instability_hint)
        x = s.positions
        v = s.velocities
        ex = s.extra
        tab, cnt = solver.ntab, solver.ncnt
        solver.divergence_solve(v, dt, ex["kappa_v"])
        g = self._gravity
        if m.surface_tension > 0.0:
            forces.normals(x, self._rho, tab, cnt, m.mass, m.support, self._kind, self._nrm)
            amax = forces.accelerations(x, v, self._rho, self._zero_p, tab, cnt,
                                  m.boundary_points, *self._no_boundary, self._bpsi,
                                  self._bmirror, m.mass, m.support, self._kind, 0.0, 0.0,
                                  m.speed_of_sound, m.rest_density, m.surface_tension,
                                  self._nrm, g, self._a)
        else:
            self._a[:] = g
            amax = float(np.linalg.norm(g))
        if self._field is not None:
            extra = np.asarray(self._field(x, v, s.time), dtype=np.float64)
            if extra.shape != x.shape:
                raise ValueError(f"external field returned shape {extra.shape}, expected {x.shape}")
            self._a += extra
            amax = float(np.sqrt((self._a ** 2).sum(axis=1)).max())
        solver.kick(v, self._a, dt)
        self.last_viscosity_iterations = solver.viscosity_solve(v, x, dt, *self._nu)
        solver.density_solve(v, self._rho, m.rest_density, dt, ex["pi"])
        self.last_density_iterations = solver.density_iterations
        self.last_divergence_iterations = solver.divergence_iterations
        self.last_density_error = solver.density_error
        self.last_divergence_error = solver.divergence_error
        err = solver.density_error
        if not math.isfinite(err) or (solver.density_iterations >= m.max_iterations
                                      and err > m.density_error_limit):
            raise SimulationUnstableError(
                s.time, f"DFSPH density solve reached a mean density error {err:.3g} > "
                f"density_error_limit {m.density_error_limit:g} in {m.max_iterations} "
                f"iterations", self.instability_hint)
        vmax = solver.drift(x, v, dt)
        if m.xsph > 0.0:
            out = np.empty_like(v)
            forces.xsph(v, self._rho, x, tab, cnt, m.mass, m.support, self._kind, m.xsph, out)
            s.velocities = out
            vmax = float(np.sqrt((out ** 2).sum(axis=1)).max())
        if m.container is not None:
            self.contained += int(particles.contain(x, s.velocities, self._clo, self._chi))
        old = ex["kinematics"]
        cap = self._update_step_cap(float(old[3]) if old.shape[0] > 3 else self.max_dt, dt,
                                    solver.density_iterations)
        ex["kinematics"] = np.array([vmax, amax, dt, cap])
        if not math.isfinite(vmax):
            raise SimulationUnstableError(s.time + dt, "non-finite velocities", self.instability_hint)
        if m.domain is not None:
            bad = particles.outside(x, self._dlo, self._dhi)
            if bad >= 0:
                raise SimulationUnstableError(
                    s.time + dt, f"particle {int(s.extra['id'][bad])} left the domain "
                    f"at {x[bad].tolist()}", self.instability_hint)
