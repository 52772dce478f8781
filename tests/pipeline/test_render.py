"""Offscreen rendering with no DISPLAY: movies, turntables, invariants and cached images."""

import os
from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest
import pyvista as pv
from _helpers import ballistic

from pipeline import Flow, SimulationSource
from pipeline.cli import main
from pipeline.io.series import SeriesWriter, read_series
from pipeline.render import Renderer, parse_size, timelapse, turntable
from pipeline.scene import available_scenes, load_scene

pytestmark = pytest.mark.render

SIZE = (160, 120)

#: Small versions of every scene for the image regression: (parameters, frames).
SMALL_SCENES = {
    "bouncing": ({"count": 4}, 4),
    "dam_break": ({"spacing": 0.02, "smooth_iterations": 5}, 3),
    "drop": ({"spacing": 0.02, "pool_depth": 0.04, "drop_radius": 0.03,
              "smooth_iterations": 5}, 3),
    "cloth_drape": ({"resolution": 8}, 3),
    "jello_drop": ({"spacing": 0.06}, 3),
    "jello_fem": ({"spacing": 0.06}, 3),
    "hair": ({"strands": 12, "segments": 5}, 3),
    "noise_smoke": ({"rate": 600.0, "max_particles": 400}, 6),
    "floating": ({"spacing": 0.025, "box_height": 0.05, "smooth_iterations": 5}, 3),
    "jello_splash": ({"spacing": 0.025, "smooth_iterations": 5}, 3),
}


@pytest.fixture(scope="module")
def series(tmp_path_factory):
    out = tmp_path_factory.mktemp("render")
    flow = Flow(SimulationSource(ballistic(n=40), fps=10, duration=0.5))
    return flow.run(out, progress=False)["particles"]


def _foreground(image, background):
    """Fraction of pixels that differ clearly from an image of the empty scene."""
    return float((np.abs(image.astype(int) - background.astype(int)).sum(axis=2) > 30).mean())


def test_renders_without_display_through_egl_or_osmesa(series):
    assert "DISPLAY" not in os.environ
    with Renderer(series, size=SIZE) as renderer:
        image = renderer.render(0)
        assert image.shape == (SIZE[1], SIZE[0], 3)
        assert renderer.plotter.render_window.GetClassName() in (
            "vtkEGLRenderWindow", "vtkOSOpenGLRenderWindow")


def test_image_is_not_blank_and_particles_are_blue(series, tmp_path):
    empty = tmp_path / "empty.pvd"
    writer = SeriesWriter(empty)
    writer.write(pv.PolyData(), 0.0)
    with Renderer([series], size=SIZE, text=False) as renderer:
        bounds = renderer.bounds
        image = renderer.render(2)
    # The empty scene from the same camera: same bounds, no particles.
    with Renderer(empty, size=SIZE, text=False, bounds=bounds) as renderer:
        background = renderer.render(0)
    fraction = _foreground(image, background)
    assert 0.002 < fraction < 0.9
    mask = np.abs(image.astype(int) - background.astype(int)).sum(axis=2) > 30
    r, g, b = image[mask].astype(float).mean(axis=0)
    assert b > r + 20, f"particles are not blue-ish: mean RGB {r:.0f} {g:.0f} {b:.0f}"


def test_turntable_is_a_seamless_loop_of_distinct_views(series, tmp_path):
    n = 5
    out = turntable(series, tmp_path / "tt", frames=n, time_index=2, size=SIZE, progress=False)
    frames = [imageio.imread(p) for p in sorted(out.glob("frame_*.png"))]
    assert len(frames) == n and frames[0].shape[:2] == (SIZE[1], SIZE[0])
    for i in range(n):
        for j in range(i + 1, n):
            assert np.abs(frames[i].astype(int) - frames[j].astype(int)).mean() > 0.5, \
                f"views {i} and {j} are the same"
    # frame n + 1 of the loop (azimuth 360) is frame 1, exactly: no repeated frame at the seam
    with Renderer(series, size=SIZE, frames=[2]) as renderer:
        np.testing.assert_array_equal(renderer.render(2, 360.0), frames[0])
        np.testing.assert_array_equal(renderer.render(2, 360.0 * (n - 1) / n), frames[-1])
    gif = turntable(series, tmp_path / "tt.gif", frames=2, time_index=2, size=SIZE,
                    progress=False)
    assert len(imageio.mimread(gif)) == 2  # two distinct views, not one merged frame


def test_timelapse_mp4_has_every_frame_and_the_size(series, tmp_path):
    out = timelapse(series, tmp_path / "movie.mp4", size=SIZE, progress=False)
    reader = imageio.get_reader(out)
    assert reader.count_frames() == 6
    assert tuple(reader.get_meta_data()["size"]) == SIZE
    reader.close()


def test_png_folder_output(series, tmp_path):
    out = turntable(series, tmp_path / "pngs", frames=3, size=SIZE, progress=False)
    files = sorted(out.glob("frame_*.png"))
    assert [f.name for f in files] == ["frame_0000.png", "frame_0001.png", "frame_0002.png"]
    assert imageio.imread(files[0]).shape[:2] == (SIZE[1], SIZE[0])


def test_empty_series_renders_empty_scene(tmp_path):
    path = tmp_path / "empty.pvd"
    writer = SeriesWriter(path)
    writer.write(pv.PolyData(), 0.0)
    writer.write(pv.PolyData(), 0.1)
    out = timelapse(path, tmp_path / "empty.gif", size=SIZE, progress=False)
    assert len(imageio.mimread(out)) == 2
    # the frames themselves (PNG, lossless): a real picture of the empty scene, the same in
    # both frames but for the time label at the top; a series with points looks different
    frames = timelapse(path, tmp_path / "empty", size=SIZE, progress=False)
    images = [np.asarray(imageio.imread(p))[..., :3].astype(int)
              for p in sorted(frames.glob("*.png"))]
    assert len(images) == 2 and images[0].shape == (SIZE[1], SIZE[0], 3)
    label = 20  # rows of the time label
    assert np.array_equal(images[0][label:], images[1][label:])
    assert not np.array_equal(images[0][:label], images[1][:label])  # t = 0 and t = 0.1
    assert images[0].std() > 1.0  # not a blank frame
    points = tmp_path / "points.pvd"
    writer = SeriesWriter(points)
    writer.write(pv.PolyData(np.random.default_rng(0).uniform(0, 1, (50, 3))), 0.0)
    drawn = timelapse(points, tmp_path / "points", size=SIZE, progress=False)
    with_points = np.asarray(imageio.imread(sorted(drawn.glob("*.png"))[0]))[..., :3].astype(int)
    assert np.abs(with_points[label:] - images[0][label:]).max() > 100


def test_color_by_unknown_array_lists_the_arrays(series):
    with pytest.raises(ValueError, match="arrays: id, velocity"):
        Renderer(series, size=SIZE, color_by="temperature")


@pytest.mark.parametrize("text, ok", [("640x480", (640, 480)), ("321x241", (320, 240)),
                                      ("big", None), ("8x8", None)])
def test_parse_size(text, ok):
    if ok:
        assert parse_size(text) == ok
    else:
        with pytest.raises(ValueError, match="size"):
            parse_size(text)


def test_cli_render_writes_gif_with_requested_frames(series, tmp_path, capsys):
    out = tmp_path / "t.gif"
    code = main(["render", str(series), "--turntable", "4", "--size", "96x64", "--out", str(out),
                 "--color-by", "velocity", "-q"])
    assert code == 0
    frames = imageio.mimread(out)
    assert len(frames) == 4 and frames[0].shape[:2] == (64, 96)


@pytest.mark.parametrize("content", [None, "garbage", "<VTKFile type='Collection'><Collection>"
                                     "<DataSet timestep='0' file='p/gone.vtp'/>"
                                     "</Collection></VTKFile>"])
def test_cli_render_missing_or_malformed_series(tmp_path, capsys, content):
    path = tmp_path / "s.pvd"
    if content is not None:
        path.write_text(content)
    code = main(["render", str(path), "--out", str(tmp_path / "x.gif"), "-q"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and err.startswith("blobflow: error: ")
    assert not (tmp_path / "x.gif").exists()


def test_without_offscreen_opengl_run_keeps_its_series_and_render_says_why(tmp_path, capsys,
                                                                             monkeypatch):
    # where neither EGL nor OSMesa is installed VTK crashes creating a window: measured, a
    # segmentation fault; blobflow must stop before that and say which packages are missing
    import pipeline.render.offscreen as offscreen

    monkeypatch.setattr(offscreen, "_CAN_RENDER", False)
    out = tmp_path / "run"
    code = main(["run", "bouncing", "--frames", "3", "--set", "count=4", "--out", str(out), "-q"])
    err = capsys.readouterr().err
    assert code == 0 and "rendering skipped" in err and "libegl1" in err
    assert len(read_series(out / "particles.pvd")[0]) == 3
    assert not list(out.glob("*.gif")) and not list(out.glob("*.mp4"))
    code = main(["render", str(out / "particles.pvd"), "--out", str(tmp_path / "x.gif"), "-q"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "libosmesa6" in err
    assert not (tmp_path / "x.gif").exists()


def test_every_scene_has_a_small_image_regression_case():
    assert set(available_scenes()) <= set(SMALL_SCENES), "add the new scene to SMALL_SCENES"


@pytest.fixture(scope="module")
def scene_series(tmp_path_factory):
    """The written series of each small scene, run once for all the images of this module."""
    runs = {}

    def series(scene_name):
        if scene_name not in runs:
            parameters, frames = SMALL_SCENES[scene_name]
            flow = load_scene(scene_name).build(**parameters)
            flow.source.set_frames(flow.source.fps, frames=frames)
            paths = flow.run(tmp_path_factory.mktemp(scene_name), progress=False)
            runs[scene_name] = {name: paths[name] for name in flow.drawn_outputs()}
        return runs[scene_name]

    return series


@pytest.mark.parametrize("scene_name", sorted(SMALL_SCENES))
@pytest.mark.parametrize("which", ["first", "last"])
def test_scene_images_match_cache(scene_name, which, scene_series, verify_image_cache):
    paths = scene_series(scene_name)
    index = 0 if which == "first" else -1
    renderer = Renderer(list(paths.values()), size=SIZE, frames=[index])
    renderer.render(index, 0.0)
    verify_image_cache(renderer.plotter)
    renderer.close()


def test_every_scene_has_cached_images():
    """A new scene must come with its cached images (pytest-pyvista would otherwise write them
    on the first run and pass)."""
    cache = Path(__file__).resolve().parents[1] / "image_cache"
    missing = [f"scene_images_match_cache[{which}-{name}].png" for name in available_scenes()
               for which in ("first", "last")
               if not (cache / f"scene_images_match_cache[{which}-{name}].png").is_file()]
    assert not missing, f"no cached image: {missing}; run the render tests with --reset_image_cache"
