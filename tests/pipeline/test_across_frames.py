"""Surfaces smoothed across frames (``blobflow surface --across-frames K``): a static series is
left as it is, a moving drop's sampling jitter is smoothed, resume rewrites a lost frame
identically, and bad input is refused."""

import numpy as np
import pytest
import pyvista as pv

from filters.surface.temporal import normal_offsets, vertex_normals
from pipeline import read_series
from pipeline.cli import main
from pipeline.io.series import SeriesWriter
from pipeline.surface.frames import surface_series
from pipeline.tasks import FramesError

SPACING = 0.02
OPTIONS = dict(radius=0.5 * SPACING, smooth_iterations=10, feature_smoothing=10)


def ball(radius_s=3, seed=0):
    g = np.stack(np.meshgrid(*[np.arange(-radius_s - 1, radius_s + 2)] * 3, indexing="ij"), -1)
    g = g.reshape(-1, 3).astype(float)
    g = g[np.linalg.norm(g - 0.1, axis=1) < radius_s] * SPACING
    return g + np.random.default_rng(seed).uniform(-0.05, 0.05, g.shape) * SPACING


def write_particles(path, frames, with_ids=True, shuffle=True, ids=None):
    """A particle series at 10 fps, every frame listed in another order (ids ``ids[k]``, by
    default the row numbers, kept with their particles)."""
    writer = SeriesWriter(path)
    rng = np.random.default_rng(1)
    for k, x in enumerate(frames):
        order = rng.permutation(len(x)) if shuffle else np.arange(len(x))
        cloud = pv.PolyData(np.ascontiguousarray(x[order]))
        if with_ids:
            frame_ids = np.arange(len(x)) if ids is None else np.asarray(ids[k])
            cloud.point_data["id"] = frame_ids[order].astype(np.int64)
        writer.write(cloud, k / 10)
    return path


def meshes(path):
    _, frames = read_series(path)
    return [(np.asarray(f.points, np.float64), np.asarray(f.faces.reshape(-1, 4)[:, 1:]))
            for f in frames]


def test_a_static_series_keeps_its_single_frame_surfaces(tmp_path):
    # the same particles in the same order in every frame: bitwise equal single-frame surfaces
    particles = write_particles(tmp_path / "p" / "particles.pvd", [ball()] * 5, shuffle=False)
    surface_series(particles, tmp_path / "one" / "surface.pvd", progress=False, **OPTIONS)
    surface_series(particles, tmp_path / "five" / "surface.pvd", progress=False,
                   across_frames=2, **OPTIONS)
    single = meshes(tmp_path / "one" / "surface.pvd")
    across = meshes(tmp_path / "five" / "surface.pvd")
    assert len(across) == 5
    for (p, t), (q, u) in zip(single, across, strict=False):
        np.testing.assert_array_equal(t, u)
        np.testing.assert_array_equal(q, p)
    # the first pass's single-frame surfaces are gone once the series is complete
    assert sorted(f.name for f in (tmp_path / "five").iterdir()) == [
        "surface", "surface.pvd", "surface.source.json", "surface.vtp.series"]


def test_a_moving_drop_jitters_no_more_and_keeps_its_volume(tmp_path):
    # a drop moving 0.37 spacings a frame across the voxel lattice: its single-frame surfaces
    # differ from each other by the sampling, which the particles' motion does not explain
    x = ball()
    step = np.array([0.37, 0.21, -0.13]) * SPACING
    particles = write_particles(tmp_path / "p" / "particles.pvd", [x + k * step for k in range(7)])
    surface_series(particles, tmp_path / "one" / "surface.pvd", progress=False, **OPTIONS)
    surface_series(particles, tmp_path / "five" / "surface.pvd", progress=False,
                   across_frames=2, **OPTIONS)
    from filters.surface.mesh import mesh_stats

    def unexplained(ms):
        out = []
        for k in range(2, 4):  # frames with both neighbours on each side
            p, t = ms[k]
            d = normal_offsets(p + step, vertex_normals(p, t), *ms[k + 1], 0.5 * SPACING)
            assert np.isfinite(d).all()
            out.append(np.sqrt(np.mean(d ** 2)))
        return np.mean(out)

    single = meshes(tmp_path / "one" / "surface.pvd")
    across = meshes(tmp_path / "five" / "surface.pvd")
    # measured 0.93x (0.0070 against 0.0075 spacings): the sampling's jitter is a pattern a
    # voxel wide, which the offsets' smoothing over the mesh mostly keeps (the SPH frames'
    # gain is measured in bench_splash.py); what must hold is that it never gets worse
    assert unexplained(across) < unexplained(single)
    for (p, t), (q, u) in zip(single, across, strict=False):
        assert abs(mesh_stats(q, u).volume / mesh_stats(p, t).volume - 1) < 0.005


def test_resume_rewrites_a_lost_frame_identically(tmp_path):
    x = ball()
    particles = write_particles(tmp_path / "p" / "particles.pvd",
                                [x + k * np.array([0.3, 0, 0]) * SPACING for k in range(5)])
    out = tmp_path / "s" / "surface.pvd"
    surface_series(particles, out, progress=False, across_frames=2, **OPTIONS)
    frame = tmp_path / "s" / "surface" / "surface_000002.vtp"
    before = frame.read_bytes()
    frame.unlink()
    result = surface_series(particles, out, progress=False, resume=True, across_frames=2,
                            **OPTIONS)
    assert (result.computed, result.skipped) == (1, 4)
    assert frame.read_bytes() == before
    assert not (tmp_path / "s" / "_surface_single").exists()


def test_particles_without_ids_are_refused_naming_the_array(tmp_path):
    particles = write_particles(tmp_path / "p" / "particles.pvd", [ball()] * 3, with_ids=False)
    with pytest.raises(FramesError, match="'id'"):
        surface_series(particles, tmp_path / "s" / "surface.pvd", progress=False,
                       across_frames=1, **OPTIONS)
    with pytest.raises(ValueError, match="across_frames"):
        surface_series(particles, tmp_path / "s" / "surface.pvd", progress=False,
                       across_frames=11, **OPTIONS)


def test_cli_across_frames(tmp_path, capsys):
    particles = write_particles(tmp_path / "p" / "particles.pvd", [ball()] * 3)
    assert main(["surface", str(particles), "--out", str(tmp_path / "s"), "--radius",
                 str(0.5 * SPACING), "--across-frames", "1", "-q"]) == 0
    assert len(meshes(tmp_path / "s" / "surface.pvd")) == 3
    assert main(["surface", str(particles), "--out", str(tmp_path / "t"),
                 "--across-frames", "-1"]) == 2
    assert "--across-frames must be in [0, 10]" in capsys.readouterr().err


def test_particles_that_leave_or_arrive_are_matched_by_id(tmp_path):
    # frame 1 lacks ten particles and frame 2 has a new one: the others are still followed
    x = ball()
    n = len(x)
    frames = [x, x[10:], np.vstack([x, [[0.0, 0.0, 4.5 * SPACING]]])]
    ids = [np.arange(n), np.arange(10, n), np.arange(n + 1)]
    particles = write_particles(tmp_path / "p" / "particles.pvd", frames, ids=ids)
    surface_series(particles, tmp_path / "s" / "surface.pvd", progress=False, across_frames=1,
                   **OPTIONS)
    surface_series(particles, tmp_path / "one" / "surface.pvd", progress=False, **OPTIONS)
    out, single = meshes(tmp_path / "s" / "surface.pvd"), meshes(tmp_path / "one" / "surface.pvd")
    assert len(out) == 3 and all(np.isfinite(p).all() and len(t) for p, t in out)
    # the particles that stay do not move: the surface away from those that come and go
    # (beyond the kernels' reach of them) stays within a few hundredths of a spacing (measured
    # 0.04: the volume correction of frame 1 offsets its whole piece, ten particles smaller)
    changed = np.vstack([x[:10], frames[2][-1:]])
    p0 = single[0][0]
    far = np.min(np.linalg.norm(p0[:, None] - changed[None], axis=2), axis=1) > 3 * SPACING
    assert far.sum() > 100
    np.testing.assert_allclose(out[0][0][far], single[0][0][far], atol=0.05 * SPACING)


def test_a_rewritten_series_is_read_anew_not_from_the_last_pass(tmp_path):
    # a pass keeps the frames it read (each serves 2 K + 1 tasks); a series rewritten in place
    # and filtered again must give what a first pass over it gives, not the old frames' result
    x = ball()
    moves = [np.array([0.3, 0.0, 0.0]), np.array([0.0, -0.2, 0.25])]
    series = [[x + k * m * SPACING for k in range(4)] for m in moves]
    fresh = write_particles(tmp_path / "fresh" / "particles.pvd", series[1])
    surface_series(fresh, tmp_path / "f" / "surface.pvd", progress=False, across_frames=1,
                   **OPTIONS)
    reused = tmp_path / "p" / "particles.pvd"
    for frames in series:  # the same paths, other particles the second time
        write_particles(reused, frames)
        surface_series(reused, tmp_path / "s" / "surface.pvd", progress=False, across_frames=1,
                       **OPTIONS)
    for (p, t), (q, u) in zip(meshes(tmp_path / "f" / "surface.pvd"),
                              meshes(tmp_path / "s" / "surface.pvd"), strict=True):
        np.testing.assert_array_equal(t, u)
        np.testing.assert_array_equal(p, q)
