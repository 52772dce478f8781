"""Hostile and careless input: every defect of the reliability review, reproduced and fixed.

Each numbered test reproduces one finding (resume deleting outside its folder, huge frame counts,
truncated frames read as empty, a non-Dask scheduler, tracebacks instead of one line, ``surface``
overwriting its input, memory refused only after it is spent, VTK noise, another scene's folder).
The far-apart-points findings (splat, noise) are tested in test_splat.py and test_noise.py.
"""

import http.server
import json
import re
import socket
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import pyvista as pv
from _helpers import ballistic, failing_ballistic

from filters.memory import MEMORY_ENV, MemoryLimitError, check_memory, format_bytes
from pipeline import Flow, SimulationSource
from pipeline.cli import main
from pipeline.io.series import SeriesError, SeriesWriter, read_frame, read_series, write_frame
from pipeline.scene import Scene, available_scenes, load_scene


def _cli(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _one_error_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, f"expected one line on stderr, got:\n{err}"
    assert lines[0].startswith("blobflow: error: ")
    return lines[0]


def _bouncing(tmp_path, capsys, name="run", *extra):
    out = tmp_path / name
    code, _, err = _cli(capsys, "run", "bouncing", "--duration", "0.1", "--out", out,
                        "--no-render", "--quiet", "--set", "count=2", *extra)
    assert code == 0, err
    return out


def _tree(folder: Path) -> dict:
    """Every file below ``folder`` with its bytes (to show that nothing changed)."""
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# -- 1. resume must never delete outside its folder ----------------------------------------------
def test_1_resume_never_deletes_files_a_collection_points_outside_its_folder(tmp_path, capsys):
    out = _bouncing(tmp_path, capsys)
    victim = tmp_path / "victim.txt"
    absolute = tmp_path / "elsewhere" / "absolute.txt"
    absolute.parent.mkdir()
    victim.write_text("keep me")
    absolute.write_text("keep me too")
    pvd = out / "particles.pvd"
    text = pvd.read_text().replace("  </Collection>", (
        '    <DataSet timestep="0.133333333" group="" part="0" file="../victim.txt"/>\n'
        f'    <DataSet timestep="0.166666667" group="" part="0" file="{absolute}"/>\n'
        "  </Collection>"))
    pvd.write_text(text)
    before = _tree(out)
    code, _, err = _cli(capsys, "run", "bouncing", "--duration", "0.1", "--out", out,
                        "--no-render", "--quiet", "--set", "count=2", "--resume")
    assert code == 2
    assert "../victim.txt" in _one_error_line(err)
    assert victim.read_text() == "keep me" and absolute.read_text() == "keep me too"
    assert _tree(out) == before


def test_1_series_writer_refuses_foreign_entries_and_truncates_only_its_own(tmp_path):
    path = tmp_path / "s.pvd"
    writer = SeriesWriter(path)
    for t in (0.0, 0.5):
        writer.write(pv.PolyData(np.zeros((2, 3))), t)
    outside = tmp_path / "outside.vtp"
    outside.write_text("x")
    writer.entries.append((1.0, "../outside.vtp"))  # as if the collection had been edited
    with pytest.raises(SeriesError, match="outside"):
        writer.truncate(1)
    assert outside.exists()
    writer.entries.pop()
    writer._write_collections()
    text = path.read_text().replace("s/s_000001.vtp", "/etc/hostname")
    path.write_text(text)
    with pytest.raises(SeriesError, match="not written by blobflow"):
        SeriesWriter(path, resume=True)


# -- 2. huge frame counts refused before any allocation -------------------------------------------
@pytest.mark.timeout(60)
@pytest.mark.parametrize("args", [("--frames", "1000000000000"),
                                  ("--fps", "1e12", "--duration", "1"),
                                  ("--fps", "1000", "--duration", "1e9")])
def test_2_huge_frame_counts_are_refused_up_front(tmp_path, capsys, args):
    out = tmp_path / "huge"
    code, _, err = _cli(capsys, "run", "bouncing", "--out", out, "--no-render", "--quiet", *args)
    assert code == 2
    assert re.search(r"frames|fps", _one_error_line(err))
    assert not out.exists()


# -- 3. a truncated frame is an error, never an empty frame ---------------------------------------
def test_3_truncated_frame_is_refused_by_info_render_and_surface(tmp_path, capsys):
    out = _bouncing(tmp_path, capsys)
    frame = out / "particles" / "particles_000002.vtp"
    data = frame.read_bytes()
    frame.write_bytes(data[: len(data) // 2])
    for argv in (("info", out / "particles.pvd"),
                 ("render", out / "particles.pvd", "--out", tmp_path / "r.gif", "--turntable", "2",
                  "--quiet"),
                 ("surface", out / "particles.pvd", "--out", tmp_path / "surf", "--quiet")):
        code, _, err = _cli(capsys, *argv)
        assert code == 2, argv
        assert "particles_000002.vtp" in _one_error_line(err)
    assert not (tmp_path / "r.gif").exists() and not (tmp_path / "surf").exists()


def _same_frame(a, b) -> bool:
    """Same points and the same array values in order (a flipped byte may rename an array)."""
    if a.n_points != b.n_points or not np.array_equal(a.points, b.points):
        return False
    return all(np.array_equal(a.point_data[x], b.point_data[y])
               for x, y in zip(a.point_data.keys(), b.point_data.keys(), strict=False))


def test_3_fuzz_series_reader_truncations_and_byte_flips(tmp_path, rng):
    """Truncations at 20 offsets and 200 random bit flips of a real frame: each read is either a
    clear SeriesError or the original frame, never a crash, a hang or a silently short frame."""
    original = pv.PolyData(rng.random((300, 3)))
    original["velocity"] = rng.random((300, 3))
    original["id"] = np.arange(300)
    path = write_frame(original, tmp_path / "f.vtp")
    data = path.read_bytes()
    reference = pv.wrap(read_frame(path))
    assert _same_frame(reference, original)
    probe = tmp_path / "probe.vtp"
    outcomes = {"error": 0, "same": 0}
    cases = [data[:cut] for cut in np.linspace(0, len(data) - 1, 20).astype(int)]
    for _ in range(200):
        flipped = bytearray(data)
        flipped[rng.integers(len(data))] ^= 1 << int(rng.integers(8))
        cases.append(bytes(flipped))
    for case in cases:
        probe.write_bytes(case)
        try:
            frame = pv.wrap(read_frame(probe))
        except SeriesError as exc:
            assert str(probe) in str(exc)
            outcomes["error"] += 1
            continue
        assert _same_frame(frame, original), "a damaged frame was read as a different frame"
        outcomes["same"] += 1
    assert outcomes["error"] >= 19  # all truncations but (at most) the closing tags


# -- 4. a scheduler address that is not Dask ------------------------------------------------------
@pytest.mark.timeout(60)
def test_4_scheduler_that_is_not_dask_is_refused_quickly(tmp_path, capsys):
    pytest.importorskip("dask.distributed")
    out = _bouncing(tmp_path, capsys)
    http_server = http.server.ThreadingHTTPServer(("127.0.0.1", 0),
                                                  http.server.BaseHTTPRequestHandler)
    threading.Thread(target=http_server.serve_forever, daemon=True).start()
    talker = socket.socket()
    talker.bind(("127.0.0.1", 0))
    talker.listen()

    def talk():
        while True:
            try:
                conn, _ = talker.accept()
            except OSError:
                return
            conn.sendall(b"SSH-2.0-OpenSSH_9.2\r\n" * 4)

    threading.Thread(target=talk, daemon=True).start()
    try:
        for port in (http_server.server_address[1], talker.getsockname()[1]):
            start = time.monotonic()
            code, _, err = _cli(capsys, "surface", out / "particles.pvd", "--out",
                                tmp_path / "s", "--quiet", "--scheduler", f"tcp://127.0.0.1:{port}")
            assert code == 2
            assert "not a Dask scheduler" in _one_error_line(err)
            assert time.monotonic() - start < 10.0
    finally:
        http_server.shutdown()
        talker.close()
    assert not (tmp_path / "s").exists()


# -- 5. one line and exit 2 instead of tracebacks -------------------------------------------------
@pytest.mark.parametrize("folder", ["/sys/blobflow-test", "/proc/blobflow-test"])
def test_5_output_folder_that_cannot_be_created(tmp_path, capsys, folder):
    if not Path(folder).parent.is_dir():
        pytest.skip(f"{Path(folder).parent} does not exist here")
    code, _, err = _cli(capsys, "run", "bouncing", "--frames", "2", "--out", folder, "--no-render",
                        "--quiet")
    assert code == 2 and "cannot be written" in _one_error_line(err)


@pytest.mark.parametrize("damage", ["garbage", "dat_frame", "other_fps", "longer_record"])
def test_5_resume_over_a_damaged_or_different_run(tmp_path, capsys, damage):
    out = _bouncing(tmp_path, capsys)
    pvd = out / "particles.pvd"
    if damage == "garbage":
        pvd.write_text("<<< not xml")
    elif damage == "dat_frame":
        pvd.write_text(pvd.read_text().replace("particles_000003.vtp", "particles_000003.dat"))
    before = _tree(out)
    extra = ("--fps", "20") if damage == "other_fps" else ()
    if damage == "longer_record":  # the series has more frames than the resumed run would make
        extra = ("--duration", "0.05")
        argv = ("run", "bouncing", "--out", out, "--no-render", "--quiet", "--resume", *extra)
    else:
        argv = ("run", "bouncing", "--duration", "0.1", "--out", out, "--no-render", "--quiet",
                "--resume", *extra)
    code, _, err = _cli(capsys, *argv)
    assert code == 2, err
    _one_error_line(err)
    assert _tree(out) == before  # scene.json keeps the fps of the run on disk
    code, _, err = _cli(capsys, "run", "bouncing", "--duration", "0.1", "--out", out,
                        "--no-render", "--quiet", "--resume")
    assert code == (2 if damage in ("garbage", "dat_frame") else 0), err


def test_5_jello_mesh_that_is_missing_or_not_a_mesh(tmp_path, capsys):
    not_a_mesh = tmp_path / "notes.stl"
    not_a_mesh.write_text("these are my notes")
    for mesh in (tmp_path / "missing.stl", not_a_mesh):
        code, _, err = _cli(capsys, "run", "jello_drop", "--set", f"mesh={mesh}", "--frames", "2",
                            "--out", tmp_path / "j", "--no-render", "--quiet")
        assert code == 2
        assert "mesh" in _one_error_line(err)
    assert not (tmp_path / "j").exists()


@pytest.mark.parametrize("times", [("0.1", "0.1"), ("0.1", "0.05"), ("0.1", "nan"),
                                   ("0.1", "inf")])
def test_5_render_refuses_bad_frame_times(tmp_path, capsys, times):
    out = _bouncing(tmp_path, capsys)
    pvd = out / "particles.pvd"
    pvd.write_text(pvd.read_text().replace('timestep="0.033333333"', f'timestep="{times[0]}"')
                   .replace('timestep="0.066666667"', f'timestep="{times[1]}"'))
    code, _, err = _cli(capsys, "render", pvd, "--out", tmp_path / "m.mp4", "--quiet")
    assert code == 2 and "frame times must be finite and increasing" in _one_error_line(err)
    assert not (tmp_path / "m.mp4").exists()


# -- 6. surface never overwrites its input, never writes outside --out -----------------------------
def test_6_surface_refuses_to_overwrite_its_input_or_escape_out(tmp_path, capsys):
    out = _bouncing(tmp_path, capsys)
    before = _tree(out)
    for argv in (("--out", out, "--name", "particles"),
                 ("--out", tmp_path / "s", "--name", "../x"),
                 ("--out", tmp_path / "s", "--name", "/abs")):
        code, _, err = _cli(capsys, "surface", out / "particles.pvd", *argv, "--quiet")
        assert code == 2, argv
        _one_error_line(err)
    assert _tree(out) == before
    assert not (tmp_path / "s").exists() and not (tmp_path / "x").exists()


def test_6_surface_with_a_missing_frame_writes_nothing(tmp_path, capsys):
    out = _bouncing(tmp_path, capsys)
    (out / "particles" / "particles_000003.vtp").unlink()
    code, _, err = _cli(capsys, "surface", out / "particles.pvd", "--out", tmp_path / "s",
                        "--quiet")
    assert code == 2 and "particles_000003.vtp" in _one_error_line(err)
    assert not (tmp_path / "s").exists()


# -- 8. memory estimated and refused before it is spent --------------------------------------------
@pytest.mark.timeout(60)
@pytest.mark.parametrize("scene, sets", [
    ("dam_break", ("spacing=0.0004",)),
    ("hair", ("strands=100000", "segments=256")),
])
def test_8_oversized_scenes_are_refused_before_allocating(tmp_path, capsys, scene, sets):
    import resource

    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    argv = ["run", scene, "--frames", "2", "--out", tmp_path / "big", "--no-render", "--quiet"]
    for s in sets:
        argv += ["--set", s]
    code, _, err = _cli(capsys, *argv)
    assert code == 2
    line = _one_error_line(err)
    assert "memory limit" in line and "GiB" in line and MEMORY_ENV in line
    grown = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) * 1024
    assert grown < 2**30
    assert not (tmp_path / "big").exists()


def test_8_memory_limit_is_overridable_and_messages_name_sizes(monkeypatch):
    monkeypatch.setenv(MEMORY_ENV, "1.5M")
    with pytest.raises(MemoryLimitError, match=r"needs about 1.91 MiB, above the memory limit "
                                               r"of 1.5 MiB \(BLOBFLOW_MAX_MEMORY\)"):
        check_memory("a test", 2e6)
    check_memory("a test", 1e6)
    monkeypatch.setenv(MEMORY_ENV, "lots")
    with pytest.raises(ValueError, match=MEMORY_ENV):
        check_memory("a test", 1)
    assert [format_bytes(n) for n in (0, 512, 3 * 2**20, 1.5 * 2**40)] == [
        "0 B", "512 B", "3 MiB", "1.5 TiB"]


def test_8_surface_budget_is_checked_against_the_machine_before_any_frame(tmp_path, capsys,
                                                                          monkeypatch):
    out = _bouncing(tmp_path, capsys)
    monkeypatch.setenv(MEMORY_ENV, "64M")
    code, _, err = _cli(capsys, "surface", out / "particles.pvd", "--out", tmp_path / "s",
                        "--option", f"max_bytes={2**30}", "--quiet")
    assert code == 2
    line = _one_error_line(err)
    assert "1 GiB" in line and "64 MiB" in line and MEMORY_ENV in line
    assert not (tmp_path / "s").exists()
    # left at its default, the budget shrinks to the limit instead of being refused
    code, _, err = _cli(capsys, "surface", out / "particles.pvd", "--out", tmp_path / "s",
                        "--quiet")
    assert code == 0, err


# -- 9. failures are one message, not pages of VTK text --------------------------------------------
def _fake_scene(monkeypatch, simulation):
    def build():
        return Flow(SimulationSource(simulation, fps=10.0, duration=1.0))

    scene = Scene("fake", build, "a scene for tests", fps=10.0, duration=1.0)
    monkeypatch.setattr("pipeline.scene.load_scene", lambda name: scene)
    return scene


class _Interrupting(type(ballistic())):
    def _step(self, dt):
        if self.state.time > 0.25:
            raise KeyboardInterrupt
        super()._step(dt)


@pytest.mark.parametrize("kind", ["unstable", "interrupt"])
def test_9_failures_print_one_message_without_vtk_text(tmp_path, capfd, monkeypatch, kind):
    if kind == "unstable":
        sim = failing_ballistic(fail_after=0.25)
    else:
        base = ballistic()
        sim = _Interrupting(base.state.positions, base.state.velocities, max_dt=1 / 100)
    _fake_scene(monkeypatch, sim)
    code = main(["run", "fake", "--out", str(tmp_path / "f"), "--no-render", "--quiet"])
    _, err = capfd.readouterr()
    assert code == (1 if kind == "unstable" else 130)
    lines = [line for line in err.splitlines() if line.strip()]
    assert 1 <= len(lines) <= 2 and all(line.startswith("blobflow: ") for line in lines), err
    assert "vtk" not in err.lower()
    times, _ = read_series(tmp_path / "f" / "particles.pvd")
    assert len(times) == 3  # 0, 0.1, 0.2 written before the failure, all readable


def test_9_failed_surface_frames_are_named_without_vtk_text(tmp_path, capfd):
    out = tmp_path / "run"
    assert main(["run", "bouncing", "--duration", "0.1", "--out", str(out), "--no-render",
                 "--quiet"]) == 0
    capfd.readouterr()
    # a budget that holds one brick (refused up front below that, since issue 31) but not the
    # grid and its brick images
    code = main(["surface", str(out / "particles.pvd"), "--out", str(tmp_path / "s"), "--quiet",
                 "--option", "max_bytes=600000"])
    _, err = capfd.readouterr()
    assert code == 1
    assert "frame" in err and "vtk" not in err.lower()
    assert len([line for line in err.splitlines() if line.strip()]) <= 8


# -- 10. an output folder holding another scene's run ----------------------------------------------
def test_10_folder_of_another_scene_is_refused_and_reruns_leave_nothing_stale(tmp_path, capsys):
    out = _bouncing(tmp_path, capsys)
    before = _tree(out)
    code, _, err = _cli(capsys, "run", "hair", "--frames", "2", "--out", out, "--no-render",
                        "--quiet")
    assert code == 2 and "bouncing" in _one_error_line(err)
    assert _tree(out) == before
    (out / "turntable.gif").write_bytes(b"old render")
    (out / "movie.mp4").write_bytes(b"old render")
    record = json.loads((out / "scene.json").read_text())
    record["outputs"].append("surface")  # as if the previous run had written a surface too
    (out / "scene.json").write_text(json.dumps(record))
    (out / "surface").mkdir()
    (out / "surface" / "surface_000000.vtp").write_text("old")
    (out / "surface.pvd").write_text("old")
    notes = out / "my_notes.txt"
    notes.write_text("mine")
    _bouncing(tmp_path, capsys)
    left = sorted(p.name for p in out.iterdir())
    assert left == ["colliders.vtp", "my_notes.txt", "particles", "particles.checkpoint.npz",
                    "particles.pvd", "particles.vtp.series", "scene.json"]  # colliders.vtp: the
    # new run's floor; the checkpoint: the new run's (pipeline.io.checkpoint)


# -- property test: bad --set values for every parameter of every scene ----------------------------
def _bad_values(parameter) -> list[str]:
    """Values that no parameter of this kind and documented range may accept."""
    kind, doc = parameter.kind, parameter.doc
    values = {"bool": ["maybe", "2", ""], "int": ["1.5", "ten", "1e400", ""],
              "float": ["nan", "inf", "-inf", "1e", "x", ""],
              "vector": ["1,2", "a,b,c", "nan,0,0", "1,2,3,4"],
              "str": []}[kind]
    if kind in ("int", "float"):
        if re.search(r"(^|[^<])>=? ?0\b|\(0, |\[0, |positive", doc):
            values.append("-1")
        match = re.search(r"(?:in|from) [\[(]\s*(-?[\d.e+-]+)\s*(?:,| to)"
                          r"\s*(-?[\d.e+-]+)\s*[\])]", doc)
        if match:
            values.append(repr(float(match.group(2)) * 10 + 10))
    if parameter.name == "mesh":
        values.append("/nonexistent/mesh.stl")
    return values


def _scene_parameters():
    for name in available_scenes():
        for parameter in load_scene(name).parameters.values():
            yield name, parameter


@pytest.mark.timeout(300)
def test_bad_set_values_for_every_scene_parameter_exit_2_with_one_line(tmp_path, capsys, rng):
    checked = 0
    for scene, parameter in _scene_parameters():
        values = _bad_values(parameter)
        if len(values) > 3:  # a random sample keeps the test fast; the seed keeps it repeatable
            values = list(rng.choice(values, 3, replace=False))
        for value in values:
            out = tmp_path / f"{scene}-{parameter.name}"
            code, _, err = _cli(capsys, "run", scene, "--frames", "1", "--out", out,
                                "--no-render", "--quiet", "--set", f"{parameter.name}={value}")
            assert code == 2, f"{scene} --set {parameter.name}={value!r} was accepted"
            line = _one_error_line(err)
            assert parameter.name in line, line
            assert not out.exists(), f"{scene} --set {parameter.name}={value!r} wrote {out}"
            checked += 1
    assert checked > 50
