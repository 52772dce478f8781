"""SPH liquid in Numba: weakly compressible (Becker & Teschner 2007) or divergence-free (DFSPH).

``SPHLiquid(..., solver="wcsph")`` (the default) steps with the Tait equation of state
(:mod:`filters.sph.wcsph`, :mod:`filters.sph.forces`).  ``solver="dfsph"`` replaces it by the two
implicit pressure solves of Bender & Koschier (2015, 2017) (:mod:`filters.sph.dfsph_step`,
:mod:`filters.sph.dfsph`), with the same boundary particles, viscosity, surface tension,
external fields, state and checkpoints, and steps from the velocity CFL condition only.

Walls and bodies are one kind of boundary (:mod:`filters.sph.boundary`,
:mod:`filters.sph.boundary_set`): boundary particles with volumes, normals, velocities and
friction factors.  With DFSPH they may move between steps (:meth:`SPHLiquid.move_boundary`, a
rigid body or a deforming surface driven by another simulation) and report the force the fluid
exerts on each of them (:meth:`SPHLiquid.boundary_forces`), for two-way coupling.
"""

from __future__ import annotations

import math
import warnings
from typing import TYPE_CHECKING

import numba
import numpy as np

from ..kernels import kernel_id
from ..simulation import Frame, OutputSpec, Simulation, SimulationUnstableError, State
from . import particles
from .boundary import BoundaryParticles, lattice_volume
from .boundary_set import BoundarySet, boundary_forces
from .dfsph_step import MIN_DT, DFSPHStepper
from .model import SPHModel, as_field, check_boxes, default_support_factor
from .parameters import check_liquid_parameters
from .wcsph import CELL_PAD, REACH, WCSPHStepper

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["SPHModel", "SPHLiquid", "default_support_factor", "ContainerCorrectionWarning"]

#: Extras that follow the particles when they are re-ordered by grid cell.
_PER_PARTICLE = ("pi", "kappa_v", "pressure")


class ContainerCorrectionWarning(RuntimeWarning):
    """The container safety net of :class:`SPHLiquid` had to put particles back in the tank:
    the boundary did not hold."""


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
        Walls, obstacles and bodies, see :mod:`filters.sph.boundary`; they may move between
        steps (:meth:`move_boundary`, DFSPH).  None: no walls.
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
        Courant number in (0, 1], default 0.4.  DFSPH: ``dt = cfl * spacing / max |v|``, and the
        step is also capped so that a particle near a wall, at the velocity it ended the last
        step with, would approach the wall by at most ``0.35 cfl`` spacings
        (:meth:`filters.sph.dfsph_step.DFSPHStepper.wall_cap`; the cap shrinks by at most 30 %
        a step, so at an impact a particle can still come closer in one step: measured, up to
        0.38 spacings at cfl 0.4 in the 2 cm dam break's impact on the far wall, in 15 of its
        251 steps more than 0.14).
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
        ``(lower, upper)`` inner walls of a box tank (m): a safety net.  A particle found beyond
        a wall plane after a step is put back on the plane with its outward velocity removed;
        :attr:`contained` counts these corrections, frames carry the count as the field
        ``container_corrections`` and the first one raises a
        :class:`ContainerCorrectionWarning`.  The boundary is meant to hold without it: with
        DFSPH the wall constraints (:mod:`filters.sph.dfsph`) keep every particle off the
        walls (tested: none needed in the dam break at 1 cm and 4 mm).
    boundary_pressure : {"adami", "mirror"}
        WCSPH: ``"adami"`` (default): boundary pressures extrapolated from the fluid with the
        hydrostatic term (Adami, Hu & Adams 2012), which keeps the pressure gradient right next to
        walls; ``"mirror"``: each fluid particle's own pressure mirrored onto the boundary
        (Akinci et al. 2012), cheaper but makes narrow columns too stiff near walls.  DFSPH
        mirrors, plus its wall constraints (:mod:`filters.sph.dfsph`).
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
    kinematic_viscosity : float, optional
        DFSPH: ``nu`` (m^2/s) in [0, 1] of the implicit viscosity (Weiler et al. 2018), fluid
        and boundary alike; default Monaghan's ``alpha c h / 20`` from ``viscosity`` and
        ``boundary_viscosity``.
    initial_pressure : (N,) array_like, optional
        DFSPH: gauge pressure (Pa) the particles start with, e.g. the hydrostatic pressure of a
        resting pool (:func:`filters.sph.settle.hydrostatic_pressure`): the first pressure
        solves then start from equilibrium instead of from zero.  Default zeros.

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
    (WCSPH: positions at the last rebuild, which decide the next one) and ``kinematics``
    (``[max |v|, max |a|]`` of the last step, which the adaptive step uses; DFSPH adds the last
    step and the step cap), and for DFSPH the warm starts ``pi`` and ``kappa_v`` (see
    :mod:`filters.sph.dfsph`) and ``pressure``, what frames report, so a restored checkpoint
    continues bit-identically (tested).  After each DFSPH step,
    :attr:`last_density_iterations`, :attr:`last_divergence_iterations`,
    :attr:`last_density_error`, :attr:`last_divergence_error` and
    :attr:`last_wall_violation` describe the solves.

    Frames carry ``velocity`` (m/s), ``density`` (kg/m^3, by summation at the frame's
    positions), ``pressure`` (Pa, gauge: zero at the free surface; WCSPH: the equation of state
    at the frame's positions; DFSPH: the converged pressure of the last full step, that of the
    density and divergence solves together, which is hydrostatic in a liquid at rest) and
    ``id``, and the field ``container_corrections``.
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

    def __init__(self, positions: ArrayLike, velocities: ArrayLike | None = None, *, spacing: float,
                 boundary: BoundaryParticles | None = None, rest_density: float = 1000.0,
                 kernel: str = "cubic", support_factor: float | None = None,
                 speed_of_sound: float | None = None, gamma: float = 7.0, viscosity: float = 0.05,
                 boundary_viscosity: float | None = None, xsph: float = 0.0,
                 surface_tension: float = 0.0, gravity: ArrayLike = (0.0, 0.0, -9.81),
                 external: object | None = None, cfl: float = 0.4, max_dt: float | None = None,
                 density_error_limit: float = 0.1,
                 domain: tuple[ArrayLike, ArrayLike] | None = None,
                 container: tuple[ArrayLike, ArrayLike] | None = None,
                 boundary_pressure: str = "adami", skin: float = 0.2, threads: int | None = None,
                 solver: str = "wcsph", max_density_error: float = 1e-3,
                 max_divergence_error: float = 1e-2, max_iterations: int = 100,
                 kinematic_viscosity: float | None = None,
                 initial_pressure: ArrayLike | None = None):
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
        n = state.n_points
        if initial_pressure is not None:
            if solver != "dfsph":
                raise ValueError("initial_pressure needs solver='dfsph' (WCSPH's pressure "
                                 "follows from its density)")
            initial_pressure = np.array(initial_pressure, dtype=np.float64)
            if initial_pressure.shape != (n,) or not np.isfinite(initial_pressure).all() or (
                    initial_pressure < 0).any():
                raise ValueError(f"initial_pressure must be a finite ({n},) array of gauge "
                                 f"pressures >= 0 (Pa), got shape {initial_pressure.shape}")
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
        self.boundary_set = BoundarySet(boundary, rest_density, reach * CELL_PAD / REACH)
        initial = boundary if boundary is not None else BoundaryParticles(np.zeros((0, 3)),
                                                                          np.zeros(0))
        self.model = SPHModel(
            spacing=spacing, support=h, kernel=kernel, rest_density=rest_density, mass=mass,
            speed_of_sound=float(speed_of_sound), gamma=gamma, viscosity=viscosity,
            boundary_viscosity=boundary_viscosity, xsph=xsph, surface_tension=surface_tension,
            gravity=tuple(gravity), cfl=cfl, max_dt=max_dt,
            density_error_limit=density_error_limit, domain=domain, container=container,
            boundary_pressure=boundary_pressure,
            boundary_points=initial.points, boundary_volumes=initial.volumes, solver=solver,
            max_density_error=max_density_error, max_divergence_error=max_divergence_error,
            max_iterations=max_iterations,
        )
        self.max_dt = max_dt
        self.gravity = np.array(gravity, dtype=np.float64)
        self._field = field
        if domain is not None:
            self._dlo = np.array(domain[0], dtype=np.float64)
            self._dhi = np.array(domain[1], dtype=np.float64)
        if container is not None:
            self._clo = np.array(container[0], dtype=np.float64)
            self._chi = np.array(container[1], dtype=np.float64)
        #: Number of container corrections (particles put back on a wall plane) so far.
        self.contained = 0
        state.extra["id"] = np.arange(n, dtype=np.int64)
        state.extra["kinematics"] = np.array(
            [float(np.sqrt((state.velocities ** 2).sum(axis=1)).max()),
             float(np.linalg.norm(gravity))])
        self.state = state
        #: Largest relative compression ``max (rho - rho0) / rho0`` seen at the last evaluation.
        self.density_error = 0.0
        #: Mean relative compression over particles at the last evaluation.
        self.mean_density_error = 0.0
        #: DFSPH: iterations and mean errors the last step's solves reached (0 for WCSPH).
        self.last_density_iterations = 0
        self.last_divergence_iterations = 0
        self.last_density_error = 0.0
        self.last_divergence_error = 0.0
        #: DFSPH: largest wall-constraint violation the last density solve left (fraction of
        #: the kernel, see :mod:`filters.sph.dfsph`).
        self.last_wall_violation = 0.0
        #: DFSPH: conjugate-gradient iterations of the last implicit viscosity solve.
        self.last_viscosity_iterations = 0
        kind = kernel_id(kernel)
        if solver == "dfsph":
            pi = np.zeros(n) if initial_pressure is None else initial_pressure / rest_density
            state.extra["pi"] = pi  # rho0 p / rho^2 at rest density
            state.extra["kappa_v"] = np.zeros(n)
            state.extra["pressure"] = (np.zeros(n) if initial_pressure is None
                                       else initial_pressure.copy())
            # [.., last step, step cap]: the cap starts where gravity alone compresses the fluid
            # by the tolerance in one step and then follows the density solver's effort.
            gnorm = float(np.linalg.norm(gravity))
            cap = (min(max_dt, math.sqrt(max_density_error * spacing / gnorm)) if gnorm > 0.0
                   else max_dt)
            state.extra["kinematics"] = np.append(state.extra["kinematics"], [max_dt, cap])
            if kinematic_viscosity is None:  # Monaghan's nu = alpha c h' / (2 (d + 2))
                nu = (viscosity * speed_of_sound * 0.5 * h / 10.0,
                      boundary_viscosity * speed_of_sound * 0.5 * h / 10.0)
            else:
                nu = (kinematic_viscosity, kinematic_viscosity)
            self._stepper = DFSPHStepper(self, kind, volume, *nu)
        else:
            self._stepper = WCSPHStepper(self, kind, skin * h,
                                         rest_density * speed_of_sound ** 2 / gamma)
        self.threads = threads  # None: decided at each step (_step_threads)
        self._warned = False
        #: DFSPH: relative residual at which the implicit viscosity's conjugate gradients stop
        #: (1e-3).  A liquid coupled with bodies (:class:`filters.coupling.Coupled`) solves to
        #: 1e-6, so that the viscous forces it reports on the boundary are the momentum the
        #: fluid lost (at 1e-3 the residual left 0.2 % of a body's momentum unaccounted for).
        self.viscosity_tolerance = 1e-3

    # -- protocol -------------------------------------------------------------------------
    @property
    def output_spec(self) -> OutputSpec:
        return OutputSpec(point_arrays=(("velocity", 3), ("density", 1), ("pressure", 1),
                                        ("id", 1)), topology="vertices")

    def frame(self) -> Frame:
        """Current positions with ``velocity`` (m/s), ``density`` (kg/m^3, evaluated at these
        positions), ``pressure`` (Pa, gauge; see the class notes) and ``id``; the field
        ``container_corrections`` (int64, corrections so far)."""
        previous = numba.get_num_threads()
        numba.set_num_threads(self._step_threads(previous))
        try:
            self.evaluate_density()
        finally:
            numba.set_num_threads(previous)
        s = self.state
        stepper = self._stepper
        if self.model.solver == "dfsph":
            pressure = s.extra["pressure"].copy()
        else:
            pressure = stepper.p.copy()
        return Frame(time=s.time, points=s.positions.copy(), point_data={
            "velocity": s.velocities.copy(), "density": stepper.rho.copy(),
            "pressure": pressure, "id": s.extra["id"].copy()},
            field_data={"container_corrections": np.array([self.contained], dtype=np.int64)})

    def max_step(self) -> float:
        """Adaptive step (s).  WCSPH: CFL with viscous term and force condition.  DFSPH: the
        velocity CFL ``cfl * spacing / max |v|``, at most ``max_dt`` and at most a cap that
        follows the density solver's effort (:meth:`DFSPHStepper.step_cap
        <filters.sph.dfsph_step.DFSPHStepper.step_cap>`); at least 1e-5 s."""
        m = self.model
        if m.solver == "dfsph":
            kin = self.state.extra["kinematics"]
            vmax = float(kin[0])
            dt = min(self.max_dt, float(kin[3]) if kin.shape[0] > 3 else self.max_dt)
            if vmax * dt > m.cfl * m.spacing:
                dt = m.cfl * m.spacing / vmax
            return max(dt, MIN_DT)
        vmax, amax = (float(v) for v in self.state.extra["kinematics"][:2])
        hs = 0.5 * m.support
        dt = m.cfl * hs / (m.speed_of_sound * (1.0 + 0.6 * m.viscosity) + vmax)
        if amax > 0.0:
            dt = min(dt, 0.25 * math.sqrt(hs / amax))
        return min(dt, self.max_dt)

    #: :meth:`advance_to` crosses the time left in two equal steps where it is between one and
    #: two steps, so that no step is shorter than half of :meth:`max_step` (unless the whole
    #: interval is).  A DFSPH density solve removes the density error it finds within the step
    #: it is given: in a step a hundred times shorter than usual that asks for velocities a
    #: hundred times larger (measured: a 12 m/s kick in a dam break sampled every 3.6 ms, the
    #: remainder step being 25 microseconds).
    split_last_steps = True

    def set_state(self, state: State) -> None:
        super().set_state(state)
        self._stepper.forget_lists()  # lists belong to the old state

    # -- the boundary -----------------------------------------------------------------------
    @property
    def boundary(self) -> BoundaryParticles:
        """The boundary particles as they are now (moved by :meth:`move_boundary`), in the
        order of the ``BoundaryParticles`` the liquid was built with."""
        b = self.boundary_set
        return BoundaryParticles(b.points, b.volumes, b.normals, b.velocities, b.friction)

    def move_boundary(self, points: ArrayLike | None = None,
                      velocities: ArrayLike | None = None, *, volumes: ArrayLike | None = None,
                      indices: ArrayLike | None = None,
                      normals: ArrayLike | None = None) -> None:
        """Move (some of) the boundary particles before the next step (DFSPH).

        A rigid body or a deforming surface simulated elsewhere hands over its particles' new
        positions and velocities here; during the next step the fluid sees them move with
        those velocities (in the density and divergence solves, the wall constraints and the
        viscosity) and :meth:`boundary_forces` then reports what it did to them.

        Parameters
        ----------
        points : (K, 3) array_like, optional
            Positions (m) of the particles ``indices`` (all when ``indices`` is None).
        velocities : (K, 3) array_like, optional
            Their velocities (m/s).
        volumes : (K,) array_like, optional
            Their volumes (m^3), > 0 (a deformed surface:
            :func:`filters.sph.boundary.boundary_volumes`).
        indices : (K,) array_like of int, optional
            Which boundary particles, in the order the liquid was built with.
        normals : (K, 3) array_like, optional
            Their unit normals, e.g. those of a body that has turned.

        Raises
        ------
        ValueError
            For bad arrays (see :meth:`filters.sph.boundary_set.BoundarySet.move`), or with
            ``solver="wcsph"``, whose Verlet lists assume a static boundary.
        """
        if self.model.solver != "dfsph":
            raise ValueError("move_boundary needs solver='dfsph' (WCSPH's boundary is static)")
        self.boundary_set.move(points, velocities, volumes, indices, normals)

    def boundary_forces(self, indices: ArrayLike | None = None) -> np.ndarray:
        """Force (N) the fluid exerted on boundary particles during the last step (DFSPH).

        Pressure (the density and divergence solves' pressures mirrored onto the boundary,
        plus the wall pressures) and viscosity (the boundary term of the implicit viscosity,
        with each particle's friction factor), the reaction to what the boundary did to the
        fluid: summed over a body's particles, the force of the liquid on the body.  Computed
        on demand from a record of the step (no cost while nobody asks).

        Parameters
        ----------
        indices : array_like of int, optional
            Boundary particles (in the order the liquid was built with); default all.

        Returns
        -------
        (K, 3) float64
            Zeros before the first step, and after a step that stopped part way with an
            error (e.g. :class:`filters.simulation.SimulationUnstableError`).
        """
        if self.model.solver != "dfsph":
            raise ValueError("boundary_forces needs solver='dfsph'")
        stepper = self._stepper
        if stepper.record is None:
            k = self.boundary_set.n_points if indices is None else len(np.asarray(indices))
            return np.zeros((k, 3))
        return boundary_forces(stepper.record, indices)

    # -- used by the steppers ---------------------------------------------------------------
    def permute(self, order: np.ndarray) -> None:
        """Re-order the particles (positions, velocities, ``id`` and the per-particle warm
        starts) so that particle ``k`` is the old particle ``order[k]``."""
        s = self.state
        x = s.positions
        xo = np.empty_like(x)
        vo = np.empty_like(s.velocities)
        io = np.empty_like(s.extra["id"])
        particles.permute(x, s.velocities, s.extra["id"], order, xo, vo, io)
        s.positions = xo
        s.velocities = vo
        s.extra["id"] = io
        for name in _PER_PARTICLE:
            if name in s.extra and s.extra[name].shape == (x.shape[0],):
                s.extra[name] = s.extra[name][order]

    def note_density(self, rho: np.ndarray) -> float:
        """Record the largest and mean compression of the densities ``rho`` (kg/m^3)."""
        ratio = rho / self.model.rest_density - 1.0
        self.density_error = max(float(ratio.max()), 0.0)
        self.mean_density_error = float(np.maximum(ratio, 0.0).mean())
        return self.density_error

    def evaluate_density(self) -> float:
        """Densities (and WCSPH pressures) at the current positions; returns the largest
        compression."""
        self._stepper.density(self)
        return self.note_density(self._stepper.rho)

    def add_external(self, a: np.ndarray, amax: float) -> float:
        """Add the external field's accelerations to ``a`` (N, 3); returns the new ``max |a|``."""
        if self._field is None:
            return amax
        s = self.state
        extra = np.asarray(self._field(s.positions, s.velocities, s.time), dtype=np.float64)
        if extra.shape != s.positions.shape:
            raise ValueError(f"external field returned shape {extra.shape}, expected "
                             f"{s.positions.shape}")
        a += extra
        return float(np.sqrt((a ** 2).sum(axis=1)).max())

    # -- stepping ---------------------------------------------------------------------------
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
        s = self.state
        m = self.model
        vmax, amax = self._stepper.step(self, dt)
        if m.solver != "dfsph":
            s.extra["kinematics"] = np.array([vmax, amax])
        if m.container is not None:
            fixed = int(particles.contain(s.positions, s.velocities, self._clo, self._chi))
            if fixed:
                self.contained += fixed
                if not self._warned:
                    self._warned = True
                    warnings.warn(
                        f"the container safety net put {fixed} particle(s) back into the tank "
                        f"at t = {s.time + dt:.6g} s: the boundary did not hold (frames count "
                        f"the corrections in the field 'container_corrections')",
                        ContainerCorrectionWarning, stacklevel=4)
        if not math.isfinite(vmax):
            raise SimulationUnstableError(s.time + dt, "non-finite velocities",
                                          self.instability_hint)
        if m.domain is not None:
            bad = particles.outside(s.positions, self._dlo, self._dhi)
            if bad >= 0:
                raise SimulationUnstableError(
                    s.time + dt, f"particle {int(s.extra['id'][bad])} left the domain "
                    f"at {s.positions[bad].tolist()}", self.instability_hint)
