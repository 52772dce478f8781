"""Mass-spring simulations: hair, cloth and jello, with colliders and a choice of integrator.

:class:`MassSpringSimulation` couples a :class:`filters.elastic.topology.SpringTopology` with a
:class:`filters.elastic.springs.SpringSystem` and one of the schemes of :mod:`filters.integrators`
(backward Euler by Newton with a line search by default), with contacts and Coulomb friction
against :class:`filters.elastic.contact.Colliders` solved inside every step
(:class:`filters.elastic.contact_model.ContactModel`).  Frames carry the spring mesh (hair as
lines, cloth as triangles) or, for jello, the user's embedded mesh deformed by the lattice
(trilinear weights), with a fixed topology so that XDMF export can share it, and the energy
account as field data.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..integrators import check_scheme, integrate
from ..linalg import LinearSolver
from ..simulation import Frame, OutputSpec, Simulation, SimulationUnstableError, State
from ..validation import check_choice, check_finite_vector, check_int, check_range
from .contact import Colliders
from .contact_model import DEFAULT_SLIP_VELOCITY, DEFAULT_STIFFNESS_RATIO, ContactModel
from .energy import EnergyAccount, energy_account
from .springs import DAMPING_MODES, SpringSystem
from .topology import (
    BEND,
    SHEAR,
    STRETCH,
    SpringTopology,
    cloth_from_mesh,
    cloth_grid,
    hair_strands,
    jello_from_mesh,
)

if TYPE_CHECKING:
    from typing import Any

    from numpy.typing import ArrayLike

__all__ = [
    "MassSpringModel",
    "MassSpringSimulation",
    "ClothSimulation",
    "HairSimulation",
    "JelloSimulation",
    "check_stepping",
]


@dataclass(frozen=True)
class MassSpringModel:
    """Fixed parameters of a :class:`MassSpringSimulation` (arrays are read-only).

    Attributes
    ----------
    topology : SpringTopology
        Particles, springs, masses, pins and output cells.
    stiffness : (S,) float64 array
        Seed-form spring stiffness (N).
    damping : (S,) float64 array
        Spring damping (N s/m).
    damping_mode : str
        ``"axial"`` or ``"relative"``.
    drag : float
        Per-particle drag (N s/m).
    gravity : tuple of 3 float
        Acceleration (m/s^2).
    scheme : str
        Integrator name (one of :data:`filters.integrators.SCHEMES`).
    solver : str
        Linear solver of the implicit schemes.
    substeps : int
        Integrator steps per :meth:`Simulation.step`.
    max_speed : float
        Speed (m/s) above which the simulation is declared unstable.
    """

    topology: SpringTopology
    stiffness: np.ndarray
    damping: np.ndarray
    damping_mode: str
    drag: float
    gravity: tuple
    scheme: str
    solver: str
    substeps: int
    max_speed: float


def _per_kind(kinds, stretch, shear, bend):
    values = np.empty(kinds.shape[0])
    values[kinds == STRETCH] = stretch
    values[kinds == SHEAR] = shear
    values[kinds == BEND] = bend
    return values



def check_stepping(scheme: str, solver: str, colliders: Colliders | None, max_dt: float,
                   substeps: int, newton_tol: float, max_newton: int,
                   max_speed: float) -> tuple[LinearSolver, float, int, dict[str, float], float]:
    """Check the stepping parameters every elastic simulation takes.

    Returns
    -------
    tuple
        ``(LinearSolver, max_dt, substeps, {"newton_tol", "max_newton"}, max_speed)``.

    Raises
    ------
    ValueError, TypeError
        Naming the parameter and its valid range.
    """
    check_scheme(scheme)
    linear_solver = LinearSolver(solver)
    if colliders is not None and not isinstance(colliders, Colliders):
        raise TypeError(f"colliders must be a Colliders object, got {type(colliders).__name__}")
    max_dt = check_range("max_dt", max_dt, 0.0, math.inf, low_inclusive=False)
    substeps = check_int("substeps", substeps, 1)
    newton = dict(newton_tol=check_range("newton_tol", newton_tol, 0.0, math.inf,
                                         low_inclusive=False),
                  max_newton=check_int("max_newton", max_newton, 1))
    max_speed = check_range("max_speed", max_speed, 0.0, math.inf, low_inclusive=False)
    return linear_solver, max_dt, substeps, newton, max_speed

class MassSpringSimulation(Simulation):
    """Particles joined by damped springs, advanced by an explicit or implicit Euler scheme.

    Parameters
    ----------
    topology : SpringTopology
        From :mod:`filters.elastic.topology` (pins included).
    velocities : (N, 3) array_like, optional
        Initial velocities (m/s).
    stretch_stiffness : float
        Seed-form stiffness ``k`` (N) of stretch springs, >= 0: ``f = -k (l/L - 1) u``.
    shear_stiffness, bend_stiffness : float, optional
        Stiffness (N) of shear and bend springs; default ``stretch_stiffness`` and
        ``0.1 * stretch_stiffness``.  For a topology with ``bend_triples`` (hair),
        ``bend_stiffness`` is the bending rigidity (N m^2) instead.
    damping : float
        Spring damping coefficient (N s/m), >= 0.
    damping_mode : {"axial", "relative"}
        Spring damping model (see :mod:`filters.elastic.springs`).
    drag : float
        Per-particle drag ``-drag v`` (N s/m), >= 0.
    gravity : sequence of 3 float
        Acceleration (m/s^2).
    scheme : {"backward_euler", "linearized_backward_euler", "symplectic_euler", "euler"}
        Integrator (:mod:`filters.integrators`); ``"backward_euler"`` (solved by Newton's method
        with a line search) is the robust default.
    solver : {"auto", "pcg", "direct"}
        Linear solver of the implicit schemes.
    colliders : Colliders, optional
        Obstacles.
    max_dt : float
        Largest step (s) :meth:`advance_to` takes, > 0.
    substeps : int
        Integrator steps per step, >= 1 (explicit schemes need many).
    newton_tol : float
        Newton stopping tolerance on ``max |d| / h`` (m/s), > 0.
    max_newton : int
        Newton iteration limit, >= 1.
    max_speed : float
        Any particle faster than this (m/s) raises :class:`SimulationUnstableError`.
    contact_stiffness : float, optional
        One barrier stiffness (N/m) for every contact point, > 0; by default each point's is
        ``contact_ratio`` times its share of the diagonal of the implicit system matrix,
        ``m / (max_dt / substeps)^2`` plus its springs' stiffness
        (:class:`filters.elastic.contact_model.ContactModel`).
    contact_ratio : float
        Barrier stiffness over that diagonal, > 0.
    slip_velocity : float
        Slip velocity (m/s) below which friction holds (static friction creeps slower), > 0.
    bend_damping : float
        Damping time (s) of the bending of polylines (hair, :attr:`SpringTopology.bend_triples`),
        >= 0: each triple's damping is this times its bending stiffness (stiffness-proportional
        Rayleigh damping: a bending mode of angular frequency ``w`` gets the damping ratio
        ``bend_damping w / 2``).

    Contacts with ``colliders`` are solved inside every step of every scheme, with Coulomb
    friction (:mod:`filters.elastic.contact_model`, :mod:`filters.contact_solve`).  Contact
    points are the particles, or the embedded mesh's vertices when the topology has one
    (jello), so that what is drawn is what touches.
    """

    instability_hint = ("the spring forces are too stiff for this time step: use "
                        "scheme='backward_euler' or more substeps")

    def __init__(self, topology: SpringTopology, velocities: ArrayLike | None = None, *,
                 stretch_stiffness: float = 1e3, shear_stiffness: float | None = None,
                 bend_stiffness: float | None = None, damping: float = 0.0,
                 damping_mode: str = "axial", drag: float = 0.0,
                 gravity: ArrayLike = (0.0, 0.0, -9.81), scheme: str = "backward_euler",
                 solver: str = "auto", colliders: Colliders | None = None,
                 max_dt: float = 1.0 / 60.0, substeps: int = 1, newton_tol: float = 1e-3,
                 max_newton: int = 10, max_speed: float = 100.0,
                 contact_stiffness: float | None = None,
                 contact_ratio: float = DEFAULT_STIFFNESS_RATIO,
                 slip_velocity: float = DEFAULT_SLIP_VELOCITY, bend_damping: float = 0.0):
        if not isinstance(topology, SpringTopology):
            raise TypeError(f"topology must be a SpringTopology, got {type(topology).__name__}")
        k_stretch = check_range("stretch_stiffness", stretch_stiffness, 0.0)
        k_shear = k_stretch if shear_stiffness is None else check_range(
            "shear_stiffness", shear_stiffness, 0.0)
        k_bend = 0.1 * k_stretch if bend_stiffness is None else check_range(
            "bend_stiffness", bend_stiffness, 0.0)
        damping = check_range("damping", damping, 0.0)
        bend_damping = check_range("bend_damping", bend_damping, 0.0)
        check_range("contact_ratio", contact_ratio, 0.0, math.inf, low_inclusive=False)
        check_range("slip_velocity", slip_velocity, 0.0, math.inf, low_inclusive=False)
        if contact_stiffness is not None:
            check_range("contact_stiffness", contact_stiffness, 0.0, math.inf,
                        low_inclusive=False)
        check_choice("damping_mode", damping_mode, DAMPING_MODES)
        drag = check_range("drag", drag, 0.0)
        gravity = check_finite_vector("gravity", gravity, 3)
        (self.linear_solver, self.max_dt, substeps, self._newton,
         max_speed) = check_stepping(scheme, solver, colliders, max_dt, substeps, newton_tol,
                                     max_newton, max_speed)
        stiffness = _per_kind(topology.kinds, k_stretch, k_shear, k_bend)
        damp = np.full(topology.springs.shape[0], damping)
        for a in (stiffness, damp):
            a.setflags(write=False)
        self.model = MassSpringModel(topology, stiffness, damp, damping_mode, drag,
                                     tuple(gravity), scheme, solver, substeps, max_speed)
        bending = {}
        if topology.bend_triples is not None:
            bending = dict(bend_triples=topology.bend_triples,
                           bend_stiffness=k_bend * topology.bend_scale,
                           bend_damping=bend_damping * k_bend * topology.bend_scale)
        self.system = SpringSystem(topology.springs, topology.rest_lengths, stiffness,
                                   topology.masses, damping=damp, damping_mode=damping_mode,
                                   drag=drag, gravity=gravity, pinned=topology.pinned, **bending)
        self.colliders = colliders
        self.contact = None
        if colliders is not None:
            embedding = None
            if topology.embedding is not None:
                embedding = (topology.embedding.nodes, topology.embedding.weights)
            self.contact = ContactModel(colliders, topology.masses, self.max_dt / substeps,
                                        embedding=embedding, pinned=topology.pinned,
                                        stiffness_ratio=contact_ratio,
                                        stiffness=contact_stiffness,
                                        slip_velocity=slip_velocity,
                                        elastic_diagonal=self.system.elastic_diagonal())
        self.state = State(topology.positions, velocities)
        if self.contact is not None:
            self.contact.check_outside(self.state.positions)
        self.state.velocities[topology.pinned] = 0.0
        self.last_info = None

    # -- protocol ---------------------------------------------------------------------------
    @property
    def output_spec(self) -> OutputSpec:
        return OutputSpec(point_arrays=(("velocity", 3), ("id", 1)),
                          topology=self.model.topology.topology, fixed_topology=True)

    def frame(self) -> Frame:
        top = self.model.topology
        s = self.state
        if top.embedding is not None:
            points = top.embedding.points(s.positions)
            vel = top.embedding.points(s.velocities)
        else:
            points = s.positions.copy()
            vel = s.velocities.copy()
        return Frame(time=s.time, points=points,
                     point_data={"velocity": vel,
                                 "id": np.arange(points.shape[0], dtype=np.int64)},
                     connectivity=(top.offsets.copy(), top.indices.copy()),
                     field_data=self.energies().field_data())

    def _step(self, dt: float) -> None:
        m = self.model
        h = dt / m.substeps
        options = {}
        if m.scheme in ("backward_euler", "linearized_backward_euler"):
            options["solver"] = self.linear_solver
        if m.scheme == "backward_euler":
            options.update(self._newton)
        if self.contact is not None:
            options["contact"] = self.contact
        s = self.state
        for _ in range(m.substeps):
            self.last_info = integrate(self.system, s, h, m.scheme, **options)
            speed2 = np.einsum("ij,ij->i", s.velocities, s.velocities).max(initial=0.0)
            if not (speed2 <= m.max_speed ** 2):
                raise SimulationUnstableError(
                    s.time + dt, f"particle speed {math.sqrt(speed2):.3g} m/s > max_speed",
                    self.instability_hint)

    # -- diagnostics ------------------------------------------------------------------------
    @property
    def newton_options(self) -> dict:
        """The Newton options of the ``"backward_euler"`` steps: ``newton_tol`` (m/s) and
        ``max_newton`` (a copy)."""
        return dict(self._newton)

    def energies(self) -> EnergyAccount:
        """The energy account (J) of the current state: kinetic, gravitational, elastic and
        contact energies (:class:`filters.elastic.energy.EnergyAccount`)."""
        return energy_account(self.system, self.state.positions, self.state.velocities,
                              self.contact)

    def energy(self) -> float:
        """Total energy (J) of the current state: kinetic + gravitational + elastic + contact."""
        return self.energies().total

    def pin_forces(self) -> np.ndarray:
        """Forces (N) the springs exert on the pinned particles, (P, 3), in pin order."""
        f = self.system.forces(self.state.positions, np.zeros_like(self.state.velocities))
        f -= self.system.masses[:, None] * self.system.gravity[None, :]
        return f[self.system.pinned]


class HairSimulation(MassSpringSimulation):
    """Pinned strands (see :func:`filters.elastic.topology.hair_strands`); output lines.

    Parameters
    ----------
    roots : (R, 3) array_like
        Root positions (m), pinned.
    directions : (R, 3) or (3,) array_like
        Strand directions.
    segments, length, linear_density, cells, clamped
        As in :func:`filters.elastic.topology.hair_strands`.
    bend_stiffness : float
        Bending rigidity ``EI`` (N m^2) of a strand, >= 0 (the quadratic bending energy of
        :func:`filters.elastic.springs.bending_springs`).  A strand hangs straight over
        lengths beyond ``(EI / (linear_density g))^(1/3)``: 1e-6 N m^2 and 1 g/m give 4.7 cm.
    **options
        Passed to :class:`MassSpringSimulation` (``bend_damping`` damps the bending).
    """

    def __init__(self, roots: ArrayLike, directions: ArrayLike, *, segments: int = 16,
                 length: float = 0.3, linear_density: float = 1e-3, cells: str = "polylines",
                 clamped: bool = False, bend_stiffness: float = 1e-6, **options: Any):
        top = hair_strands(roots, directions, segments=segments, length=length,
                           linear_density=linear_density, cells=cells, clamped=clamped)
        bend_stiffness = check_range("bend_stiffness", bend_stiffness, 0.0)
        super().__init__(top, bend_stiffness=bend_stiffness, **options)


class ClothSimulation(MassSpringSimulation):
    """Cloth from a triangle mesh (see :func:`filters.elastic.topology.cloth_from_mesh`); output
    triangles.

    Parameters
    ----------
    points : (N, 3) array_like
        Vertices (m).
    triangles : (T, 3) int array_like
        Triangles.
    pinned : array_like of int or (N,) bool, optional
        Vertices held fixed.
    areal_density : float
        Mass per area (kg/m^2).
    **options
        Passed to :class:`MassSpringSimulation`.
    """

    def __init__(self, points: ArrayLike, triangles: ArrayLike, *, pinned: ArrayLike | None = None,
                 areal_density: float = 0.2, **options: Any):
        top = cloth_from_mesh(points, triangles, areal_density=areal_density)
        if pinned is not None:
            top = top.with_pins(pinned)
        super().__init__(top, **options)

    @classmethod
    def grid(cls, nx: int, ny: int, *, size: ArrayLike = (1.0, 1.0),
             origin: ArrayLike = (0.0, 0.0, 0.0), plane: str = "xy",
             pinned: ArrayLike | None = None, areal_density: float = 0.2,
             **options: Any) -> ClothSimulation:
        """A rectangular cloth with structural, shear and bend springs
        (see :func:`filters.elastic.topology.cloth_grid`); particle ``i + nx * j``."""
        top = cloth_grid(nx, ny, size=size, origin=origin, plane=plane,
                         areal_density=areal_density)
        if pinned is not None:
            top = top.with_pins(pinned)
        self = cls.__new__(cls)
        MassSpringSimulation.__init__(self, top, **options)
        return self


class JelloSimulation(MassSpringSimulation):
    """A jello: the interior of a closed mesh as a spring lattice; output the mesh, deformed.

    Parameters
    ----------
    points : (M, 3) array_like
        Vertices (m) of a closed, consistently oriented triangle mesh.
    triangles : (T, 3) int array_like
        Its triangles.
    spacing : float
        Lattice spacing (m).
    density : float
        Mass density (kg/m^3).
    **options
        Passed to :class:`MassSpringSimulation` (``shear_stiffness`` applies to face and body
        diagonals; the default bend stiffness is unused: the lattice has no bend springs).
    """

    def __init__(self, points: ArrayLike, triangles: ArrayLike, *, spacing: float,
                 density: float = 1000.0, **options: Any):
        top = jello_from_mesh(points, triangles, spacing=spacing, density=density)
        super().__init__(top, **options)

    def mesh_points(self) -> np.ndarray:
        """The embedded mesh's vertices (M, 3) (m) for the current state."""
        return self.model.topology.embedding.points(self.state.positions)
