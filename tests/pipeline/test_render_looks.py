"""What the renders show: shadows under resting bodies, the tank's edges, smoke as soft sprites,
robust framing, the most interesting frame, and the gallery."""

import json
import math
import os
from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest
import pyvista as pv

from filters.geometry import Box, Plane
from pipeline.cli import main
from pipeline.io.colliders import COLLIDERS_FILE, Collider, write_colliders
from pipeline.io.series import SeriesWriter
from pipeline.render import frame_at_time, interesting_frame, turntable
from pipeline.render.gallery import (
    GALLERY_SIZE,
    code_mtime,
    gallery_still,
    run_is_current,
    run_series,
)
from pipeline.render.renderer import Renderer
from pipeline.scene import Scene, available_scenes, load_scene

pytestmark = pytest.mark.render

SIZE = (240, 180)
ROOT = Path(__file__).resolve().parents[2]


def _write(path, frames, dt=0.1):
    writer = SeriesWriter(path)
    for k, data in enumerate(frames):
        writer.write(data, round(k * dt, 9))
    return path


def _luminance(image):
    return image[..., :3].astype(float).mean(axis=-1)


def _sample(image, pixels):
    """Luminance at each (column, row), or NaN outside the image."""
    lum = _luminance(image)
    out = []
    for c, r in np.round(pixels).astype(int):
        inside = 0 <= r < lum.shape[0] and 0 <= c < lum.shape[1]
        out.append(lum[r, c] if inside else np.nan)
    return np.array(out)


@pytest.fixture(scope="module")
def resting_ball(tmp_path_factory):
    """A ball resting on a declared floor (two identical frames) and its colliders file."""
    folder = tmp_path_factory.mktemp("ball")
    ball = pv.Sphere(radius=0.1, center=(0.0, 0.0, 0.1), theta_resolution=48, phi_resolution=48)
    path = _write(folder / "jello.pvd", [ball, ball])
    write_colliders([Collider("floor", Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)), "floor")],
                    folder / COLLIDERS_FILE)
    return path


def test_floor_under_a_resting_body_is_in_its_shadow(resting_ball):
    view = (-0.4, 0.4, -0.4, 0.4, 0.0, 0.25)
    images = {}
    for shadows in (True, False):
        with Renderer(resting_ball, size=SIZE, text=False, shadows=shadows,
                      bounds=view) as renderer:
            images[shadows] = renderer.render(0, 0.0)
            key = np.array(renderer.key_light_position)
            # floor points just outside the ball's footprint (radius 0.1 m) on the side away
            # from the key light, under the ball's shadow, and far from it towards the light
            away = math.atan2(-key[1], -key[0])
            angles = away + np.radians(np.arange(-30, 31, 10))
            near = [np.array([0.125 * math.cos(a), 0.125 * math.sin(a), 0.0]) for a in angles]
            far = [np.array([-0.3 * math.cos(a), -0.3 * math.sin(a), 0.0]) for a in angles]
            pixels_near, pixels_far = renderer.pixels_of(near), renderer.pixels_of(far)
    lit, flat = images[True], images[False]

    def floor_pixels(pixels):
        """The pixels that show the floor (grey, not the orange ball) in both pictures."""
        keep = []
        for c, r in np.round(pixels).astype(int):
            if not (0 <= r < SIZE[1] and 0 <= c < SIZE[0]):
                continue
            if all(abs(int(im[r, c, 0]) - int(im[r, c, 2])) < 25 for im in (lit, flat)):
                keep.append((c, r))
        return np.array(keep, dtype=float)

    near_px, far_px = floor_pixels(pixels_near), floor_pixels(pixels_far)
    assert len(near_px) >= 2 and len(far_px) >= 2, (len(near_px), len(far_px))
    near_lum, far_lum = _sample(lit, near_px), _sample(lit, far_px)
    # the floor right by the ball is in its shadow: much darker than the floor far away ...
    assert near_lum.mean() < far_lum.mean() - 40, (near_lum, far_lum)
    # ... which is the shadow's doing: without shadows the two are nearly alike
    assert abs(_sample(flat, near_px).mean() - _sample(flat, far_px).mean()) < 12


@pytest.fixture(scope="module")
def empty_tank(tmp_path_factory):
    folder = tmp_path_factory.mktemp("tank")
    lo, hi = (0.0, 0.0, 0.0), (0.4, 0.1, 0.3)
    path = _write(folder / "particles.pvd", [pv.PolyData(), pv.PolyData()])  # an empty tank
    write_colliders([Collider("tank", ~Box(lo, hi), "container")], folder / COLLIDERS_FILE)
    return path, np.array(lo), np.array(hi)


def test_tank_edges_are_drawn_along_their_projection(empty_tank):
    path, lo, hi = empty_tank
    # the four top edges and the four vertical ones: 8 of the 12, none hidden by the bottom

    def corners(z):
        return [np.array([x, y, z]) for x, y in ((lo[0], lo[1]), (hi[0], lo[1]),
                                                 (hi[0], hi[1]), (lo[0], hi[1]))]

    top = corners(hi[2])
    edges = [(top[k], top[(k + 1) % 4]) for k in range(4)]
    edges += [(a, b) for a, b in zip(corners(lo[2]), top, strict=False)]
    samples = [a + f * (b - a) for a, b in edges for f in np.linspace(0.15, 0.85, 8)]
    with Renderer(path, size=SIZE, text=False) as renderer:
        image = renderer.render(0, 0.0)
        pixels = renderer.pixels_of(samples)
    with Renderer(path, size=SIZE, text=False, colliders=None, bounds=renderer.bounds) as bare:
        without = bare.render(0, 0.0)
    lum, lum_without = _luminance(image), _luminance(without)
    darkest = []
    for c, r in np.round(pixels).astype(int):
        window = (slice(max(r - 1, 0), r + 2), slice(max(c - 1, 0), c + 2))
        darkest.append((lum[window].min(), lum_without[window].min()))
    darkest = np.array(darkest)
    # the edge colour (dark slate) along every projected edge, where the picture without the
    # tank is light (floor or background)
    assert (darkest[:, 0] < 110).all(), darkest[:, 0].round()
    assert (darkest[:, 1] > 150).all(), darkest[:, 1].round()


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    flow = load_scene("noise_smoke").build(rate=1500.0, max_particles=2000)
    flow.source.set_frames(flow.source.fps, frames=12)
    return flow.run(tmp_path_factory.mktemp("smoke"), progress=False)


def test_smoke_is_soft_translucent_sprites(smoke_run):
    series = list(smoke_run.values())
    assert [p.stem for p in series] == ["particles"]  # smoke is not contoured by default
    with Renderer(series, size=SIZE, text=False) as renderer:
        image = renderer.render(-1, 0.0)
        assert renderer.layers[0].kind == "smoke"
        bounds = renderer.bounds
    # the same view without the smoke (the ball and floor only)
    empty = series[0].parent / "nothing.pvd"
    _write(empty, [pv.PolyData()])
    with Renderer(empty, size=SIZE, text=False, bounds=bounds,
                  colliders=series[0].parent / COLLIDERS_FILE) as renderer:
        background = renderer.render(0, 0.0)
    diff = np.abs(image.astype(int) - background.astype(int)).max(axis=-1)
    smoke = diff[diff > 3]
    assert smoke.size > 0.01 * diff.size, "no smoke drawn"
    # soft alpha: a continuum of intermediate intensities, not a hard-edged shell whose pixels
    # all jump by about the same amount
    assert len(np.unique(smoke)) >= 40
    low, high = np.percentile(smoke, [10, 90])
    assert high > 2.5 * low, (low, high)
    middle = ((smoke > 0.1 * smoke.max()) & (smoke < 0.9 * smoke.max())).mean()
    assert middle > 0.5, middle


def test_camera_ignores_stray_particles(tmp_path):
    rng = np.random.default_rng(1)
    block = rng.uniform(0.0, 1.0, (400, 3))
    stray = np.vstack([block, [[40.0, 0.0, 0.5]]])
    a = _write(tmp_path / "a.pvd", [pv.PolyData(block)])
    b = _write(tmp_path / "b.pvd", [pv.PolyData(stray)])
    with Renderer(a, size=SIZE) as ra, Renderer(b, size=SIZE) as rb:
        np.testing.assert_allclose(ra.bounds, rb.bounds, atol=0.05)
        assert rb.bounds[1] < 1.1


def _moving(tmp_path, speeds):
    frames = []
    for k, v in enumerate(speeds):
        poly = pv.PolyData(np.array([[0.0, 0.0, 1.0 + 0.1 * k], [1.0, 0.0, 1.0]]))
        poly.point_data["velocity"] = np.array([[v, 0.0, 0.0], [0.0, 0.0, 0.0]])
        frames.append(poly)
    return _write(tmp_path / "particles.pvd", frames)


def test_interesting_frame_is_the_most_energetic_or_the_largest_surface(tmp_path):
    path = _moving(tmp_path, [0.0, 1.0, 3.0, 2.0, 0.5])
    assert interesting_frame(path) == (2, "largest kinetic energy")
    surfaces = [pv.Sphere(radius=r) for r in (0.1, 0.3, 0.2, 0.25, 0.1)]
    surface = _write(tmp_path / "surface.pvd", surfaces)
    assert interesting_frame([path, surface]) == (1, "largest surface area")
    assert frame_at_time(path, 0.31) == 3
    with pytest.raises(ValueError, match="time"):
        frame_at_time(path, 5.0)


def test_turntable_takes_the_interesting_frame_unless_told(tmp_path):
    path = _moving(tmp_path, [0.0, 1.0, 3.0, 2.0, 0.5])
    auto = turntable(path, tmp_path / "auto", frames=2, size=SIZE, progress=False)
    with Renderer(path, size=SIZE, frames=[2]) as renderer:
        expected = renderer.render(2, 0.0)
    np.testing.assert_array_equal(imageio.imread(auto / "frame_0000.png"), expected)
    code = main(["render", str(path), "--turntable", "2", "--time", "0.4", "--size", "240x180",
                 "--out", str(tmp_path / "late"), "-q"])
    assert code == 0
    with Renderer(path, size=SIZE, frames=[4]) as renderer:
        expected = renderer.render(4, 0.0)
    np.testing.assert_array_equal(imageio.imread(tmp_path / "late" / "frame_0000.png"), expected)


@pytest.mark.parametrize("argv, message", [
    (["--turntable", "3", "--time", "9"], "--time must be within"),
    (["--time", "0.1"], "give --turntable"),
    (["--turntable", "3", "--time", "0.1", "--time-index", "1"], "not allowed with"),
])
def test_cli_render_time_mistakes(tmp_path, capsys, argv, message):
    path = _moving(tmp_path, [0.0, 1.0])
    code = main(["render", str(path), *argv, "--out", str(tmp_path / "x.gif"), "-q"])
    err = capsys.readouterr().err
    assert code == 2 and message in err and err.count("\n") == 1
    assert not (tmp_path / "x.gif").exists()


def test_gallery_runs_a_scene_with_its_defaults_and_reuses_the_run(tmp_path, capsys,
                                                                    monkeypatch):
    monkeypatch.chdir(tmp_path)  # no outputs/bouncing of the working copy is reused
    out, runs = tmp_path / "docs", tmp_path / "runs"
    assert main(["gallery", "bouncing", "--out", str(out), "--runs", str(runs), "-q"]) == 0
    image = imageio.imread(out / "bouncing.png")
    assert image.shape[:2] == (480, 640) and image.std() > 10
    record = json.loads((runs / "bouncing" / "scene.json").read_text())
    assert record["parameters"] == json.loads(json.dumps(load_scene("bouncing").defaults()))
    assert (runs / "bouncing" / COLLIDERS_FILE).is_file()
    capsys.readouterr()
    before = (runs / "bouncing" / "particles.pvd").stat().st_mtime_ns
    assert main(["gallery", "bouncing", "--out", str(out), "--runs", str(runs), "-q"]) == 0
    assert "reusing" in capsys.readouterr().out
    assert (runs / "bouncing" / "particles.pvd").stat().st_mtime_ns == before
    np.testing.assert_array_equal(imageio.imread(out / "bouncing.png"), image)
    # a run of the defaults where `blobflow run bouncing` writes is reused as well
    (tmp_path / "outputs").mkdir()
    (runs / "bouncing").rename(tmp_path / "outputs" / "bouncing")
    capsys.readouterr()
    assert main(["gallery", "bouncing", "--out", str(out), "--runs", str(runs), "-q"]) == 0
    assert f"reusing the run in {Path('outputs') / 'bouncing'}" in capsys.readouterr().out
    assert not (runs / "bouncing").exists()
    np.testing.assert_array_equal(imageio.imread(out / "bouncing.png"), image)
    # a scene's still time chooses the frame instead of the most interesting one
    reused = tmp_path / "outputs" / "bouncing"
    path, index, reason = gallery_still(reused, tmp_path / "still.png", time=0.2)
    assert index == 6 and "t = 0.2 s" in reason  # 30 frames per second
    with Renderer(run_series(reused), size=GALLERY_SIZE, frames=[6]) as renderer:
        np.testing.assert_array_equal(imageio.imread(path), renderer.render(6, 0.0))
    # a run older than the code that computes it is stale: run again
    scene = load_scene("bouncing")
    assert run_is_current(reused, scene)
    os.utime(reused / "particles.pvd", (code_mtime(scene) - 10.0,) * 2)
    assert not run_is_current(reused, scene)
    assert main(["gallery", "nope", "--out", str(out), "--runs", str(runs)]) == 2


def test_scene_still_time_must_lie_within_its_duration():
    build = load_scene("bouncing").build_function
    assert Scene("b", build, "d", duration=2.0, still=1.5).still == 1.5
    with pytest.raises(ValueError, match="still must be a time in"):
        Scene("b", build, "d", duration=2.0, still=2.5)


def test_docs_show_the_gallery_image_of_every_scene():
    # the scenes' page of the user guide (the README shows one picture and links there)
    page = (ROOT / "docs" / "user_guide" / "scenes.rst").read_text(encoding="utf-8")
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "docs/user_guide/scenes.rst" in readme
    for name in available_scenes():
        assert (ROOT / "docs" / f"{name}.png").is_file(), f"run `blobflow gallery {name}`"
        assert f".. image:: /{name}.png" in page, f"show docs/{name}.png in the scenes' page"


def test_gallery_draws_only_the_outputs_the_scene_draws(tmp_path):
    """A series written for other tools (jello_fem's tetrahedra) stays off the gallery's still."""
    run = tmp_path / "run"
    run.mkdir()
    _write(run / "tets.pvd", [pv.Sphere(radius=0.4, center=(0.8, 0.0, 0.5))] * 3)
    _write(run / "jello.pvd", [pv.Sphere(radius=0.15, center=(0.0, 0.0, 0.15))] * 3)
    (run / "scene.json").write_text(json.dumps({"scene": "x", "outputs": ["tets", "jello"]}))
    assert run_series(run) == [run / "tets.pvd", run / "jello.pvd"]
    assert run_series(run, ["jello"]) == [run / "jello.pvd"]
    path, index, _ = gallery_still(run, tmp_path / "still.png", size=SIZE, time=0.1,
                                   outputs=["jello"])
    assert index == 1
    image = imageio.imread(path)
    with Renderer(run / "jello.pvd", size=SIZE, frames=[1]) as renderer:
        np.testing.assert_array_equal(image, renderer.render(1, 0.0))
    with Renderer(run_series(run), size=SIZE, frames=[1]) as renderer:
        assert np.abs(renderer.render(1, 0.0).astype(int) - image.astype(int)).max() > 50


def test_flat_faces_of_a_liquid_surface_are_shaded_flat(tmp_path):
    """A closed surface with its normals averaged across sharp edges (a pool cut flat at its
    tank's walls) is drawn with split normals: each flat face evenly lit, no diagonal streaks
    over its long triangles; the written surface is left as it is."""
    box = pv.Box(bounds=(0, 0.4, 0, 0.2, 0, 0.3), level=0, quads=False).triangulate().clean()
    box = box.compute_normals(cell_normals=False, split_vertices=False, consistent_normals=True,
                              auto_orient_normals=True)
    path = _write(tmp_path / "surface.pvd", [box, box])
    written = {f: f.read_bytes() for f in sorted(tmp_path.rglob("*")) if f.is_file()}
    with Renderer(path, size=SIZE, frames=[0]) as renderer:
        image = renderer.render(0, 0.0)
        u, v = (g.ravel() for g in np.meshgrid(np.linspace(0.1, 0.9, 9), np.linspace(0.1, 0.9, 9)))
        faces = {"front": np.c_[0.4 * u, 0 * u, 0.3 * v],
                 "top": np.c_[0.4 * u, 0.2 * v, 0.3 + 0 * u],
                 "side": np.c_[0.4 + 0 * u, 0.2 * u, 0.3 * v]}
        for name, points in faces.items():
            lum = _sample(image, renderer.pixels_of(points))
            assert np.ptp(lum) < 10, (name, np.ptp(lum))  # averaged normals: 55 to 127
    assert {f: f.read_bytes() for f in sorted(tmp_path.rglob("*")) if f.is_file()} == written


def test_a_liquid_surface_is_drawn_as_water_whatever_its_series_is_called(tmp_path):
    from pipeline.render import looks
    from pipeline.surface import reconstruct

    x = (np.mgrid[0:8, 0:8, 0:8].reshape(3, -1).T + 0.5) * 0.02
    options = dict(feature_smoothing=0, smooth_iterations=0, attributes=())
    liquid = reconstruct(x, 0.01, liquid=True, **options)
    other = reconstruct(x, 0.01, **options)  # a point cloud's surface
    untagged = liquid.copy()  # as written before the tag existed
    untagged.field_data.remove("blobflow_kind")
    cases = [("smooth", liquid, "water"), ("surface_smooth", liquid, "water"),
             ("surface", other, "solid"), ("surface", untagged, "water"),
             ("smooth", untagged, "solid")]
    for k, (name, data, look) in enumerate(cases):
        path = _write(tmp_path / str(k) / f"{name}.pvd", [data, data.scale(1.2)])
        with Renderer(path, size=SIZE, frames=[0], colliders=None, floor=False) as renderer:
            layer = renderer.layers[0]
            assert layer.kind == look, (name, look)
            prop = layer.actor.GetProperty()
            colour = looks.WATER if look == "water" else looks.SOLID
            np.testing.assert_allclose(prop.GetColor(), pv.Color(colour).float_rgb)
            assert prop.GetSpecular() == looks.MATERIALS[look]["specular"]
            assert prop.GetSpecularPower() == looks.MATERIALS[look]["specular_power"]
        # a liquid's surface alone decides the most interesting frame: its largest area
        expected = (1, "largest surface area") if look == "water" else (1, "last frame")
        assert interesting_frame(path) == expected


def test_smoke_hides_any_surface_contoured_around_its_particles(tmp_path):
    from pipeline.surface import reconstruct

    rng = np.random.default_rng(0)
    smoke = pv.PolyData(rng.uniform(0.0, 0.2, (300, 3)))
    smoke.point_data["age"] = rng.uniform(0.0, 1.0, 300)
    surface = reconstruct(smoke, 0.03, anisotropic=False, feature_smoothing=0,
                          smooth_iterations=0, attributes=())  # tagged particle_surface
    assert surface.n_cells > 0
    particles = _write(tmp_path / "particles.pvd", [smoke, smoke])
    contoured = _write(tmp_path / "smooth.pvd", [surface, surface])
    with Renderer([particles, contoured], size=SIZE, frames=[0], colliders=None) as renderer:
        assert [(layer.name, layer.kind) for layer in renderer.layers] == [("particles", "smoke")]
