"""``jello_fem``: the jello drop as a finite-element solid; outputs its tetrahedra and its mesh."""

from __future__ import annotations

from filters.elastic.contact import Colliders
from filters.elastic.fem_simulation import FEMSimulation
from filters.elastic.materials import MATERIALS
from filters.elastic.topology import icosphere
from filters.geometry import Plane
from filters.validation import check_choice, check_range
from pipeline import Flow, SimulationSource
from pipeline.embedding import EmbeddedSurface, read_closed_mesh
from pipeline.io.volume_mesh import read_volume_mesh
from pipeline.scene import Scene

SCENE_FPS = 30.0
SCENE_DURATION = 2.0


def build(*, mesh: str = "", radius: float = 0.15, height: float = 0.4, spacing: float = 0.04,
          material: str = "neo_hookean", youngs_modulus: float = 5e4,
          poisson_ratio: float = 0.45, density: float = 1000.0, damping: float = 0.002,
          friction: float = 0.5, velocity: tuple = (0.0, 0.0, 0.0),
          max_dt: float = 1.0 / 240.0) -> Flow:
    """Drop a jello made of finite elements: the interior of a closed mesh cut into tetrahedra.

    The same drop as ``jello_drop``; the springs are replaced by linear tetrahedra of a
    hyperelastic material given by Young's modulus and Poisson's ratio, integrated by backward
    Euler (Newton, line search) with the same floor contact as ``jello_drop``: the mesh's
    vertices touch the floor through a 1 mm barrier with Coulomb friction and critical normal
    damping, inside every step, so the energy account written with every frame (field data)
    never rises.  Outputs:
    ``tets``, the tetrahedra (VTU) with ``strain_energy_density`` (J/m^3) per cell, and
    ``jello``, the user's mesh embedded in them (VTP, and XDMF).

    Parameters
    ----------
    mesh : str
        Path of a closed surface mesh readable by PyVista (any format), cut into tetrahedra on
        a lattice of ``spacing``; or of a volume mesh of linear tetrahedra (Gmsh ``.msh``,
        Medit ``.mesh``, Abaqus ``.inp``, VTU, ... read through meshio), simulated as it is,
        its boundary faces drawn and touching the floor; empty for an icosphere of
        ``radius``.  It is translated so that its lowest point is at ``height``.
    radius : float
        Radius of the default icosphere (m), > 0.
    height : float
        Initial height of the mesh's lowest point above the floor (m), >= 0.
    spacing : float
        Edge of the lattice cells cut into six tetrahedra each (m), > 0 (unused for a volume
        mesh).
    material : str
        ``neo_hookean`` (Smith, de Goes & Kim 2018) or ``corotated`` (Müller & Gross 2004).
    youngs_modulus : float
        Young's modulus E (Pa), > 0.
    poisson_ratio : float
        Poisson's ratio nu, in [0, 0.5); 0.45 keeps the volume within a fraction of a percent.
    density : float
        Mass density (kg/m^3), > 0.
    damping : float
        Rayleigh stiffness damping beta (s), >= 0.
    friction : float
        Coulomb friction coefficient of the floor, >= 0.
    velocity : vector
        Initial velocity (m/s).
    max_dt : float
        Largest time step (s), > 0.
    """
    import numpy as np

    volume = read_volume_mesh(mesh) if mesh else None
    if volume is not None:
        points, tets = volume
    elif mesh:
        points, triangles = read_closed_mesh(mesh)
    else:
        points, triangles = icosphere(check_range("radius", radius, 0.0, low_inclusive=False), 3)
    check_choice("material", material, MATERIALS)
    height = check_range("height", height, 0.0)
    points = points - [0.0, 0.0, points[:, 2].min() - height]
    ground = Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    floor = Colliders(friction=friction).add(ground)
    options = dict(material=material, youngs_modulus=youngs_modulus,
                   poisson_ratio=poisson_ratio, density=density, stiffness_damping=damping,
                   colliders=floor, max_dt=max_dt)
    if volume is not None:
        sim = FEMSimulation.from_tets(points, tets, name="mesh", **options)
    else:
        sim = FEMSimulation.from_mesh(points, triangles, spacing=spacing, **options)
    sim.state.velocities[:] = np.asarray(velocity, dtype=np.float64)
    # the renders draw the embedded mesh; the tetrahedra are on disk for ParaView
    flow = Flow(SimulationSource(sim, fps=SCENE_FPS, duration=SCENE_DURATION), name="tets",
                draw=False)
    flow.add("jello", EmbeddedSurface(sim.model.mesh.embedding), xdmf=True)
    flow.add_collider("floor", ground, role="floor")
    return flow


# its still: the jello squashed on the floor at its first landing, as jello_drop's
SCENE = Scene("jello_fem", build, "the jello drop with finite elements (tetrahedra, "
              "Neo-Hookean or corotated)", fps=SCENE_FPS, duration=SCENE_DURATION,
              still=1.0 / 3.0)
