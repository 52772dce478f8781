"""Issue 31: limits computed from the machine and the input, stated in the message, and one
line instead of a traceback (items 5, 6, 7, 8, 9, 12, 13, 14's overflows, 15)."""

import io
import json
import os
import resource
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import pyvista as pv

from filters.memory import MEMORY_ENV
from filters.surface import crowding
from filters.surface.crowding import CrowdingError, check_crowding, pair_work_limit
from pipeline.cli import main
from pipeline.cli.common import max_workers
from pipeline.io.series import SeriesWriter
from pipeline.paraview import bridge
from pipeline.render import max_views
from pipeline.surface import reconstruct
from pipeline.surface.contour import brick_chunk

ROOT = Path(__file__).resolve().parents[2]


def _env():
    return {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), os.environ.get("PYTHONPATH", "")])}


def _cli(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _one_error_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()
             and not line.startswith("blobflow: compiling")]
    assert len(lines) == 1, f"expected one line on stderr, got:\n{err}"
    assert lines[0].startswith("blobflow: error: "), lines[0]
    return lines[0]


def _cloud_series(folder: Path, frames, name="particles") -> Path:
    """A series of the given point clouds, 0.1 s apart, with ids."""
    writer = SeriesWriter(folder / f"{name}.pvd")
    for k, points in enumerate(frames):
        cloud = pv.PolyData(np.asarray(points, dtype=np.float64))
        cloud["id"] = np.arange(len(points))
        writer.write(cloud, 0.1 * k)
    return writer.path


def _grown_rss() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


# -- 5. the contour's bricks count against the surface's memory budget ---------------------------
def test_5_brick_settings_the_budget_cannot_hold_are_refused_before_any_work(
        tmp_path, capsys, monkeypatch, rng):
    series = _cloud_series(tmp_path, [rng.uniform(0, 0.05, (200, 3))] * 2)
    monkeypatch.setenv(MEMORY_ENV, "256M")
    before = _grown_rss()
    for block, brick, size in (("32", "16", "513^3"), ("64", "64", "4097^3")):
        code, _, err = _cli(capsys, "surface", series, "--out", tmp_path / "s", "--quiet",
                            "--option", f"block_size={block}", "--option", f"brick_blocks={brick}")
        assert code == 2
        line = _one_error_line(err)
        assert f"block_size * brick_blocks = {block} * {brick}" in line and size in line, line
        assert "quarter of max_bytes" in line
    assert _grown_rss() - before < 2**28 and not (tmp_path / "s").exists()
    # the bricks filled at once shrink to fit a quarter of the budget; the defaults are as before
    assert brick_chunk(32, 4 * 2**30) == 16 and brick_chunk(512, 4 * 2**30) == 1
    assert brick_chunk(128, 40 * 2**20) == 1 and brick_chunk(32, 2**21) == 3


# -- 6. crowding: quadratic work refused with the machine's limit --------------------------------
@pytest.mark.timeout(120)
def test_6_crowded_clouds_are_refused_before_the_quadratic_work(tmp_path, capsys, rng,
                                                                monkeypatch):
    # enough identical points that their pairs exceed this machine's limit (1e6 on 2 cores)
    n = max(1_000_000, int(2.0 * pair_work_limit() ** 0.5))
    start = time.monotonic()
    with pytest.raises(CrowdingError) as info:
        reconstruct(np.full((n, 3), 0.5), radius=0.01)
    message = str(info.value)
    assert f"{n:,}" in message and "core" in message and f"{pair_work_limit():.3g}" in message
    with pytest.raises(CrowdingError, match="check the radius"):  # a radius far too large
        check_crowding(rng.uniform(0, 1, (n, 3)), 4.0 * 0.5)
    assert time.monotonic() - start < 30.0  # refused, not computed
    # a liquid sampled at twice its radius passes, however large (here the pairs are counted
    # with a limit a million times lower)
    monkeypatch.setattr(crowding, "WORK_SECONDS", 60e-6)
    lattice = (np.indices((40, 40, 40)).reshape(3, -1).T + 0.5) * 0.02
    check_crowding(lattice, 4 * 0.01)
    with pytest.raises(CrowdingError):
        check_crowding(lattice, 40 * 0.01)  # ten times the radius: crowded
    # through the command line: refused before the first frame, with exit code 2
    series = _cloud_series(tmp_path, [np.full((3000, 3), 0.5)])
    code, _, err = _cli(capsys, "surface", series, "--out", tmp_path / "s", "--quiet",
                        "--radius", "0.01")
    assert code == 2 and "crowded" in _one_error_line(err)
    assert not (tmp_path / "s").exists()


# -- 7. the bridge's serving loop answers every line ----------------------------------------------
def test_7_the_bridge_answers_bad_lines_and_failures_and_carries_on(tmp_path, monkeypatch):
    good = write_good_particles(tmp_path)
    real = bridge._surface

    def surface(source, target, options_json):
        if source == "boom":
            raise MemoryError()
        return real(source, target, options_json)

    monkeypatch.setattr(bridge, "_surface", surface)
    request = {"command": "surface", "source": str(good), "target": str(tmp_path / "o.vtp"),
               "options": {"radius": 0.01, "feature_smoothing": 0, "smooth_iterations": 0}}
    lines = ["[" * 100_000 + "]" * 100_000,  # RecursionError in the JSON parser
             json.dumps({**request, "source": "boom"}),  # MemoryError in the request
             "x" * (bridge.MAX_REQUEST + 10),  # too long to hold
             "{" * 50,
             json.dumps(request)]
    out = io.StringIO()
    bridge.serve(io.StringIO("\n".join(lines) + "\n"), out)
    answers = [json.loads(line) for line in out.getvalue().splitlines()]
    assert [a["ok"] for a in answers] == [False, False, False, False, True]
    assert "RecursionError" in answers[0]["error"] and "MemoryError" in answers[1]["error"]
    assert "longer than" in answers[2]["error"]
    assert (tmp_path / "o.vtp").is_file()
    # the same in the worker process the plugin keeps
    stdin = lines[0] + "\n" + json.dumps({**request, "target": str(tmp_path / "p.vtp")}) + "\n"
    result = subprocess.run([sys.executable, "-m", "pipeline.paraview.bridge", "serve"],
                            input=stdin,
                            capture_output=True, text=True, timeout=240, env=_env())
    assert result.returncode == 0 and "Traceback" not in result.stderr
    assert [json.loads(line)["ok"] for line in result.stdout.splitlines()] == [False, True]


def write_good_particles(folder: Path) -> Path:
    from pipeline.io.series import write_frame

    x = (np.indices((5, 5, 5)).reshape(3, -1).T + 0.5) * 0.02
    return write_frame(pv.PolyData(x), folder / "good.vtp")


# -- 8. a scheduler that stalls in the middle of a handshake ---------------------------------------
def _server(reply: bytes, trickle: float = 0.0):
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen()
    held = []

    def serve():
        while True:
            try:
                conn, _ = listener.accept()
            except OSError:
                return
            held.append(conn)
            for k in range(len(reply)) if trickle else [None]:
                try:
                    conn.sendall(reply[k:k + 1] if trickle else reply)
                except OSError:
                    break
                if trickle:
                    time.sleep(trickle)

    threading.Thread(target=serve, daemon=True).start()
    return listener


@pytest.mark.timeout(120)
def test_8_a_scheduler_that_stalls_mid_handshake_is_refused_within_the_promise(tmp_path, capsys,
                                                                             monkeypatch):
    pytest.importorskip("dask.distributed")
    import pipeline.tasks

    monkeypatch.setattr(pipeline.tasks, "PROBE_TIMEOUT", 1.5)  # 5 s by default: a fast test
    series = _cloud_series(tmp_path, [np.random.default_rng(1).uniform(0, 0.1, (30, 3))])
    frames = struct.pack("<QQQ", 2, 40, 40)  # two frames of 40 bytes announced, none sent
    replies = [struct.pack("<Q", 100) + b"\x01\x02",  # a part of the first block
               struct.pack("<Q", len(frames)) + frames,  # the block, then not the frames
               struct.pack("<Q", 24) + frames]  # the same, a byte every 0.4 s (trickled)
    for k, reply in enumerate(replies):
        server = _server(reply, trickle=0.4 if k == 2 else 0.0)
        try:
            start = time.monotonic()
            code, _, err = _cli(capsys, "surface", series, "--out", tmp_path / "s", "--quiet",
                                "--scheduler", f"tcp://127.0.0.1:{server.getsockname()[1]}")
            line = _one_error_line(err)
            assert code == 2 and "not a Dask scheduler" in line and "within 1.5 s" in line, line
            assert time.monotonic() - start < 5.0
        finally:
            server.close()
    assert not (tmp_path / "s").exists()


# -- 9. a stray particle or a NaN does not blank the movie -----------------------------------------
def _stray_series(folder: Path, extra) -> Path:
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    base = np.random.default_rng(0).normal(0, 0.1, (80, 3)) + [0, 0, 0.5]
    path = _cloud_series(folder, [base, base])
    if extra is not None:  # written as another program would: blobflow refuses NaN
        cloud = pv.PolyData(np.vstack([base, extra]))
        writer = vtkXMLPolyDataWriter()
        writer.SetInputData(cloud)
        writer.SetFileName(str(folder / "particles" / "particles_000001.vtp"))
        writer.Write()
    return path


@pytest.mark.timeout(300)
def test_9_a_stray_particle_or_a_nan_leaves_the_picture_as_it_was(tmp_path, capsys):
    import imageio.v2 as imageio

    from pipeline.render import render_still

    images = {}
    for name, extra in (("clean", None), ("stray", [[1e6, 0.0, 0.0]]),
                        ("nan", [[np.nan, 0.0, 0.5]])):
        path = _stray_series(tmp_path / name, None if extra is None else np.array(extra))
        png, _ = render_still(path, tmp_path / f"{name}.png", time_index=1, size=(160, 120),
                              text=False)
        images[name] = imageio.imread(png).astype(int)
    clean = images["clean"]
    drawn = (np.abs(clean - clean[0, 0]).sum(-1) > 60).mean()
    assert drawn > 0.05  # the particles are there
    for name in ("stray", "nan"):
        assert (np.abs(images[name] - clean).sum(-1) > 30).mean() < 0.002, name
    code, _, err = _cli(capsys, "render", tmp_path / "stray" / "particles.pvd", "--out",
                        tmp_path / "m.gif", "--size", "96x64", "--quiet")
    assert code == 0, err


# -- 12. USD: no NaN, no infinity, distinct time codes ---------------------------------------------
def test_12_export_refuses_nan_inf_and_times_that_collapse(tmp_path, capsys):
    pytest.importorskip("pxr")
    good = _cloud_series(tmp_path / "good", [np.zeros((3, 3)), np.ones((3, 3))])
    for extra, needle in ((("--fps", "inf"), "fps must be in (0, 1e+06]"),
                          (("--fps", "nan"), "fps must be in"),
                          (("--radius", "inf"), "radius must be in (0, inf)")):
        code, _, err = _cli(capsys, "export", good, "--usd", tmp_path / "x.usda", *extra)
        assert code == 2 and needle in _one_error_line(err)
    nan = _stray_series(tmp_path / "nan", np.array([[np.nan, 0.0, 0.0]]))
    code, _, err = _cli(capsys, "export", nan, "--usd", tmp_path / "x.usda")
    assert code == 2 and "frame 1 has NaN or infinite points" in _one_error_line(err)
    far = 1e300  # two neighbouring doubles whose products with 30 round to one double
    while far * 30.0 != np.nextafter(far, np.inf) * 30.0:
        far = np.nextafter(far, np.inf)
    for times, needle in (((far, np.nextafter(far, np.inf)), "fall on the same time code"),
                          ((0.0, 1e308), "beyond what a double holds")):
        pvd = good.read_text().replace('timestep="0.0"', f'timestep="{float(times[0])!r}"').replace(
            'timestep="0.1"', f'timestep="{float(times[1])!r}"')
        (tmp_path / "good" / "far.pvd").write_text(pvd)
        code, _, err = _cli(capsys, "export", tmp_path / "good" / "far.pvd", "--usd",
                            tmp_path / "x.usda", "--fps", "30")
        assert code == 2 and needle in _one_error_line(err)
    assert not [p for p in tmp_path.iterdir() if p.is_file()]  # no stage, no temporary


# -- 13. unbounded resources: limits from the machine, stated --------------------------------------
@pytest.mark.timeout(120)
def test_13_limits_are_computed_from_the_machine_and_stated(tmp_path, capsys, monkeypatch, rng):
    before = _grown_rss()
    code, _, err = _cli(capsys, "run", "noise_smoke", "--frames", "2", "--out", tmp_path / "n",
                        "--no-render", "--quiet", "--set", "rate=1e12", "--set",
                        "max_particles=10000000000000")
    line = _one_error_line(err)
    assert code == 2 and "live particles" in line and "memory limit" in line, line
    assert _grown_rss() - before < 2**28 and not (tmp_path / "n").exists()
    series = _cloud_series(tmp_path, [rng.uniform(0, 0.1, (30, 3))] * 2)
    limit, why = max_workers()
    code, _, err = _cli(capsys, "surface", series, "--out", tmp_path / "s", "--quiet",
                        "--workers", "100000")
    assert code == 2 and f"more than {limit}: {why}" in _one_error_line(err)
    views, _ = max_views((640, 480), "t.gif")
    code, _, err = _cli(capsys, "render", series, "--turntable", "100000000", "--out",
                        tmp_path / "t.gif", "--quiet")
    line = _one_error_line(err)
    assert code == 2 and "100000000 views are more than" in line and str(views) in line, line
    monkeypatch.setenv(MEMORY_ENV, "8M")
    code, _, err = _cli(capsys, "render", series, "--out", tmp_path / "m.gif", "--size",
                        "1920x1080", "--quiet")
    line = _one_error_line(err)
    assert code == 2 and "a GIF holds all its images in memory" in line and "8 MiB" in line
    assert not (tmp_path / "s").exists() and not list(tmp_path.glob("*.gif"))


@pytest.mark.timeout(300)
def test_13_info_holds_one_frame_at_a_time(tmp_path):
    rng = np.random.default_rng(5)
    series = _cloud_series(tmp_path, [rng.uniform(0, 1, (250_000, 3)) for _ in range(12)])
    code = ("import resource, sys\nfrom pipeline.cli import main\n"
            "import pyvista, numpy\nbase = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
            "assert main(['info', sys.argv[1]]) == 0\n"
            "print('GROWN', (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base) * 1024)\n")
    result = subprocess.run([sys.executable, "-c", code, str(series)], capture_output=True,
                            text=True, timeout=240, env=_env())
    assert result.returncode == 0, result.stderr
    grown = int(next(line for line in result.stdout.splitlines()
                     if line.startswith("GROWN")).split()[1])
    frame = 250_000 * (24 + 8)  # points and ids of one frame
    assert grown < 6 * frame  # all 12 frames at once: 18 (measured 144 MiB before, 39 after)
    assert "12 frames" in result.stdout


# -- 14. overflows, names too long, encoders: one line ---------------------------------------------
def test_14_overflows_long_names_and_encoder_limits_are_one_line(tmp_path, capsys, rng):
    series = _cloud_series(tmp_path / "a", [rng.uniform(0, 0.1, (30, 3))] * 3)
    long = "n" * 300
    cases = [
        (("run", "bouncing", "--duration", "1e308", "--out", tmp_path / "o", "--no-render"),
         "frames than can be counted"),
        (("run", "bouncing", "--frames", "2", "--out", tmp_path / long, "--no-render"),
         "File name too long"),
        (("surface", series, "--out", tmp_path / "s", "--name", long), "file system's limit"),
        (("render", series, "--fps", "1e-9", "--out", tmp_path / "m.mp4"),
         "--fps must be in [0.01, 1000]"),
        (("render", series, "--fps", "1e9", "--out", tmp_path / "m.mp4"),
         "--fps must be in [0.01, 1000]"),
        (("render", series, "--orbit", "inf", "--out", tmp_path / "m.mp4"), "--orbit"),
    ]
    pvd = series.read_text()
    (tmp_path / "a" / "big.pvd").write_text(pvd.replace('timestep="0.1"', 'timestep="1e400"'))
    (tmp_path / "a" / "deep.series").write_text("[" * 100_000)
    (tmp_path / "a" / "huge.series").write_text(json.dumps({"files": [
        {"name": "particles/particles_000000.vtp", "time": 10**400}]}))
    for name, needle in (("big.pvd", "frame times must be finite"),
                         ("deep.series", "not a valid series file"),
                         ("huge.series", "not a valid series file")):
        cases.append((("info", tmp_path / "a" / name), needle))
    for argv, needle in cases:
        code, _, err = _cli(capsys, *argv)
        assert code == 2, (argv, err)
        assert needle in _one_error_line(err), (argv, err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a"]


# -- 15. input mistakes are refused before the first frame -----------------------------------------
@pytest.mark.timeout(120)
def test_15_input_mistakes_are_refused_before_the_first_frame(tmp_path, capsys, rng):
    points = [rng.uniform(0, 0.1, (40, 3)) for _ in range(3)]
    series = _cloud_series(tmp_path / "in", points)
    no_ids = tmp_path / "noid" / "p.pvd"
    writer = SeriesWriter(no_ids)
    for k, p in enumerate(points):
        writer.write(pv.PolyData(p), 0.1 * k)
    for source, extra, needle in (
            (series, ("--radius", "inf"), "radius must be in (0, inf), got inf"),
            (series, ("--cell-size", "1e-9"), "cell_size = 1e-09 m is too small"),
            (series, ("--radius", "1e-300"), "more than the 2096890"),
            (no_ids, ("--across-frames", "2"), "'id' point array, which frame 0")):
        start = time.monotonic()
        code, _, err = _cli(capsys, "surface", source, "--out", tmp_path / "s", "--quiet", *extra)
        assert code == 2, err
        line = _one_error_line(err)
        assert needle in line and "--resume" not in line, line
        assert time.monotonic() - start < 20.0
    assert not (tmp_path / "s").exists()
