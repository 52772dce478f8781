"""``hair``: strands pinned on a head swing down under gravity."""

from __future__ import annotations

import numpy as np

from filters.elastic.contact import Colliders
from filters.geometry import Sphere
from filters.elastic.mass_spring import HairSimulation
from filters.validation import check_int, check_range
from pipeline import Flow, SimulationSource
from pipeline.scene import Scene

SCENE_FPS = 30.0
SCENE_DURATION = 3.0


def build(*, strands: int = 200, segments: int = 16, length: float = 0.3,
          head_radius: float = 0.1, stiffness: float = 50.0, bend: float = 5.0,
          damping: float = 0.002, seed: int = 0, max_dt: float = 1.0 / 60.0) -> Flow:
    """Strands rooted on the upper half of a spherical head, growing outwards, falling and swinging.

    Each strand is a chain of particles with stretch springs ``i, i+1`` and bend springs
    ``i, i+2``, its root pinned; the head is a sphere collider.  Output ``hair``: polylines.

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
        Seed-form bend-spring stiffness (N), >= 0.
    damping : float
        Axial spring damping (N s/m), >= 0.
    seed : int
        Seed of the random root positions.
    max_dt : float
        Largest time step (s), > 0.
    """
    strands = check_int("strands", strands, 1, 100_000)
    head_radius = check_range("head_radius", head_radius, 0.0, low_inclusive=False)
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(strands, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.2  # upper half
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    center = np.array([0.0, 0.0, 1.5])
    roots = center + head_radius * d
    head = Sphere(center, head_radius * 0.98)  # just inside the roots
    colliders = Colliders(friction=0.3, thickness=0.002).add(head)
    sim = HairSimulation(roots, d, segments=segments, length=length,
                         stretch_stiffness=stiffness, bend_stiffness=bend, damping=damping,
                         colliders=colliders, max_dt=max_dt, cells="segments")
    flow = Flow(SimulationSource(sim, fps=SCENE_FPS, duration=SCENE_DURATION), name="hair",
                xdmf=True)
    flow.add_collider("head", head)
    return flow


SCENE = Scene("hair", build, "pinned hair strands swinging on a head (mass-spring chains)",
              fps=SCENE_FPS, duration=SCENE_DURATION)
