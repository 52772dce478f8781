"""``jello_drop``: a jello shape falls, bounces and wobbles on the floor; the output is its mesh."""

from __future__ import annotations

from filters.elastic.contact import Colliders
from filters.elastic.mass_spring import JelloSimulation
from filters.elastic.topology import icosphere
from filters.geometry import Plane
from filters.validation import check_range
from pipeline import Flow, SimulationSource
from pipeline.embedding import read_closed_mesh
from pipeline.scene import Scene

SCENE_FPS = 30.0
SCENE_DURATION = 2.0


def build(*, mesh: str = "", radius: float = 0.15, height: float = 0.4, spacing: float = 0.04,
          stiffness: float = 60.0, damping: float = 10.0, density: float = 1000.0,
          friction: float = 0.5, velocity: tuple = (0.0, 0.0, 0.0),
          max_dt: float = 1.0 / 240.0) -> Flow:
    """Drop a jello: the interior of a closed mesh as a spring lattice, the mesh embedded in it.

    The mesh's vertices are the contact points with the floor (a 1 mm barrier with friction),
    so the drawn surface is what touches.  The defaults squash the ball by about a quarter of
    its height on impact; it hops, lands and wobbles at about 4 Hz, and rests on the floor with
    its volume within 1 % (a spring lattice keeps volume only approximately: a softer one sags
    more and loses more).

    Parameters
    ----------
    mesh : str
        Path of a closed surface mesh readable by PyVista (any format); empty for an icosphere
        of ``radius``.  It is translated so that its lowest point is at ``height``.
    radius : float
        Radius of the default icosphere (m), > 0.
    height : float
        Initial height of the mesh's lowest point above the floor (m), >= 0.
    spacing : float
        Lattice spacing (m), > 0.
    stiffness : float
        Seed-form stiffness ``k`` (N) of the lattice springs, > 0.
    damping : float
        Axial spring damping (N s/m), >= 0.
    density : float
        Mass density (kg/m^3), > 0.
    friction : float
        Coulomb friction coefficient of the floor, >= 0.
    velocity : vector
        Initial velocity (m/s).
    max_dt : float
        Largest time step (s), > 0; small steps keep the wobble (backward Euler damps
        oscillations faster than the step).
    """
    import numpy as np

    if mesh:
        points, triangles = read_closed_mesh(mesh)
    else:
        points, triangles = icosphere(check_range("radius", radius, 0.0, low_inclusive=False), 3)
    height = check_range("height", height, 0.0)
    points = points - [0.0, 0.0, points[:, 2].min() - height]
    ground = Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    floor = Colliders(friction=friction).add(ground)
    sim = JelloSimulation(points, triangles, spacing=spacing, density=density,
                          stretch_stiffness=stiffness, damping=damping, colliders=floor,
                          max_dt=max_dt)
    sim.state.velocities[:] = np.asarray(velocity, dtype=np.float64)
    flow = Flow(SimulationSource(sim, fps=SCENE_FPS, duration=SCENE_DURATION), name="jello",
                xdmf=True)
    flow.add_collider("floor", ground, role="floor")
    return flow


# its still: the jello squashed on the floor at its first landing (the most energetic frame is
# the jello in the air just before it)
SCENE = Scene("jello_drop", build, "a jello mesh dropped on the floor (embedded spring lattice)",
              fps=SCENE_FPS, duration=SCENE_DURATION, still=1.0 / 3.0)
