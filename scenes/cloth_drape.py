"""``cloth_drape``: a square cloth falls onto a sphere and drapes over it down to the floor."""

from __future__ import annotations

from filters.elastic.contact import Colliders
from filters.elastic.mass_spring import ClothSimulation
from filters.geometry import Plane, Sphere
from filters.validation import check_int, check_range
from pipeline import Flow, SimulationSource
from pipeline.scene import Scene

SCENE_FPS = 30.0
SCENE_DURATION = 3.0


def build(*, resolution: int = 32, size: float = 1.0, height: float = 0.7,
          sphere_radius: float = 0.25, stiffness: float = 200.0, bend: float = 0.5,
          damping: float = 0.02, friction: float = 0.5, areal_density: float = 0.2,
          solver: str = "auto", max_dt: float = 1.0 / 60.0) -> Flow:
    """A horizontal ``resolution`` x ``resolution`` cloth dropped onto a sphere on the floor.

    Backward Euler by Newton with line search (Gast et al. 2015); the sphere and the floor are
    contacts inside the implicit solve (a barrier 5 mm thick, Li et al. 2020) with Coulomb
    friction, which holds the cloth on the sphere: it drapes over it, its corners on the floor,
    and comes to rest.  The output ``cloth`` is the triangle mesh (fixed topology), written as
    a PVD series and as XDMF, with the energy account as field data.

    Parameters
    ----------
    resolution : int
        Particles per side (4 to 256).
    size : float
        Side length of the cloth (m), > 0.
    height : float
        Initial height of the cloth above the floor (m), > 2 * sphere_radius.
    sphere_radius : float
        Radius of the sphere resting on the floor under the cloth's centre (m), > 0.
    stiffness : float
        Seed-form stretch and shear stiffness ``k`` (N), > 0.
    bend : float
        Seed-form bend-spring stiffness (N), >= 0.
    damping : float
        Axial spring damping (N s/m), >= 0.
    friction : float
        Coulomb friction coefficient of the sphere and floor, >= 0.
    areal_density : float
        Mass per area of the cloth (kg/m^2), > 0.
    solver : str
        Linear solver: ``auto``, ``pcg`` or ``direct``.
    max_dt : float
        Largest time step (s), > 0.
    """
    resolution = check_int("resolution", resolution, 4, 256)
    size = check_range("size", size, 0.0, low_inclusive=False)
    sphere_radius = check_range("sphere_radius", sphere_radius, 0.0, low_inclusive=False)
    height = check_range("height", height, 2.0 * sphere_radius, low_inclusive=False)
    floor = Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    ball = Sphere((0.0, 0.0, sphere_radius), sphere_radius)
    colliders = Colliders(friction=friction, thickness=0.005).add(floor).add(ball)
    sim = ClothSimulation.grid(resolution, resolution, size=(size, size),
                               origin=(-size / 2, -size / 2, height), plane="xy",
                               areal_density=areal_density, stretch_stiffness=stiffness,
                               bend_stiffness=bend, damping=damping, colliders=colliders,
                               solver=solver, max_dt=max_dt, newton_tol=1e-2)
    flow = Flow(SimulationSource(sim, fps=SCENE_FPS, duration=SCENE_DURATION), name="cloth",
                xdmf=True)
    flow.add_collider("floor", floor, role="floor", size=4.0 * size)
    flow.add_collider("sphere", ball)
    return flow


# its still: the cloth draped over the sphere (the most energetic frame is the flat cloth just
# before it lands)
SCENE = Scene("cloth_drape", build, "mass-spring cloth draping over a sphere (implicit Newton)",
              fps=SCENE_FPS, duration=SCENE_DURATION, still=1.0)
