"""The weakly compressible stepper of :class:`filters.sph.SPHLiquid` (Becker & Teschner 2007).

The method (equation of state, forces, boundary pressures, the adaptive step) is described in
:mod:`filters.sph.forces`, with its references.  Neighbour lists are Verlet lists: built with a
skin (radius ``h (1 + skin)``) by the uniform grid of :mod:`filters.neighbors` and reused by
every pass until some particle has moved half the skin; each rebuild also re-sorts the particles
by grid cell (a parallel counting sort) for memory locality.  The ``id`` array in the state's
extras follows the particles through these permutations.  The boundary is static here (moving
boundaries need the DFSPH solver).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numba
import numpy as np

from ..binning import cell_keys, counting_sort
from ..neighbors import bounds, grid_query_padded
from ..simulation import SimulationUnstableError
from . import forces, particles

if TYPE_CHECKING:
    from .liquid import SPHLiquid

__all__ = ["WCSPHStepper", "CELL_PAD", "REACH"]

#: Grid cells are padded by this factor so that a neighbour at exactly the radius is found.
CELL_PAD = 1.0 + 1e-9
#: Grid cells per search radius (see :mod:`filters.neighbors`).
REACH = 2


class WCSPHStepper:
    """Neighbour lists, densities and one WCSPH step of a liquid.

    Parameters
    ----------
    liquid : SPHLiquid
        The liquid stepped (its ``model``, ``state``, ``boundary_set`` and ``gravity``).
    kind : int
        Kernel id.
    skin : float
        Verlet skin (m).
    stiffness : float
        Tait ``B = rho0 c^2 / gamma`` (Pa).
    """

    def __init__(self, liquid: SPHLiquid, kind: int, skin: float, stiffness: float):
        n = liquid.state.n_points
        self.kind = kind
        self.skin = skin
        self.stiffness = stiffness
        self.tab = None
        self.capacity = 48
        self.bcapacity = 32
        self.rho = np.empty(n)
        self.p = np.empty(n)
        self.a = np.empty((n, 3))
        self.nrm = np.zeros((n, 3))
        self.bpr = np.full(liquid.boundary_set.n_points, -1.0)

    def forget_lists(self) -> None:
        """Drop the lists (they belong to a state that was replaced)."""
        self.tab = None

    def ensure_lists(self, liquid: SPHLiquid) -> None:
        """Make the neighbour lists valid for the current positions (Verlet lists with a skin).

        Lists hold every pair within ``h + skin`` of the positions at the last rebuild (the
        ``anchor`` in the state's extras) and stay valid while no particle has moved more than
        ``skin / 2`` from its anchor.  A rebuild also sorts the particles by grid cell.  Rows are
        sorted by index and every pass skips pairs beyond ``h``, so sums do not depend on which
        valid list is used: a state restored between rebuilds (lists rebuilt without sorting,
        with radius ``h + 2 skin``) continues bit-identically.
        """
        s = liquid.state
        h = liquid.model.support
        anchor = s.extra.get("anchor")
        if anchor is None or anchor.shape != s.positions.shape:
            rebuild = True
        else:
            moved2 = particles.max_displacement2(s.positions, anchor)
            rebuild = self.skin <= 0.0 or moved2 > (0.5 * self.skin) ** 2
        if rebuild:
            self._build_lists(liquid, h + self.skin, permute=True)
            s.extra["anchor"] = s.positions.copy()
        elif self.tab is None:
            self._build_lists(liquid, h + 2.0 * self.skin, permute=False)

    def _build_lists(self, liquid, radius, permute):
        s = liquid.state
        x = s.positions
        cell = radius * CELL_PAD / REACH
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
        if permute:
            liquid.permute(order)
            sx = s.positions
            sorted_ids = np.arange(x.shape[0], dtype=np.int32)
        else:
            sx = np.ascontiguousarray(x[order])
            sorted_ids = order
        r2 = radius * radius
        self.tab, self.cnt, best = grid_query_padded(
            s.positions, True, False, sx, start, sorted_ids, lo, cell, dims, REACH, r2,
            self.capacity)
        self.capacity = best + 4
        particles.sort_rows(self.tab, self.cnt)
        b = liquid.boundary_set
        identity = np.arange(b.n_points, dtype=np.int32)
        self.btab, self.bcnt, best = grid_query_padded(
            s.positions, False, False, b.sorted_points, b.start, identity, b.origin, b.cell,
            b.dims, REACH, r2, self.bcapacity)
        self.bcapacity = max(best, 1) + 4
        particles.sort_rows(self.btab, self.bcnt)

    def density(self, liquid: SPHLiquid) -> float:
        """Densities (kg/m^3) and Tait pressures (Pa, gauge) at the current positions; returns
        the largest compression."""
        m = liquid.model
        b = liquid.boundary_set
        self.ensure_lists(liquid)
        forces.density(liquid.state.positions, self.tab, self.cnt, b.sorted_points, self.btab,
                       self.bcnt, b.sorted_mass, m.mass, m.support, self.kind, self.rho)
        return float(forces.tait_pressure(self.rho, m.rest_density, self.stiffness, m.gamma,
                                          self.p))

    def step(self, liquid: SPHLiquid, dt: float) -> tuple[float, float]:
        """One symplectic Euler step of ``dt`` seconds; returns ``(max |v|, max |a|)``."""
        s = liquid.state
        m = liquid.model
        b = liquid.boundary_set
        err = liquid.evaluate_density()
        if not np.isfinite(err) or err > m.density_error_limit:
            raise SimulationUnstableError(
                s.time, f"density error {err:.3g} > density_error_limit {m.density_error_limit:g}",
                liquid.instability_hint)
        x = s.positions
        v = s.velocities
        if m.surface_tension > 0.0:
            forces.normals(x, self.rho, self.tab, self.cnt, m.mass, m.support, self.kind,
                           self.nrm)
        g = liquid.gravity
        forces.boundary_pressures(x, self.rho, self.p, b.sorted_points, self.btab, self.bcnt,
                                  m.support, self.kind, g, m.rest_density, self.stiffness,
                                  m.gamma, m.boundary_pressure == "mirror", self.bpr)
        amax = forces.accelerations(x, v, self.rho, self.p, self.tab, self.cnt, b.sorted_points,
                                    self.btab, self.bcnt, b.sorted_mass, self.bpr,
                                    b.sorted_friction, m.mass,
                                    m.support, self.kind, m.viscosity, m.boundary_viscosity,
                                    m.speed_of_sound, m.rest_density, m.surface_tension,
                                    self.nrm, g, self.a)
        amax = liquid.add_external(self.a, amax)
        vmax = particles.integrate(x, v, self.a, dt)
        if m.xsph > 0.0:
            out = np.empty_like(v)
            forces.xsph(v, self.rho, x, self.tab, self.cnt, m.mass, m.support, self.kind,
                        m.xsph, out)
            s.velocities = out
            vmax = float(np.sqrt((out ** 2).sum(axis=1)).max())
        return vmax, amax
