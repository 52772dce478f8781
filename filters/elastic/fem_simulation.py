"""Finite-element solids: a tetrahedral mesh, a material, and the elastic simulations' step.

:class:`FEMSimulation` couples a :class:`filters.elastic.tetmesh.TetMesh` with a
:class:`filters.elastic.fem.FEMSystem` and is advanced exactly like the mass-spring
simulations (:class:`filters.elastic.mass_spring.MassSpringSimulation`, whose step it
inherits): one of the schemes of :mod:`filters.integrators` (backward Euler by Newton with a
line search on the incremental potential by default), the colliders' barrier contacts, lagged
Coulomb friction and normal damping inside every step
(:class:`filters.elastic.contact_model.ContactModel`, the embedded surface's vertices as the
contact points, as for the spring jello), the same energy account and the same instability
check.  Its frames are the tetrahedra (a VTK unstructured grid with the strain energy density
per cell, the energy account as field data); the user's embedded surface follows from the
nodes with the mesh's barycentric weights (:meth:`FEMSimulation.mesh_points`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..simulation import Frame, OutputSpec, State
from ..validation import check_finite_vector, check_range
from .contact_model import DEFAULT_SLIP_VELOCITY, DEFAULT_STIFFNESS_RATIO, ContactModel
from .fem import FEMSystem, tet_geometry
from .mass_spring import MassSpringSimulation, check_stepping
from .materials import material_parameters
from .tetmesh import TetMesh, tets_from_arrays, tets_from_mesh

if TYPE_CHECKING:
    from typing import Any

    from numpy.typing import ArrayLike

    from .contact import Colliders

__all__ = ["FEMModel", "FEMSimulation", "lumped_masses", "VTK_TETRA"]

#: VTK's cell type of a linear tetrahedron.
VTK_TETRA = 10


def lumped_masses(mesh: TetMesh, density: float) -> np.ndarray:
    """Lumped node masses (kg), (N,): a quarter of every tetrahedron's mass ``density phi W``
    (``phi`` its volume fraction, :attr:`TetMesh.fractions`) to each of its nodes, scaled so
    that the total is ``density * mesh.volume`` (the embedded surface's volume, which the
    fractions add up to, to their floor)."""
    density = check_range("density", density, 0.0, math.inf, low_inclusive=False)
    _, volumes = tet_geometry(mesh.positions, mesh.tets)
    if mesh.fractions is not None:
        volumes = volumes * mesh.fractions
    masses = np.bincount(mesh.tets.ravel(), weights=np.repeat(volumes / 4.0, 4),
                         minlength=mesh.positions.shape[0])
    if np.any(masses <= 0.0):
        raise ValueError("every node must belong to a tetrahedron (found unused nodes)")
    return masses * (density * mesh.volume / volumes.sum())


@dataclass(frozen=True)
class FEMModel:
    """Fixed parameters of a :class:`FEMSimulation`.

    Attributes
    ----------
    mesh : TetMesh
        Nodes, tetrahedra and the embedded surface.
    material : str
        ``"neo_hookean"`` or ``"corotated"``.
    youngs_modulus : float
        ``E`` (Pa).
    poisson_ratio : float
        ``nu``.
    density : float
        Mass density (kg/m^3).
    mass_damping, stiffness_damping : float
        Rayleigh ``alpha`` (1/s) and ``beta`` (s).
    gravity : tuple of 3 float
        Acceleration (m/s^2).
    scheme : str
        Integrator (one of :data:`filters.integrators.SCHEMES`).
    solver : str
        Linear solver of the implicit schemes.
    substeps : int
        Integrator steps per :meth:`Simulation.step`.
    max_speed : float
        Speed (m/s) above which the simulation is declared unstable.
    """

    mesh: TetMesh
    material: str
    youngs_modulus: float
    poisson_ratio: float
    density: float
    mass_damping: float
    stiffness_damping: float
    gravity: tuple
    scheme: str
    solver: str
    substeps: int
    max_speed: float


class FEMSimulation(MassSpringSimulation):
    """A finite-element solid of linear tetrahedra, advanced like the mass-spring simulations.

    Parameters
    ----------
    mesh : TetMesh
        From :func:`filters.elastic.tetmesh.tets_from_mesh` or
        :func:`~filters.elastic.tetmesh.box_tets`; its rest positions are the initial ones.
    velocities : (N, 3) array_like, optional
        Initial node velocities (m/s).
    youngs_modulus : float
        ``E`` (Pa), > 0.
    poisson_ratio : float
        ``nu``, in [0, 0.5); near 0.5 the solid keeps its volume.
    density : float
        Mass density (kg/m^3), > 0 (masses lumped, :func:`lumped_masses`).
    material : {"neo_hookean", "corotated"}
        Stable Neo-Hookean (Smith et al. 2018) or corotational linear (Müller & Gross 2004).
    mass_damping, stiffness_damping : float
        Rayleigh damping ``alpha`` (1/s) and ``beta`` (s), >= 0.
    gravity : sequence of 3 float
        Acceleration (m/s^2).
    pinned : array_like of int or (N,) bool, optional
        Nodes held fixed.
    scheme : {"backward_euler", "linearized_backward_euler", "symplectic_euler", "euler"}
        Integrator (:mod:`filters.integrators`).
    solver : {"auto", "pcg", "direct"}
        Linear solver of the implicit schemes.
    colliders : Colliders, optional
        Obstacles: barrier contacts, friction and normal damping inside every step of every
        scheme, as for the springs; the contact points are the embedded surface's vertices
        (the nodes for a mesh without one), so that what is drawn is what touches.
    max_dt : float
        Largest step (s) :meth:`advance_to` takes, > 0.
    substeps : int
        Integrator steps per step, >= 1.
    newton_tol : float
        Newton stopping tolerance on ``max |d| / h`` (m/s), > 0.
    max_newton : int
        Newton iteration limit, >= 1.
    max_speed : float
        Any node faster than this (m/s) raises :class:`SimulationUnstableError`.
    contact_stiffness : float, optional
        One barrier stiffness (N/m) for every contact point, > 0; by default each point's is
        ``contact_ratio`` times its share of ``m / (max_dt / substeps)^2`` plus the nodes'
        elastic stiffness (:meth:`filters.elastic.fem.FEMSystem.elastic_diagonal`).
    contact_ratio : float
        Barrier stiffness over that diagonal, > 0.
    slip_velocity : float
        Slip velocity (m/s) below which friction holds (static friction creeps slower), > 0.
    """

    instability_hint = ("the elements are too stiff for this time step: use "
                        "scheme='backward_euler' or more substeps")

    def __init__(self, mesh: TetMesh, velocities: ArrayLike | None = None, *,
                 youngs_modulus: float = 1e4, poisson_ratio: float = 0.45, density: float = 1000.0,
                 material: str = "neo_hookean", mass_damping: float = 0.0,
                 stiffness_damping: float = 0.0, gravity: ArrayLike = (0.0, 0.0, -9.81),
                 pinned: ArrayLike | None = None, scheme: str = "backward_euler",
                 solver: str = "auto", colliders: Colliders | None = None,
                 max_dt: float = 1.0 / 60.0, substeps: int = 1, newton_tol: float = 1e-3,
                 max_newton: int = 10, max_speed: float = 100.0,
                 contact_stiffness: float | None = None,
                 contact_ratio: float = DEFAULT_STIFFNESS_RATIO,
                 slip_velocity: float = DEFAULT_SLIP_VELOCITY):
        if not isinstance(mesh, TetMesh):
            raise TypeError(f"mesh must be a TetMesh, got {type(mesh).__name__}")
        material_parameters(material, youngs_modulus, poisson_ratio)  # validates all three
        density = check_range("density", density, 0.0, math.inf, low_inclusive=False)
        mass_damping = check_range("mass_damping", mass_damping, 0.0)
        stiffness_damping = check_range("stiffness_damping", stiffness_damping, 0.0)
        gravity = check_finite_vector("gravity", gravity, 3)
        (self.linear_solver, self.max_dt, substeps, self._newton,
         max_speed) = check_stepping(scheme, solver, colliders, max_dt, substeps, newton_tol,
                                     max_newton, max_speed)
        check_range("contact_ratio", contact_ratio, 0.0, math.inf, low_inclusive=False)
        check_range("slip_velocity", slip_velocity, 0.0, math.inf, low_inclusive=False)
        if contact_stiffness is not None:
            check_range("contact_stiffness", contact_stiffness, 0.0, math.inf,
                        low_inclusive=False)
        n = mesh.positions.shape[0]
        mask = np.zeros(n, dtype=bool)
        if pinned is not None:
            p = np.asarray(pinned)
            if p.dtype == bool:
                if p.shape != (n,):
                    raise ValueError(f"pinned mask must have shape ({n},), got {p.shape}")
                mask |= p
            else:
                idx = p.astype(np.int64).ravel()
                if idx.size and (idx.min() < 0 or idx.max() >= n):
                    raise ValueError(f"pinned indices must be in [0, {n - 1}]")
                mask[idx] = True
        self.model = FEMModel(mesh, material, float(youngs_modulus), float(poisson_ratio),
                              density, mass_damping, stiffness_damping, tuple(gravity), scheme,
                              solver, substeps, max_speed)
        masses = lumped_masses(mesh, density)
        self.system = FEMSystem(mesh.positions, mesh.tets, masses,
                                youngs_modulus=youngs_modulus, poisson_ratio=poisson_ratio,
                                material=material, mass_damping=mass_damping,
                                stiffness_damping=stiffness_damping, gravity=gravity,
                                pinned=mask, fractions=mesh.fractions)
        self.colliders = colliders
        self.contact = None
        if colliders is not None:
            emb = mesh.embedding
            self.contact = ContactModel(
                colliders, masses, self.max_dt / substeps,
                embedding=None if emb is None else (emb.nodes, emb.weights), pinned=mask,
                stiffness_ratio=contact_ratio, stiffness=contact_stiffness,
                slip_velocity=slip_velocity, elastic_diagonal=self.system.elastic_diagonal())
        self.state = State(mesh.positions, velocities)
        if self.contact is not None:
            self.contact.check_outside(self.state.positions)
        self.state.velocities[mask] = 0.0
        self.last_info = None

    @classmethod
    def from_mesh(cls, points: ArrayLike, triangles: ArrayLike, *, spacing: float,
                  **options: Any) -> FEMSimulation:
        """A solid of the interior of a closed triangle mesh, tetrahedralised on a lattice of
        ``spacing`` (m) with the mesh embedded (:func:`filters.elastic.tetmesh.tets_from_mesh`);
        ``options`` as for the class."""
        return cls(tets_from_mesh(points, triangles, spacing=spacing), **options)

    @classmethod
    def from_tets(cls, points: ArrayLike, tets: ArrayLike, *, name: str = "mesh",
                  **options: Any) -> FEMSimulation:
        """A solid of a user's own tetrahedral mesh, as it is (:func:`filters.elastic.tetmesh.
        tets_from_arrays`: checked for flat, inverted elements and several bodies); its
        boundary faces are the surface that is drawn and touches colliders; ``options`` as for
        the class."""
        return cls(tets_from_arrays(points, tets, name=name), **options)

    # -- protocol ---------------------------------------------------------------------------
    @property
    def output_spec(self) -> OutputSpec:
        return OutputSpec(point_arrays=(("velocity", 3), ("id", 1)), topology="cells",
                          fixed_topology=True, cell_arrays=(("strain_energy_density", 1),
                                                            ("volume_fraction", 1)))

    def frame(self) -> Frame:
        """The tetrahedra at the current state: node positions, ``velocity`` and ``id`` per
        node, ``strain_energy_density`` (J/m^3) and ``volume_fraction`` (the part of it the
        solid fills) per tetrahedron, the energy account
        (:meth:`energies`) as field data."""
        s = self.state
        tets = self.model.mesh.tets
        offsets = np.arange(0, 4 * tets.shape[0] + 1, 4, dtype=np.int64)
        return Frame(time=s.time, points=s.positions.copy(),
                     point_data={"velocity": s.velocities.copy(),
                                 "id": np.arange(s.n_points, dtype=np.int64)},
                     connectivity=(offsets, tets.ravel().copy()),
                     cell_types=np.full(tets.shape[0], VTK_TETRA, dtype=np.uint8),
                     cell_data={"strain_energy_density":
                                self.system.energy_density(s.positions),
                                "volume_fraction": self.system.fractions.copy()},
                     field_data=self.energies().field_data())

    # -- diagnostics ------------------------------------------------------------------------
    def mesh_points(self) -> np.ndarray:
        """The embedded surface's vertices (M, 3) (m) for the current state."""
        emb = self.model.mesh.embedding
        if emb is None:
            raise ValueError("this mesh has no embedded surface (built by box_tets?)")
        return emb.points(self.state.positions)

    def volume(self) -> float:
        """Volume (m^3) of the solid in the current state (the tetrahedra's, each times its
        volume fraction)."""
        return self.system.volume(self.state.positions)
