"""Bodies in a liquid: two-way coupling of rigid and elastic bodies with the DFSPH liquid.

:class:`Coupled` joins an :class:`filters.sph.SPHLiquid` (DFSPH) and body simulations
(:class:`filters.rigid.RigidBodies`, :class:`filters.elastic.fem_simulation.FEMSimulation`)
into one :class:`filters.simulation.Simulation`.  The bodies are part of the liquid's boundary,
the same boundary particles as the tank's walls (Akinci et al. 2012, "Versatile rigid-fluid
coupling for incompressible SPH", ACM TOG 31(4)): solid layers under each body's surface
(:mod:`filters.coupling.samples`), appended after the walls (:func:`coupled_boundary`).  One
step of ``dt``:

1. the body's boundary particles are where the body is, with its velocities (rigid:
   ``v + w x r``) and normals (:meth:`filters.sph.SPHLiquid.move_boundary`): the density and
   divergence solves, the wall constraints and the viscosity see them move;
2. the liquid steps; inside its density solve the rigid bodies accelerate with the pressures
   of every sweep (:mod:`filters.coupling.strong`, Gissler et al. 2019), so that the liquid
   expects the motion the body will make;
3. the force the liquid exerted on every boundary particle of a body during that step
   (pressure, wall pressure and viscosity, the exact reaction of what the body did to the
   fluid, :meth:`filters.sph.SPHLiquid.boundary_forces`) is applied to the body: summed into
   a force and a torque on a rigid body, or spread over an elastic body's nodes;
4. the bodies step with that force (and gravity, their contacts with the tank and each
   other), and their particles are moved to the new pose.

Buoyancy and drag are not modelled: they are what the pressure and the viscosity of the liquid
do to the body.  The momentum the liquid gives a body is the momentum it loses (Newton's third
law pair by pair), so the total momentum of liquid and bodies changes only by gravity and the
walls (tested in a closed tank without gravity).  Rigid bodies are strongly coupled to the
density solve (step 2; the force the solve moved a body with is the force the body then gets,
tested); the divergence solve and the viscosity see the bodies' velocities of the step's start,
and an elastic body moves after the liquid with the force of its step (explicitly).  Measured
on a box of half the water's density floating at rest: its vertical velocity departs from
the mean of the steps before and after by at most 0.0009 m/s; moved after the liquid's step
(``strong=False``) it alternated by up to 0.064 m/s, and one step in four needed more than 20
density iterations in the coupled benchmark's pool (one in 200 with the strong coupling).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np

from ..simulation import Frame, OutputSpec, Simulation, State
from ..sph.boundary import BoundaryParticles, concatenate_boundaries
from ..sph.liquid import SPHLiquid
from .parts import inside_depths, make_part, merge_state, split_state
from .strong import RigidLink

__all__ = ["Coupled", "CoupledModel", "coupled_boundary", "VISCOSITY_TOLERANCE", "BODY_GAP"]

#: Relative residual of the coupled liquid's implicit viscosity solve (the liquid's own default
#: is 1e-3): the viscous forces on the bodies then match the momentum the fluid lost (measured:
#: a box shot through a blob without gravity, total momentum kept to 5e-5 of it; 2e-3 at 1e-3,
#: 8e-7 at 1e-6, which took one more iteration a step, 2.9 against 1.9 in the coupled
#: benchmark's pool).
VISCOSITY_TOLERANCE = 1e-4
#: Where a particle found inside a rigid body is put back: this many spacings outside it.
BODY_GAP = 0.1


def _liquid_kernel(liquid: SPHLiquid):
    m = liquid.model
    return m.spacing, m.support / m.spacing, m.kernel


def _parts(bodies, spacing, support_factor, kernel):
    if not isinstance(bodies, (list, tuple)):
        bodies = (bodies,)
    if not bodies:
        raise ValueError("bodies must hold at least one RigidBodies or FEMSimulation")
    return [make_part(b, spacing, support_factor, kernel) for b in bodies]


def coupled_boundary(walls: BoundaryParticles | None, bodies: Sequence[Simulation],
                     spacing: float, *,
                     support_factor: float = 2.0, kernel: str = "cubic") -> BoundaryParticles:
    """The boundary of a liquid with bodies in it: the walls, then every body's particles.

    Build the :class:`filters.sph.SPHLiquid` with it (same ``spacing``, ``support_factor``
    and ``kernel``), then :class:`Coupled` with the same bodies in the same order.

    Parameters
    ----------
    walls : BoundaryParticles or None
        The static walls (a tank, :func:`filters.sph.boundary.box_boundary`).
    bodies : RigidBodies, FEMSimulation or a sequence of them
        The body simulations, at their initial state.
    spacing : float
        The liquid's particle spacing (m).
    support_factor : float
        The liquid's kernel support over its spacing.
    kernel : str
        The liquid's kernel.

    Returns
    -------
    BoundaryParticles
    """
    parts = _parts(bodies, spacing, support_factor, kernel)
    pieces = [] if walls is None else [walls]
    for part in parts:
        x, v, n = part.boundary()
        pieces.append(BoundaryParticles(x, part.volumes(), n, v))
    return concatenate_boundaries(*pieces)


@dataclass(frozen=True)
class CoupledModel:
    """Fixed parts of a :class:`Coupled` simulation.

    Attributes
    ----------
    liquid : filters.sph.SPHModel
        The liquid's model.
    bodies : tuple
        The body simulations' models, in order.
    boundary_ranges : tuple of (int, int)
        Per body simulation, the range of its particles in the liquid's boundary.
    """

    liquid: object
    bodies: tuple
    boundary_ranges: tuple


class Coupled(Simulation):
    """A DFSPH liquid and the bodies in it, two-way coupled (see the module notes).

    Parameters
    ----------
    liquid : SPHLiquid
        With ``solver="dfsph"``, built with the boundary of :func:`coupled_boundary` for these
        bodies (its last boundary particles are theirs), and the bodies' gravity.
    bodies : RigidBodies, FEMSimulation or a sequence of them
        The body simulations (each at the time of the liquid).
    strong : bool
        Move the rigid bodies inside the liquid's density solve (the default; see the module
        notes); False moves them after the liquid's step with its force.

    Raises
    ------
    ValueError, TypeError
        For a WCSPH liquid, a boundary that does not end with the bodies' particles, gravities
        that differ, or a body simulation of another kind.

    Notes
    -----
    The state (:meth:`get_state`) is the liquid's (positions, velocities, its extras) with each
    body simulation's state in the extras under ``body{k}:``, so a checkpoint resumes every
    part bit for bit.  Frames are the liquid's particles; their field data carry the bodies:
    ``body_position``, ``body_orientation`` (w, x, y, z), ``body_translation`` (one row per
    rigid body, the mesh as given maps by ``x = R X + t``), ``solid_surface`` (the elastic
    bodies' embedded surface vertices), ``fluid_penetration`` (m: how deep the deepest liquid
    particle is inside a body, 0 when none is) and ``body_corrections`` (particles put back
    out of a rigid body so far).  The DFSPH wall constraints hold the liquid off a body's
    faces, but at its convex corners, where the solid fills less of a particle's kernel, a
    particle can slip in (measured: 0.2 spacings at a sinking cube's corners); a particle
    found inside a rigid body after a step is put back :data:`BODY_GAP` spacings outside it,
    its approach velocity given to the body (:meth:`filters.coupling.parts.RigidPart.
    push_out`), as the tank's ``container`` safety net does for the walls.  An elastic body
    has no such net.  :attr:`last_body_forces` holds the force (N) and torque (N m) the
    liquid exerted on
    each body in the last step.
    """

    def __init__(self, liquid: SPHLiquid, bodies: Simulation | Sequence[Simulation], *,
                 strong: bool = True):
        if not isinstance(liquid, SPHLiquid):
            raise TypeError(f"liquid must be an SPHLiquid, got {type(liquid).__name__}")
        if liquid.model.solver != "dfsph":
            raise ValueError("liquid must use solver='dfsph' (moving boundaries and their "
                             "forces need the divergence-free solver)")
        if not isinstance(strong, (bool, np.bool_)):
            raise TypeError(f"strong must be True or False, got {strong!r}")
        spacing, support_factor, kernel = _liquid_kernel(liquid)
        parts = _parts(bodies, spacing, support_factor, kernel)
        for part in parts:
            g = np.asarray(part.sim.model.gravity, dtype=np.float64)
            if not np.allclose(g, liquid.gravity, rtol=0.0, atol=1e-12):
                raise ValueError(f"the bodies' gravity {g.tolist()} differs from the liquid's "
                                 f"{liquid.gravity.tolist()}")
            if part.sim.state.time != liquid.state.time:
                raise ValueError("the bodies and the liquid must start at the same time")
        total = sum(p.n_samples for p in parts)
        m = liquid.boundary_set.n_points
        if m < total:
            raise ValueError(f"the liquid's boundary has {m} particles, fewer than the bodies' "
                             f"{total}: build it with coupled_boundary(walls, bodies, ...)")
        ranges = []
        start = m - total
        points = liquid.boundary_set.points
        for part in parts:
            x = part.boundary()[0]
            stop = start + part.n_samples
            if not np.allclose(points[start:stop], x, rtol=0.0, atol=1e-9 * spacing):
                raise ValueError("the liquid's boundary does not end with the bodies' particles "
                                 "where they are: build it with coupled_boundary(walls, "
                                 "bodies, ...) for the same bodies, in the same order")
            ranges.append((start, stop))
            start = stop
        self.liquid = liquid
        liquid.viscosity_tolerance = min(liquid.viscosity_tolerance, VISCOSITY_TOLERANCE)
        self.parts = parts
        self._indices = [np.arange(a, b) for a, b in ranges]
        self.model = CoupledModel(liquid.model, tuple(p.sim.model for p in parts),
                                  tuple(ranges))
        self.max_dt = min([liquid.max_dt] + [p.sim.max_dt for p in parts])
        #: Liquid particles put back out of a rigid body so far (the bodies' safety net, see
        #: :meth:`filters.coupling.parts.RigidPart.push_out`).
        self.corrections = 0
        #: Per body simulation, the (B, 6) force (N) and torque (N m) of the last step.
        self.last_body_forces = [np.zeros((0, 6)) for _ in parts]
        self._link = self._make_link() if strong else None
        self._place()

    def _make_link(self):
        owner = np.full(self.liquid.boundary_set.n_points, -1, dtype=np.int64)
        count = 0
        self._link_rows = []  # per part, its bodies' rows of the link (None: not linked)
        for part, (a, b) in zip(self.parts, self.model.boundary_ranges, strict=True):
            if part.kind != "rigid":
                self._link_rows.append(None)
                continue
            owner[a:b] = part.owner + count
            self._link_rows.append(slice(count, count + part.sim.n_bodies))
            count += part.sim.n_bodies
        return RigidLink(self.liquid, owner) if count else None

    def _set_link(self) -> None:
        centers, inv_mass, inv_inertia = [], [], []
        for part in self.parts:
            if part.kind == "rigid":
                c, im, ii = part.dynamics()
                centers.append(c)
                inv_mass.append(im)
                inv_inertia.append(ii)
        self._link.set_bodies(np.concatenate(centers), np.concatenate(inv_mass),
                              np.concatenate(inv_inertia))

    @property
    def instability_hint(self) -> str:
        return self.liquid.instability_hint

    @property
    def state(self) -> State:
        """The liquid's state (its time is the simulation's); :meth:`get_state` has all."""
        return self.liquid.state

    @property
    def bodies(self) -> list:
        """The body simulations, in order."""
        return [p.sim for p in self.parts]

    @property
    def output_spec(self) -> OutputSpec:
        return self.liquid.output_spec

    # -- stepping ---------------------------------------------------------------------------
    def _place(self) -> None:
        """Move every body's boundary particles to where the body is now."""
        self._where = []
        for part, idx in zip(self.parts, self._indices, strict=True):
            x, v, n = part.boundary()
            self.liquid.move_boundary(x, v, normals=n, indices=idx)
            self._where.append(x)

    def max_step(self) -> float:
        """The smallest of the liquid's and the bodies' largest steps (s)."""
        return min([self.liquid.max_step()] + [p.sim.max_step() for p in self.parts])

    def step(self, dt: float) -> None:
        """Advance liquid and bodies by ``dt`` seconds (see the module notes).

        Raises
        ------
        ValueError
            If ``dt`` is not a finite number > 0.
        SimulationUnstableError
            From the liquid or a body.
        """
        if not (isinstance(dt, (int, float, np.floating)) and math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a finite number > 0 (s), got {dt!r}")
        dt = float(dt)
        liquid = self.liquid
        previous = numba.get_num_threads()
        # the liquid's thread count for the whole step (waking threads for the small body
        # kernels costs more than they save on a busy machine)
        numba.set_num_threads(liquid.threads or (1 if liquid.state.n_points < 20_000
                                                 else previous))
        try:
            self._step(dt)
        finally:
            numba.set_num_threads(previous)
        self.steps_taken += 1

    def _step(self, dt: float) -> None:
        where = self._where
        solver = self.liquid._stepper.solver
        link = self._link
        if link is not None:
            self._set_link()
            link.ready = False
        solver.link = link  # for this step only: the liquid stepped alone has no bodies
        try:
            self.liquid.step(dt)
        finally:
            solver.link = None
        # the rigid bodies' force and torque as the density solve summed them (its pairs, the
        # same sum as the liquid's boundary forces); elastic bodies take them per particle
        linked = link.forces() if link is not None else None
        for k, (part, idx) in enumerate(zip(self.parts, self._indices, strict=True)):
            rows = self._link_rows[k] if linked is not None else None
            if rows is not None:
                self.last_body_forces[k] = part.push_wrenches(linked[rows])
            else:
                forces = self.liquid.boundary_forces(idx)
                self.last_body_forces[k] = part.push(where[k], forces)
            part.step(dt)
            part.sim.state.time = self.liquid.state.time
        s = self.liquid.state
        gap = BODY_GAP * self.liquid.model.spacing
        for part in self.parts:
            moved = part.push_out(s.positions, s.velocities, self.liquid.model.mass, gap)
            self.corrections += moved
        self._place()

    #: no sliver of a last step, as the liquid alone (:attr:`SPHLiquid.split_last_steps`)
    split_last_steps = True

    def _land_on(self, time: float) -> None:
        self.liquid.state.time = time
        for part in self.parts:
            part.sim.state.time = time

    def check_finite(self) -> None:
        self.liquid.check_finite()
        for part in self.parts:
            part.sim.check_finite()

    # -- state ------------------------------------------------------------------------------
    def get_state(self) -> State:
        """A copy of the whole state: the liquid's, each body's under ``body{k}:``."""
        s = self.liquid.get_state()
        extra = dict(s.extra)
        for k, part in enumerate(self.parts):
            merge_state(extra, f"body{k}", part.sim.get_state())
        return State(s.positions, s.velocities, s.time, s.step, extra)

    def set_state(self, state: State) -> None:
        """Restore a state of :meth:`get_state` (copied); the bodies' particles follow.

        Raises
        ------
        ValueError
            If a body's state is missing or does not fit.
        """
        if not isinstance(state, State):
            raise TypeError(f"state must be a State, got {type(state).__name__}")
        for k in range(len(self.parts)):
            if f"body{k}:positions" not in state.extra:
                raise ValueError(f"state is missing body {k} (extra 'body{k}:positions')")
        liquid = {k: v for k, v in state.extra.items() if not k.startswith("body")}
        self.liquid.set_state(State(state.positions, state.velocities, state.time, state.step,
                                    liquid))
        for k, part in enumerate(self.parts):
            part.sim.set_state(split_state(state, f"body{k}"))
        self._place()

    # -- output -----------------------------------------------------------------------------
    def meshes(self) -> list:
        """Every body's surface where it is now: a list of ``(vertices (V, 3), triangles (T,
        3))``, rigid bodies first in the order given, then elastic ones."""
        out = []
        for part in self.parts:
            out.extend(part.meshes())
        return out

    def penetration(self) -> float:
        """How deep (m) the deepest liquid particle lies inside a body's surface now (0: none
        inside)."""
        x = self.liquid.state.positions
        return max([float(inside_depths(x, v, f).max(initial=0.0)) for v, f in self.meshes()])

    def fluid_inside(self, depth: float | None = None) -> int:
        """Number of liquid particles more than ``depth`` (m; default a tenth of the spacing)
        inside a body's surface now."""
        if depth is None:
            depth = 0.1 * self.liquid.model.spacing
        x = self.liquid.state.positions
        return int(sum(int((inside_depths(x, v, f) > depth).sum()) for v, f in self.meshes()))

    def body_mesh_layout(self) -> list:
        """How frames describe the bodies, for the pipeline: per body a dict with ``kind``
        (``"rigid"``: ``vertices`` as given and ``triangles``, its row ``row`` of the
        ``body_*`` field arrays; ``"elastic"``: ``triangles`` and the rows ``start`` to
        ``stop`` of ``solid_surface``)."""
        layout = []
        row = 0
        start = 0
        for part in self.parts:
            if part.kind == "rigid":
                for body in part.sim.model.bodies:
                    layout.append({"kind": "rigid", "vertices": np.asarray(body.vertices)
                                   + body.center, "triangles": np.asarray(body.faces),
                                   "row": row})
                    row += 1
            else:
                count = part.sim.model.mesh.embedding.rest_points.shape[0]
                layout.append({"kind": "elastic", "triangles": part.triangles,
                               "start": start, "stop": start + count})
                start += count
        return layout

    def frame(self) -> Frame:
        """The liquid's frame with the bodies in its field data (see the class notes)."""
        frame = self.liquid.frame()
        fields = {}
        for part in self.parts:
            for name, value in part.field_data().items():
                fields.setdefault(name, []).append(value)
        for name, values in fields.items():
            frame.field_data[name] = np.ascontiguousarray(np.concatenate(values))
        x = self.liquid.state.positions
        depth = max([float(inside_depths(x, v, f).max(initial=0.0)) for v, f in self.meshes()])
        frame.field_data["fluid_penetration"] = np.array([depth])
        frame.field_data["body_corrections"] = np.array([self.corrections], dtype=np.int64)
        return frame

    # -- diagnostics ------------------------------------------------------------------------
    def momentum(self) -> np.ndarray:
        """Total linear momentum (kg m/s) of the liquid and the moving bodies, (3,)."""
        p = self.liquid.model.mass * self.liquid.state.velocities.sum(axis=0)
        for part in self.parts:
            p = p + part.momentum()
        return p

