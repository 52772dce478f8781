"""The elastic scenes at their default parameters obey physics under contact.

Each test runs a scene's default simulation frame by frame (as ``blobflow run`` does) and asserts
its energy account -- kinetic + gravitational + elastic + contact, with static pins and
colliders nothing does work on it -- never rises across a frame by more than 0.5 % of the
initial total, and the state it comes to rest in.
"""

import numpy as np
import pytest

FPS = 30.0


def _run(simulation, duration, each_frame):
    """Advance ``simulation`` frame by frame to ``duration``; assert the energy account and
    call ``each_frame(simulation)``."""
    e0 = simulation.energies().total
    previous = e0
    worst = -np.inf
    for k in range(1, int(round(duration * FPS)) + 1):
        simulation.advance_to(k / FPS)
        account = simulation.energies()
        assert account.total == pytest.approx(account.kinetic + account.gravitational
                                              + account.elastic + account.contact)
        worst = max(worst, account.total - previous)
        previous = account.total
        each_frame(simulation)
    assert worst <= 0.005 * abs(e0)
    return e0


def test_cloth_drape_drapes_over_the_sphere_held_by_friction():
    from scenes.cloth_drape import build

    sim = build().source.simulation
    colliders = sim.colliders
    sphere = colliders.spheres[0]
    n = int(round(np.sqrt(sim.state.positions.shape[0])))
    corners = [0, n - 1, n * (n - 1), n * n - 1]
    seen = {"inside": np.inf, "below": np.inf, "contact": 0.0, "at3": None}

    def frame(s):
        x = s.state.positions
        seen["inside"] = min(seen["inside"], (np.linalg.norm(x - sphere[:3], axis=1)
                                              - sphere[3]).min())
        seen["below"] = min(seen["below"], x[:, 2].min())
        seen["contact"] = max(seen["contact"], s.energies().contact)
        if abs(s.state.time - 3.0) < 1e-9:
            seen["at3"] = x.copy()

    _run(sim, 4.0, frame)
    x, v = sim.state.positions, sim.state.velocities
    assert seen["contact"] > 0.0
    assert seen["inside"] > -1e-3 and seen["below"] > -1e-3  # never inside by more than 1 mm
    assert np.linalg.norm(v, axis=1).max() < 0.05  # at rest by t = 4 s
    assert np.abs(x - seen["at3"]).max() < 0.01  # and staying put
    assert np.abs(x[:, :2].mean(axis=0)).max() < 0.02  # over the sphere, not slid off
    assert x[:, 2].max() > 2 * sphere[3]  # draped over its top ...
    assert x[corners, 2].max() < 0.03  # ... with its corners on or near the floor


def test_hair_hangs_smooth_and_settles_outside_the_head():
    from scenes.hair import build

    sim = build().source.simulation
    head = sim.colliders.spheres[0]
    springs = sim.model.topology.springs
    n_per = 17
    strands = sim.state.positions.shape[0] // n_per
    t = np.linspace(0.0, 1.0, 5)[:, None, None]
    inside = [np.inf]

    def frame(s):
        x = s.state.positions
        a, b = x[springs[:, 0]], x[springs[:, 1]]
        samples = a[None] + t * (b - a)[None]  # points along every segment
        inside[0] = min(inside[0], (np.linalg.norm(samples - head[:3], axis=2) - head[3]).min())

    _run(sim, 3.0, frame)
    x = sim.state.positions.reshape(strands, n_per, 3)
    v = sim.state.velocities.reshape(strands, n_per, 3)
    assert inside[0] > -1e-9  # no segment inside the head (roots on the scalp)
    assert np.linalg.norm(v[:, -1], axis=1).max() < 0.05  # tips at rest within 3 s
    assert np.all(x[:, -1, 2] < x[:, 0, 2])  # every tip below its root: it hangs
    e = np.diff(x, axis=1)
    e /= np.linalg.norm(e, axis=2, keepdims=True)
    turn = np.degrees(np.arccos(np.clip((e[:, 1:] * e[:, :-1]).sum(axis=2), -1.0, 1.0)))
    assert turn.max() < 45.0  # smooth: no kink, even where the clamped root meets gravity


def test_jello_drop_squashes_wobbles_and_rests_on_the_floor():
    from filters.elastic.topology import mesh_volume
    from scenes.jello_drop import build

    sim = build().source.simulation
    triangles = sim.model.topology.embedding.triangles
    rest = sim.mesh_points()
    h0 = np.ptp(rest[:, 2])
    v0 = mesh_volume(rest, triangles)
    heights, gaps = [], []

    def frame(s):
        p = s.mesh_points()
        heights.append(np.ptp(p[:, 2]) / h0)
        gaps.append(p[:, 2].min())

    _run(sim, 2.0, frame)
    heights, gaps = np.array(heights), np.array(gaps)
    assert gaps.min() > 0.0  # never through the floor
    assert heights.min() <= 0.9  # squashes by 10 % of its height or more
    touching = gaps < 1e-3
    first = np.argmax(touching)
    h = heights[first:]
    # oscillation cycles: local minima of the height, 0.5 % of it deep, after the impact
    minima = [i for i in range(1, len(h) - 1) if h[i] < h[i - 1] and h[i] <= h[i + 1]
              and max(h[:i].max() if i else 0, h[i:].max()) - h[i] > 0.005]
    assert len(minima) >= 3  # the impact and two more cycles
    p = sim.mesh_points()
    assert p[:, 2].min() < 1e-3  # rests touching the floor
    assert np.abs(sim.state.velocities).max() < 0.05
    assert abs(mesh_volume(p, triangles) / v0 - 1.0) < 0.02


def test_the_energy_account_is_written_as_field_data(tmp_path):
    from filters.elastic.energy import ENERGY_FIELDS
    from pipeline import Flow, SimulationSource, read_series
    from scenes.cloth_drape import build

    sim = build(resolution=8).source.simulation
    paths = Flow(SimulationSource(sim, fps=FPS, frames=12), name="cloth").run(
        tmp_path, progress=False)
    times, frames = read_series(paths["cloth"])
    assert len(frames) == 12
    totals = []
    for data in frames:
        values = {name: float(np.asarray(data.field_data[name]).ravel()[0])
                  for name in ENERGY_FIELDS}
        assert values["energy_total"] == pytest.approx(
            sum(values[name] for name in ENERGY_FIELDS[:-1]))
        totals.append(values["energy_total"])
    assert values["energy_contact"] > 0.0  # it landed on the sphere by t = 11/30 s
    assert values["energy_total"] == pytest.approx(sim.energies().total, rel=1e-12)
    assert np.all(np.diff(totals) <= 0.005 * totals[0])
