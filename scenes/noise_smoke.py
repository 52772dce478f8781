"""``noise_smoke``: particles rising from an emitter through curl noise around a ball.

Smoke-like particles are emitted in a thin box on the floor, carried up by a uniform rising flow
plus divergence-free curl noise (Bridson, Hourihan & Nordenstam 2007) whose potential is ramped
near a ball so that the flow, rising wind included, goes around it.  Written as points
(``particles.pvd``: velocity, id, age, size, color), which the renderer draws as soft
translucent sprites fading with age; ``surface=true`` also writes a metaball surface
(``surface.pvd``) splatted with each particle's own radius (``size``, from noise).
"""

from __future__ import annotations

import math

from filters.advect import BoxEmitter, NoiseAdvection, check_integrator
from filters.fields import CurlNoise
from filters.geometry import Plane, Sphere
from filters.memory import check_memory
from filters.validation import check_int, check_range
from pipeline import Flow, SimulationSource
from pipeline.scene import Scene

SCENE_FPS = 30.0
SCENE_DURATION = 3.0


def build(*, rate: float = 3000.0, lifetime: float = 2.0, rise: float = 0.6,
          amplitude: float = 0.4, frequency: float = 2.5, octaves: int = 2,
          time_scale: float = 0.5, ball_radius: float = 0.15, ball_height: float = 0.6,
          radius: float = 0.02, surface: bool = False, integrator: str = "rk4",
          max_particles: int = 20000, seed: int = 0) -> Flow:
    """Build the noise-smoke flow.

    Parameters
    ----------
    rate : float
        Particles emitted per second (> 0, finite).
    lifetime : float
        Mean particle lifetime (s), > 0 and finite (+-25 % jitter).
    rise : float
        Speed of the uniform rising flow (m/s).
    amplitude : float
        Curl-noise velocity scale (m/s), >= 0.
    frequency : float
        Curl-noise lattice cells per metre, > 0 (eddies about 1/frequency m across).
    octaves : int
        Octaves of the noise potentials (1 to 16).
    time_scale : float
        Drift of the noise (lattice cells per second); 0 freezes the flow.
    ball_radius : float
        Radius of the ball the smoke flows around (m); 0 removes it.
    ball_height : float
        Height of the ball's centre above the floor (m).
    radius : float
        Largest particle radius for the metaball surface (m), > 0; particles get 0.5 to 1 times
        this from noise.
    surface : bool
        Also write a metaball surface of the particles (``surface.pvd``; smoke is drawn from
        the particles, not from this surface).
    integrator : str
        One of euler, rk2, rk4, linearized_backward_euler.
    max_particles : int
        Cap on live particles (>= 1); with ``rate`` and ``lifetime``, the live particles must
        fit the memory limit (:mod:`filters.memory`), checked before the run.
    seed : int
        Seed of the emitter and of the noise (>= 0).
    """
    rate = check_range("rate", rate, 0.0, math.inf, low_inclusive=False, high_inclusive=False)
    lifetime = check_range("lifetime", lifetime, 0.0, math.inf, low_inclusive=False,
                           high_inclusive=False)
    max_particles = check_int("max_particles", max_particles, 1)
    _check_particle_memory(rate, lifetime, max_particles)
    check_range("ball_radius", ball_radius, 0.0)
    check_range("radius", radius, 0.0, low_inclusive=False)
    check_integrator(integrator)
    seed = check_int("seed", seed, 0, 2**62)
    floor = Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    obstacles = (Sphere((0.0, 0.0, ball_height), ball_radius),) if ball_radius > 0 else ()
    flow_field = CurlNoise(
        amplitude=amplitude, frequency=frequency, octaves=octaves, seed=seed,
        time_scale=time_scale, colliders=obstacles, ramp_distance=0.1 if obstacles else 0.0,
        base_velocity=(0.0, 0.0, rise))
    emitter = BoxEmitter(lower=(-0.12, -0.12, 0.0), upper=(0.12, 0.12, 0.04), rate=rate,
                         lifetime=lifetime, lifetime_jitter=0.25)
    simulation = NoiseAdvection(
        flow_field, emitter, integrator=integrator, colliders=(floor, *obstacles),
        collider_margin=0.0, max_dt=1.0 / 120.0, max_particles=max_particles,
        size_range=(0.5 * radius, radius), variation_frequency=3.0, seed=seed)
    flow = Flow(SimulationSource(simulation, fps=SCENE_FPS, duration=SCENE_DURATION),
                name="particles")
    flow.add_collider("floor", floor, role="floor")
    for obstacle in obstacles:
        flow.add_collider("ball", obstacle)
    if surface:
        from pipeline.surface import surface_stages

        # metaballs of the particles' own radii, smoothed more and with no liquid features
        # (smoke particles have no liquid volume to keep)
        flow.add("surface", *surface_stages(radius=radius, radius_array="size",
                                            attributes=("velocity", "age", "color"),
                                            anisotropic=False, feature_smoothing=0,
                                            smooth_iterations=100, pass_band=0.001,
                                            volume_correction=False),
                 input="particles")
    return flow


#: Bytes a live particle takes over a run: its state (position, velocity, id, age, lifetime,
#: size, colour: 88 bytes), the frame's arrays and VTK's copy for the writer, with a margin.
BYTES_PER_PARTICLE = 400


def _check_particle_memory(rate: float, lifetime: float, max_particles: int) -> None:
    """Refuse, before the run, more live particles than the memory limit holds.

    At most ``rate * lifetime * 1.25`` particles are alive at once (lifetimes jitter by 25 %,
    plus one step's emission), and never more than ``max_particles``.
    """
    live = min(float(max_particles), rate * lifetime * 1.25 + rate / 120.0 + 1.0)
    check_memory(f"noise_smoke with rate = {rate:g}/s, lifetime = {lifetime:g} s and "
                 f"max_particles = {max_particles:,}: up to {live:,.0f} live particles",
                 live * BYTES_PER_PARTICLE, hint="lower rate, lifetime or max_particles")


SCENE = Scene("noise_smoke", build,
              "particles rising through curl noise around a ball, drawn as smoke",
              fps=SCENE_FPS, duration=SCENE_DURATION)
