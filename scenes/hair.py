"""``hair``: strands rooted on a head fall, drape over it and come to rest."""

from __future__ import annotations

import numpy as np

from filters.elastic.contact import Colliders
from filters.elastic.mass_spring import HairSimulation
from filters.geometry import Sphere
from filters.validation import check_int, check_range
from pipeline import Flow, SimulationSource
from pipeline.scene import Scene

SCENE_FPS = 30.0
SCENE_DURATION = 3.0


def build(*, strands: int = 200, segments: int = 16, length: float = 0.3,
          head_radius: float = 0.1, stiffness: float = 50.0, bend: float = 3e-6,
          damping: float = 0.002, bend_damping: float = 2e-3, air_drag: float = 4.0,
          friction: float = 0.3, linear_density: float = 1e-3, seed: int = 0,
          max_dt: float = 1.0 / 60.0) -> Flow:
    """Strands rooted on the upper half of a spherical head fall, drape over it and hang.

    Each strand is a chain of particles with stretch springs, a quadratic bending energy
    (Bergou et al. 2006; a bending rigidity, so its shape does not depend on ``segments``) and
    a clamped root: its first two particles are held, so that it leaves the scalp in its
    growth direction (outwards, combed down) as a follicle holds a hair.  The head is a sphere
    collider with friction (no segment enters it); air drag and internal (stretch and bending)
    damping bring the strands to rest.  Backward Euler by Newton with contacts in the solve.
    Output ``hair``: line segments.

    Parameters
    ----------
    strands : int
        Number of strands (1 to 100000).
    segments : int
        Springs per strand (2 to 256).
    length : float
        Strand length (m), > 0.
    head_radius : float
        Radius of the head (m), > 0.
    stiffness : float
        Seed-form stretch stiffness ``k`` (N), > 0.
    bend : float
        Bending rigidity ``EI`` of a strand (N m^2), >= 0; the strands bend under their weight
        over ``(EI / (linear_density g))^(1/3)`` (6.7 cm by default).
    damping : float
        Axial damping of the stretch springs (N s/m), >= 0.
    bend_damping : float
        Damping time of the bending (s), >= 0: its damping force is this times the rate of the
        bending force (stiffness-proportional, Rayleigh damping).
    air_drag : float
        Air drag per unit mass (1/s), >= 0 (a hair in air: about 4 1/s).
    friction : float
        Coulomb friction coefficient of the head, >= 0.
    linear_density : float
        Mass per length of a strand (kg/m), > 0.
    seed : int
        Seed of the random root positions.
    max_dt : float
        Largest time step (s), > 0.
    """
    strands = check_int("strands", strands, 1, 100_000)
    segments = check_int("segments", segments, 2, 256)
    length = check_range("length", length, 0.0, low_inclusive=False)
    head_radius = check_range("head_radius", head_radius, 0.0, low_inclusive=False)
    air_drag = check_range("air_drag", air_drag, 0.0)
    linear_density = check_range("linear_density", linear_density, 0.0, low_inclusive=False)
    rng = np.random.default_rng(seed)
    normal = rng.normal(size=(strands, 3))
    normal[:, 2] = np.abs(normal[:, 2]) + 0.2  # upper half
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    # combed down: each strand leaves the scalp 22 degrees above its downhill tangent (backwards
    # on top of the head)
    down = np.array([0.0, 0.0, -1.0]) - normal[:, 2:3] * -normal
    flat = np.linalg.norm(down, axis=1) < 0.2
    down[flat] = np.array([-1.0, 0.0, 0.0]) - normal[flat, 0:1] * -normal[flat]
    down /= np.linalg.norm(down, axis=1, keepdims=True)
    grow = 0.4 * normal + down
    grow /= np.linalg.norm(grow, axis=1, keepdims=True)
    center = np.array([0.0, 0.0, 1.5])
    roots = center + head_radius * normal
    # strands are kept 2 mm off the scalp (the barrier's reach): no segment enters the head
    head = Sphere(center, head_radius)
    colliders = Colliders(friction=friction, thickness=0.002).add(head)
    segment_mass = linear_density * length / segments
    sim = HairSimulation(roots, grow, segments=segments, length=length,
                         linear_density=linear_density, clamped=True,
                         stretch_stiffness=stiffness, bend_stiffness=bend, damping=damping,
                         bend_damping=bend_damping, drag=air_drag * segment_mass,
                         colliders=colliders, max_dt=max_dt, newton_tol=1e-2, cells="segments")
    flow = Flow(SimulationSource(sim, fps=SCENE_FPS, duration=SCENE_DURATION), name="hair",
                xdmf=True)
    flow.add_collider("head", head)
    return flow


# its still: the hair at rest, draped over the head
SCENE = Scene("hair", build, "hair strands rooted on a head, draping and coming to rest",
              fps=SCENE_FPS, duration=SCENE_DURATION, still=SCENE_DURATION)
