"""The divergence-free stepper of :class:`filters.sph.SPHLiquid` (Bender & Koschier 2015, 2017).

One step (Bender & Koschier 2017, Alg. 1): sort the particles by grid cell and compute
neighbours, densities, ``alpha_i`` and the walls in one pass; make the velocities divergence
free; apply gravity, surface tension and external fields; solve the implicit viscosity; solve
for constant density with the wall constraints (:mod:`filters.sph.dfsph`); drift.  What the
step leaves behind: the warm starts in the state, the pressure frames report (that of the last
full step, see :meth:`DFSPHStepper.step`) and a record from which the force of the fluid on the
boundary particles is computed on demand (:func:`filters.sph.boundary_set.boundary_forces`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numba
import numpy as np

from ..binning import cell_keys, counting_sort
from ..neighbors import bounds
from ..simulation import SimulationUnstableError
from . import dfsph_kernels as K
from . import forces, particles
from .dfsph import DFSPHSolver
from .wall_profile import WallProfile
from .wcsph import CELL_PAD, REACH

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from .liquid import SPHLiquid

__all__ = ["DFSPHStepper", "MIN_DT", "BUSY", "EASY", "FULL_STEP", "WALL_CFL", "SLIVER"]

#: Smallest DFSPH step (s); a faster fluid is a blow-up here.
MIN_DT = 1e-5
#: Density-solve iterations above which the next step shrinks ...
BUSY = 20
#: ... and below which it may grow again.
EASY = 10
#: Fraction of ``cfl`` (spacings per step) by which a particle may approach a wall it is near.
WALL_CFL = 0.35
#: A step at least this fraction of :meth:`SPHLiquid.max_step` is a full step: its pressure is
#: the one frames report (the last, shortened step before a frame time is not).
FULL_STEP = 0.9
#: A step shorter than this fraction of :meth:`SPHLiquid.max_step` is a sliver: its density
#: solve removes only ``dt / (SLIVER max_step)`` of the density error the particles start with
#: (the rest goes to the next steps).  Removing all of it within a sliver takes velocities of
#: ``error spacing / dt``: one step of 1.7e-5 s in a resting pool (0.1 % error) kicked
#: particles from 0.08 to 0.45 m/s.  ``advance_to`` never takes such steps (it crosses the
#: last one or two in equal halves); a script calling ``step`` with what is left may.
SLIVER = 0.25


class DFSPHStepper:
    """Neighbourhoods, the two pressure solves and one DFSPH step of a liquid.

    Parameters
    ----------
    liquid : SPHLiquid
        The liquid stepped.
    kind : int
        Kernel id.
    volume : float
        Rest volume of a fluid particle (m^3).
    nu, nu_b : float
        Kinematic viscosity of the fluid and against the boundary (m^2/s).
    """

    def __init__(self, liquid: SPHLiquid, kind: int, volume: float, nu: float, nu_b: float):
        m = liquid.model
        n = liquid.state.n_points
        walls = None
        if liquid.boundary_set.n_points:
            profile = WallProfile(m.support, m.kernel)
            walls = (m.spacing, profile.inverse_distance, profile.inverse_slope)
        self.solver = DFSPHSolver(volume, m.support, kind, m.max_density_error,
                                  m.max_divergence_error, m.max_iterations, walls=walls)
        self.kind = kind
        self.nu = nu
        self.nu_b = nu_b
        self.rho = np.empty(n)
        self.a = np.empty((n, 3))
        self.nrm = np.zeros((n, 3))
        self.zero_p = np.zeros(n)
        self.no_boundary = (np.zeros((0, 3)), np.zeros((n, 1), dtype=np.int32),
                            np.zeros(n, dtype=np.int32), np.zeros(0), np.full(0, -1.0),
                            np.zeros(0))
        self.record = None
        self.grid = None

    def forget_lists(self) -> None:
        """Nothing to forget: every step finds its neighbours afresh."""

    def neighbourhood(self, liquid: SPHLiquid) -> NDArray[np.float64]:
        """Sort the particles by grid cell (cells of ``h / 2``; a stable counting sort, the
        identity on already sorted particles) and compute neighbours, kernel gradients,
        densities, ``alpha_i`` and the walls in one pass (:meth:`DFSPHSolver.neighbourhood`).
        Returns the densities (kg/m^3)."""
        s = liquid.state
        m = liquid.model
        x = s.positions
        cell = m.support * CELL_PAD / REACH
        lo, hi, finite = bounds(x)
        if not finite:
            raise SimulationUnstableError(s.time, "non-finite positions", liquid.instability_hint)
        dims_f = np.floor((hi - lo) / cell) + 1.0
        if float(np.prod(dims_f)) > 2e8:
            raise SimulationUnstableError(s.time, "particle spread",
                                          "particles spread over more than 2e8 grid cells")
        dims = dims_f.astype(np.int64)
        keys = cell_keys(x, lo, 1.0 / cell, dims)
        start, order = counting_sort(keys, int(np.prod(dims)), numba.get_num_threads())
        if not particles.is_identity(order):
            liquid.permute(order)
        self.freeze_record()  # the pass overwrites the arrays the record refers to
        self.grid = (start, lo, cell, dims)
        self.rho = self.solver.neighbourhood(s.positions, start, lo, cell, dims,
                                             liquid.boundary_set.arrays(), m.mass)
        return self.rho

    def density(self, liquid: SPHLiquid) -> float:
        """Densities at the current positions (sorting the particles); returns the largest
        compression."""
        rho = self.neighbourhood(liquid)
        return max(float((rho / liquid.model.rest_density - 1.0).max()), 0.0)

    def freeze_record(self) -> None:
        """Copy what the boundary-force record borrows from the solver's work arrays."""
        r = self.record
        if r is not None and not r["frozen"]:
            for name in ("wall_pressure", "clusters", "cluster_normals"):
                r[name] = r[name].copy()
            r["frozen"] = True

    def step(self, liquid: SPHLiquid, dt: float) -> tuple[float, float]:
        """One DFSPH step of ``dt`` seconds; returns ``(max |v|, max |a|)`` (m/s, m/s^2).

        When ``dt`` is a full step (at least :data:`FULL_STEP` of the step the liquid would
        take), the state's ``pressure`` becomes this step's pressure ``p = (pi + pi_v)
        rho^2 / rho0`` (Pa, gauge: zero at the free surface) from the converged density and
        divergence solves, the field frames report.  The last step before a frame time is
        shortened to land on it; its solves answer a density error in a fraction of the usual
        time with a pressure scaled up accordingly, which is why it is not reported.
        """
        s = liquid.state
        m = liquid.model
        solver = self.solver
        largest = liquid.max_step()
        full = dt >= FULL_STEP * largest
        fraction = min(1.0, dt / (SLIVER * largest))
        n = s.n_points
        for name in ("pi", "kappa_v", "pressure"):
            if s.extra.get(name) is None or s.extra[name].shape != (n,):
                s.extra[name] = np.zeros(n)  # e.g. a state written by a WCSPH run
        # the step makes a record of its own: copying the last one out of the work arrays
        # that the pass is about to overwrite would be wasted (a few % of a step)
        self.record = None
        rho = self.neighbourhood(liquid)
        liquid.note_density(rho)
        mean_err = liquid.mean_density_error
        if not math.isfinite(mean_err) or mean_err > m.density_error_limit:
            raise SimulationUnstableError(
                s.time, f"mean density error {mean_err:.3g} > density_error_limit "
                f"{m.density_error_limit:g}", liquid.instability_hint)
        x = s.positions
        v = s.velocities
        ex = s.extra
        solver.divergence_solve(v, dt, ex["kappa_v"])
        g = liquid.gravity
        if m.surface_tension > 0.0:
            tab, cnt = solver.ntab, solver.ncnt
            forces.normals(x, rho, tab, cnt, m.mass, m.support, self.kind, self.nrm)
            amax = forces.accelerations(x, v, rho, self.zero_p, tab, cnt, *self.no_boundary,
                                        m.mass, m.support, self.kind, 0.0, 0.0,
                                        m.speed_of_sound, m.rest_density, m.surface_tension,
                                        self.nrm, g, self.a)
        else:
            self.a[:] = g
            amax = float(np.linalg.norm(g))
        amax = liquid.add_external(self.a, amax)
        solver.kick(v, self.a, dt)
        liquid.last_viscosity_iterations = solver.viscosity_solve(
            v, x, dt, self.nu, self.nu_b, tolerance=liquid.viscosity_tolerance)
        viscous = v.copy() if self.nu_b > 0.0 and liquid.boundary_set.n_points else None
        solver.density_solve(v, rho, m.rest_density, dt, ex["pi"], fraction)
        liquid.last_density_iterations = solver.density_iterations
        liquid.last_divergence_iterations = solver.divergence_iterations
        liquid.last_density_error = solver.density_error
        liquid.last_divergence_error = solver.divergence_error
        liquid.last_wall_violation = solver.wall_violation
        err = solver.density_error
        if not math.isfinite(err) or (solver.density_iterations >= m.max_iterations
                                      and err > m.density_error_limit):
            raise SimulationUnstableError(
                s.time, f"DFSPH density solve reached a mean density error {err:.3g} > "
                f"density_error_limit {m.density_error_limit:g} in {m.max_iterations} "
                f"iterations", liquid.instability_hint)
        total = ex["pi"] + ex["kappa_v"] / dt  # both solves' pressure, pi = rho0 p / rho^2
        if full:
            ex["pressure"] = total * rho * rho / m.rest_density
        self._keep_record(liquid, total, viscous, dt)
        vmax = solver.drift(x, v, dt)
        if m.xsph > 0.0:
            out = np.empty_like(v)
            forces.xsph(v, rho, x, solver.ntab, solver.ncnt, m.mass, m.support, self.kind,
                        m.xsph, out)
            s.velocities = out
            vmax = float(np.sqrt((out ** 2).sum(axis=1)).max())
        old = ex["kinematics"]
        cap = self.step_cap(liquid, float(old[3]) if old.shape[0] > 3 else liquid.max_dt, dt,
                            solver.density_iterations)
        cap = self.wall_cap(liquid, s.velocities, cap, dt)
        ex["kinematics"] = np.array([vmax, amax, dt, cap])
        return vmax, amax

    def _keep_record(self, liquid, total, viscous, dt):
        b = liquid.boundary_set
        if not b.n_points:
            self.record = None
            return
        m = liquid.model
        start, lo, cell, dims = self.grid
        solver = self.solver
        self.record = {
            "frozen": False, "time": liquid.state.time, "dt": dt,
            "positions": liquid.state.positions.copy(), "pressure": total,
            "wall_pressure": solver.wall_pressure, "clusters": solver.ncl,
            "cluster_normals": solver.cn,
            "velocities": viscous if viscous is not None else np.zeros((1, 3)),
            "boundary_viscosity": self.nu_b if viscous is not None else 0.0,
            "start": start, "origin": lo, "cell": cell, "dims": dims, "mass": m.mass,
            "support": m.support, "kind": self.kind,
            "boundary": {"order": b.order, "points": b.sorted_points,
                         "velocities": b.sorted_velocities, "volumes": b.sorted_volumes,
                         "friction_volumes": b.sorted_friction_volumes,
                         "normals": b.sorted_normals},
        }

    def wall_cap(self, liquid: SPHLiquid, v: np.ndarray, cap: float, dt: float) -> float:
        """The step cap after the wall condition: no particle within a spacing of the closest a
        wall constraint lets it come (:mod:`filters.sph.dfsph`) may approach that wall by more
        than :data:`WALL_CFL` ``* cfl`` spacings in a step (cfl 0.4: 0.14 spacings).

        The velocity CFL condition lets the fastest particle move ``cfl`` spacings in a step,
        and particles that hit a wall at that speed are stopped by the wall constraint but
        squeezed by the fluid behind them before the linearised density solve sees it (the
        bench dam break's worst particle at the impact on the far wall: 4.3 % without the
        condition, 1.6 % with it, for 10 % more steps).  Particles sliding along a wall do not
        approach it, so the condition only bites at impacts.  The cap shrinks by at most 30 %
        per step.
        """
        solver = self.solver
        if solver.walls is None:
            return cap
        gaps, spacing, inv_d, inv_s = solver.walls
        vn = K.wall_approach(v, solver.ncl, solver.cphi, solver.cgb, solver.cvb,
                             gaps[1] + spacing, inv_d, inv_s)
        if vn > 0.0:
            cap = min(cap, max(WALL_CFL * liquid.model.cfl * spacing / vn, 0.7 * dt))
        return cap

    def step_cap(self, liquid: SPHLiquid, cap: float, dt: float, iterations: int) -> float:
        """The step cap after a step of ``dt`` whose density solve took ``iterations``.

        The velocity CFL condition alone lets a tall resting column take ``max_dt`` steps,
        and a relaxed Jacobi solve cannot carry the missing hydrostatic pressure through
        dozens of layers in one step: the bottom compresses a little more every step until the
        flow blows up (measured: a 76-layer column at 5 ms steps).  Like SPlisHSPlasH's
        iteration-aware CFL mode, the step therefore follows the solver: it shrinks to 0.9 dt
        when the solve needed more than 20 iterations (0.5 dt when it did not converge) and
        grows by 10 % per step, up to ``max_dt``, while it needs fewer than 10.
        """
        if iterations >= liquid.model.max_iterations:
            return 0.5 * dt
        if iterations > BUSY:
            return 0.9 * dt
        if iterations < EASY:
            return min(1.1 * cap, liquid.max_dt)
        return cap
