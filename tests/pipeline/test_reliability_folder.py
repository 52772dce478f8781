"""Issue 31: the output folder is blobflow's alone (items 1, 2, 3, 10, 11 and 14's temporary
files). Each test reproduces a finding as the review did and asserts the user's files survive,
the exit code and the message."""

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pipeline.cli import main
from pipeline.io.folderlock import LOCK_NAME, lock_owner
from pipeline.io.outfiles import is_temporary_name, sweep_temporaries, temporary_path
from pipeline.io.series import read_series, validate_series

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).parent


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


def _bouncing(tmp_path, capsys, name="run", *extra, duration="0.1"):
    out = tmp_path / name
    code, _, err = _cli(capsys, "run", "bouncing", "--duration", duration, "--out", out,
                        "--no-render", "--quiet", "--set", "count=2", *extra)
    assert code == 0, err
    return out


def _tree(folder: Path) -> dict:
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and not p.is_symlink()}


# -- 1. only what blobflow wrote is removed -----------------------------------------------------
def test_1_surface_and_run_keep_the_users_files_beside_their_frames(tmp_path, capsys):
    run = _bouncing(tmp_path, capsys)
    water = tmp_path / "proj" / "water"
    water.mkdir(parents=True)
    mine = {"water_final.blend": "x", "water_notes.txt": "notes", "water_000001.vtp.orig": "o",
            "water_1.vtk": "legacy"}
    for name, text in mine.items():
        (water / name).write_text(text)
    for extra in ((), ("--across-frames", "1")):  # twice: a fresh run over its own frames
        code, _, err = _cli(capsys, "surface", run / "particles.pvd", "--out", tmp_path / "proj",
                            "--name", "water", "--quiet", *extra)
        assert code == 0, err
        assert {n: (water / n).read_text() for n in mine} == mine
        assert len(list(water.glob("water_0000*.vtp"))) == 4
    # a rerun of the scene clears its frames, never the user's file in its frames folder
    (run / "particles" / "particles_notes.txt").write_text("mine")
    (run / "particles" / "particles_7.vtp.bak").write_text("mine too")
    _bouncing(tmp_path, capsys)
    assert (run / "particles" / "particles_notes.txt").read_text() == "mine"
    assert (run / "particles" / "particles_7.vtp.bak").read_text() == "mine too"
    assert len(validate_series(run / "particles.pvd")) == 4


# -- 2. one writer per output folder -------------------------------------------------------------
def _holder(folder: Path) -> subprocess.Popen:
    """A process holding the lock of ``folder`` until killed."""
    code = ("import sys, time\nfrom pipeline.io.folderlock import lock_folder\n"
            "with lock_folder(sys.argv[1]):\n    print('held', flush=True)\n    time.sleep(120)\n")
    process = subprocess.Popen([sys.executable, "-c", code, str(folder)], stdout=subprocess.PIPE,
                               text=True, env=_env())
    assert process.stdout.readline().strip() == "held"
    return process


def test_2_a_second_writer_is_refused_with_a_message_naming_the_first(tmp_path, capsys):
    run = _bouncing(tmp_path, capsys)
    holder = _holder(run)
    try:
        before = _tree(run)
        owner = lock_owner(run)
        assert owner["pid"] == holder.pid and owner["host"] == socket.gethostname()
        for argv in (("run", "bouncing", "--duration", "0.1", "--out", run, "--no-render",
                      "--quiet", "--set", "count=2"),
                     ("run", "bouncing", "--duration", "0.2", "--out", run, "--no-render",
                      "--quiet", "--resume"),
                     ("surface", run / "particles.pvd", "--out", run, "--name", "surface",
                      "--quiet")):
            code, _, err = _cli(capsys, *argv)
            assert code == 2, err
            line = _one_error_line(err)
            assert f"pid {holder.pid} on host {socket.gethostname()}" in line, line
            assert "being written by" in line
        assert _tree(run) == before
    finally:
        holder.kill()
        holder.wait()
    # killed with SIGKILL: its lock file stays, but no process holds it: recovered
    assert (run / LOCK_NAME).exists()
    _bouncing(tmp_path, capsys)
    assert not (run / LOCK_NAME).exists()


@pytest.mark.timeout(240)
def test_2_two_runs_started_into_one_folder_leave_one_valid_series(tmp_path):
    out = tmp_path / "cc"
    argv = [sys.executable, "-m", "pipeline", "run", "bouncing", "--duration", "1.5", "--out",
            str(out), "--no-render", "--quiet"]
    first = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=_env())
    deadline = time.monotonic() + 120
    while not (out / LOCK_NAME).exists():
        assert first.poll() is None and time.monotonic() < deadline, first.communicate()
        time.sleep(0.02)
    second = subprocess.run(argv, capture_output=True, text=True, env=_env(), timeout=120)
    assert second.returncode == 2, second.stderr
    assert f"pid {first.pid}" in second.stderr
    _, err = first.communicate(timeout=180)
    assert first.returncode == 0, err
    times, frames = read_series(out / "particles.pvd")  # every frame there and readable
    assert len(times) == 46 and len({f.n_points for f in frames}) == 1 and frames[0].n_points
    assert not [p for p in out.rglob("*") if is_temporary_name(p.name)]


def test_2_temporary_names_are_unique_per_process_and_swept_after_a_crash(tmp_path):
    target = tmp_path / "particles.pvd"
    here = {temporary_path(target).name for _ in range(50)}
    assert len(here) == 50 and all(is_temporary_name(n) for n in here)
    assert all(f"-{os.getpid()}-" in n and n.endswith(".tmp.pvd") for n in here)
    code = ("import sys\nfrom pathlib import Path\n"
            "from pipeline.io.outfiles import temporary_path\n"
            "p = temporary_path(Path(sys.argv[1]))\np.write_text('half')\nprint(p.name)\n")
    other = subprocess.run([sys.executable, "-c", code, str(target)], capture_output=True,
                           text=True, env=_env(), check=True).stdout.strip()
    assert other not in here and is_temporary_name(other)
    live = temporary_path(target)
    live.write_text("being written")
    user = tmp_path / ".particles.pvd.tmp"  # a name like ours, but not ours
    user.write_text("mine")
    assert sweep_temporaries(tmp_path) == 1  # the dead process's file only
    assert not (tmp_path / other).exists() and live.exists() and user.exists()


PVPYTHON = shutil.which("pvpython")


@pytest.mark.paraview
@pytest.mark.timeout(400)
@pytest.mark.skipif(PVPYTHON is None, reason="pvpython not found (Debian's 'paraview')")
def test_2_paraview_sources_sharing_a_cache_folder_wait_for_each_other(tmp_path):
    """The plugin's scene source starts ``blobflow run --resume`` into its cache folder; while
    another writer holds that folder (here a run paused with SIGSTOP, as another source's run
    would be) the refused source waits and shows that run's frames instead of failing or
    deleting them; two sources on one folder both see every frame."""
    folder = tmp_path / "cache"
    argv = [sys.executable, "-m", "pipeline", "run", "bouncing", "--out", str(folder), "--fps",
            "10.0", "--duration", "0.5", "--no-render", "--quiet", "--resume", "--set",
            "count=2"]
    writer = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=_env())
    deadline = time.monotonic() + 120
    while lock_owner(folder) is None:
        assert writer.poll() is None and time.monotonic() < deadline
        time.sleep(0.01)
    os.kill(writer.pid, signal.SIGSTOP)  # holds the folder, writes nothing
    env = {"PATH": "/usr/bin:/bin", "BLOBFLOW_PYTHON": sys.executable, "HOME": str(tmp_path),
           "PYTHONPATH": ""}
    for name in ("NUMBA_NUM_THREADS", "NUMBA_CACHE_DIR"):
        if name in os.environ:
            env[name] = os.environ[name]
    probe = subprocess.Popen([PVPYTHON, str(HERE / "paraview_shared_probe.py"),
                              str(ROOT / "pipeline" / "paraview" / "startup.py"), str(folder)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        # the source's own run is refused (its log says by whom) and the source waits ...
        deadline = time.monotonic() + 240
        while "being written by" not in "".join(
                p.read_text() for p in folder.glob("paraview-run.*.log")):
            assert probe.poll() is None and time.monotonic() < deadline, probe.communicate()
            time.sleep(0.05)
        time.sleep(2.0)
        assert probe.poll() is None  # ... instead of failing or running over the other
    finally:
        os.kill(writer.pid, signal.SIGCONT)
    out, err = probe.communicate(timeout=240)
    assert probe.returncode == 0, (out + err)[-3000:]
    writer.wait(timeout=120)
    assert writer.returncode == 0
    seen = json.loads(next(line for line in out.splitlines()
                           if line.startswith("PROBE "))[len("PROBE "):])
    times, frames = read_series(folder / "particles.pvd")
    assert list(times) == [0.0, 0.1, 0.2, 0.3, 0.4, 0.5]
    for source in ("first", "second"):
        for step in seen[source]:
            k = list(times).index(step["time"])
            assert step["points"] == 8 == frames[k].n_points
            assert step["z_mean"] == pytest.approx(float(frames[k].points[:, 2].mean()),
                                                   abs=1e-12)


# -- 3. a symbolic link or a file in place of a frames folder ------------------------------------
def test_3_a_linked_or_foreign_frames_folder_is_refused_not_followed(tmp_path, capsys):
    other = _bouncing(tmp_path, capsys, "other")
    third = _bouncing(tmp_path, capsys, "third")
    before = _tree(other)
    new = tmp_path / "new"
    new.mkdir()
    (new / "particles").symlink_to(Path("..") / "other" / "particles")
    for argv in (("run", "bouncing", "--duration", "0.1", "--out", new, "--no-render",
                  "--quiet", "--set", "count=2"),
                 ("surface", third / "particles.pvd", "--out", new, "--name", "particles",
                  "--quiet")):
        code, _, err = _cli(capsys, *argv)
        assert code == 2
        assert "is a symbolic link" in _one_error_line(err)
    assert _tree(other) == before and sorted(p.name for p in new.iterdir()) == ["particles"]
    # a run whose frames folder was replaced by a link is not resumed into the link's target
    shutil.rmtree(new)
    _bouncing(tmp_path, capsys, "new")
    shutil.rmtree(new / "particles")
    (new / "particles").symlink_to(other / "particles")
    code, _, err = _cli(capsys, "run", "bouncing", "--duration", "0.2", "--out", new,
                        "--no-render", "--quiet", "--resume")
    assert code == 2 and "is a symbolic link" in _one_error_line(err)
    assert _tree(other) == before
    # a file where the frames folder goes
    filed = tmp_path / "filed"
    filed.mkdir()
    (filed / "particles").write_text("my file")
    code, _, err = _cli(capsys, "run", "bouncing", "--frames", "2", "--out", filed,
                        "--no-render", "--quiet")
    assert code == 2 and "is not a folder" in _one_error_line(err)
    assert (filed / "particles").read_text() == "my file"


# -- 10. surface --resume keeps only frames computed from this input and these options -----------
def test_10_surface_resume_refuses_frames_of_another_input_or_other_options(tmp_path, capsys):
    a = _bouncing(tmp_path, capsys, "a")
    b = _bouncing(tmp_path, capsys, "b", "--set", "seed=7")
    s = tmp_path / "s"
    code, _, err = _cli(capsys, "surface", a / "particles.pvd", "--out", s, "--quiet")
    assert code == 0, err
    before = _tree(s)
    for argv, needle in (((b / "particles.pvd",), "from another input"),
                         ((a / "particles.pvd", "--radius", "0.02"), "with other options (radius"),
                         ((a / "particles.pvd", "--across-frames", "1"), "--across-frames 0")):
        code, _, err = _cli(capsys, "surface", *argv, "--out", s, "--quiet", "--resume")
        assert code == 2, argv
        line = _one_error_line(err)
        assert needle in line and "run without --resume" in line, line
        assert _tree(s) == before
    code, out, err = _cli(capsys, "surface", a / "particles.pvd", "--out", s, "--quiet",
                          "--resume")
    assert code == 0 and "0 frames computed, 4 kept" in out, err
    later = (a / "particles" / "particles_000002.vtp").stat().st_mtime_ns + 10**9
    os.utime(a / "particles" / "particles_000002.vtp", ns=(later, later))  # rewritten since
    code, _, err = _cli(capsys, "surface", a / "particles.pvd", "--out", s, "--quiet",
                        "--resume")
    assert code == 2 and "particles/particles_000002.vtp changed" in _one_error_line(err)
    code, out, err = _cli(capsys, "surface", a / "particles.pvd", "--out", s, "--quiet")
    assert code == 0 and "4 frames computed" in out, err


# -- 11. a checkpoint that does not fit the scene changes nothing ----------------------------------
def test_11_a_checkpoint_that_does_not_fit_is_refused_and_the_right_resume_still_works(
        tmp_path, capsys):
    out = _bouncing(tmp_path, capsys)
    record = json.loads((out / "scene.json").read_text())
    del record["parameters"]["count"]  # as written by a version without that parameter
    (out / "scene.json").write_text(json.dumps(record))
    before = _tree(out)
    code, _, err = _cli(capsys, "run", "bouncing", "--duration", "0.2", "--out", out,
                        "--no-render", "--quiet", "--resume", "--set", "count=3")
    assert code == 2
    line = _one_error_line(err)
    assert "does not fit scene 'bouncing'" in line and "27" in line and "8" in line, line
    assert _tree(out) == before  # scene.json untouched: the right resume is not refused
    code, _, err = _cli(capsys, "run", "bouncing", "--duration", "0.2", "--out", out,
                        "--no-render", "--quiet", "--resume", "--set", "count=2")
    assert code == 0, err
    whole = _bouncing(tmp_path, capsys, "whole", duration="0.2")
    (t1, f1), (t2, f2) = read_series(out / "particles.pvd"), read_series(whole / "particles.pvd")
    assert list(t1) == list(t2)
    for x, y in zip(f1, f2, strict=False):
        np.testing.assert_array_equal(x.points, y.points)


# -- 14. temporary files are removed on failure and on SIGTERM ------------------------------------
def test_14_a_failed_export_or_movie_leaves_no_temporary_file(tmp_path, capsys, monkeypatch):
    out = _bouncing(tmp_path, capsys)
    pytest.importorskip("pxr")
    import pipeline.io.usd

    def broken(*args, **kwargs):
        raise RuntimeError("the disk is full")

    monkeypatch.setattr(pipeline.io.usd, "_write_series", broken)
    code, _, err = _cli(capsys, "export", out / "particles.pvd", "--usd", tmp_path / "x.usdc")
    assert code == 1 and "the disk is full" in err
    from pipeline.render import write_movie

    def images():
        yield np.zeros((32, 32, 3), np.uint8)
        raise RuntimeError("renderer lost")

    for name in ("m.gif", "m.mp4"):
        with pytest.raises(RuntimeError, match="renderer lost"):
            write_movie(images(), tmp_path / name, progress=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


@pytest.mark.timeout(300)
@pytest.mark.parametrize("command", ["run", "render"])
def test_14_sigterm_removes_temporary_files_and_releases_the_folder(tmp_path, capsys, command):
    if command == "run":
        out = tmp_path / "t"
        argv = ["run", "bouncing", "--duration", "20", "--out", str(out), "--no-render",
                "--quiet"]
        watched = out / "particles"  # stopped while it writes a frame
    else:
        run = _bouncing(tmp_path, capsys, duration="1.0")
        out = tmp_path / "movie"
        argv = ["render", str(run / "particles.pvd"), "--out", str(out / "m.mp4"), "--size",
                "320x240", "--quiet"]
        watched = out
        out.mkdir()
    process = subprocess.Popen([sys.executable, "-m", "pipeline", *argv], stderr=subprocess.PIPE,
                               text=True, env=_env())
    deadline = time.monotonic() + 200
    started = out / "particles.pvd" if command == "run" else out  # a frame is on disk
    while not (started.exists() and watched.is_dir()
               and any(is_temporary_name(p.name) for p in watched.iterdir())):
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()
        time.sleep(0.005)
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 143, err
    assert "terminated" in err and "Traceback" not in err
    assert not [p for p in out.rglob("*") if is_temporary_name(p.name)]
    if command == "run":
        assert not (out / LOCK_NAME).exists()
        validate_series(out / "particles.pvd")  # what was written is valid
    else:
        assert not (out / "m.mp4").exists()
