"""The blobflow command line: scenes, runs, info, and one-line errors with exit code 2."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pipeline.cli import main
from pipeline.io.series import read_series


def _run_cli(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_list_shows_bouncing_scene(capsys):
    code, out, _ = _run_cli(capsys, "list")
    assert code == 0
    assert any(line.startswith("bouncing ") for line in out.splitlines())
    code, out, _ = _run_cli(capsys, "list", "--verbose")
    assert "restitution = 0.7" in out


def test_run_writes_series_and_prints_where(tmp_path, capsys):
    out_dir = tmp_path / "b"
    code, out, err = _run_cli(capsys, "run", "bouncing", "--frames", "5", "--fps", "10",
                              "--out", str(out_dir), "--set", "count=3", "--quiet", "--no-render")
    assert code == 0, err
    assert str(out_dir) in out
    times, meshes = read_series(out_dir / "particles.pvd")
    assert times.tolist() == [0.0, 0.1, 0.2, 0.3, 0.4]
    assert meshes[0].n_points == 27
    record = json.loads((out_dir / "scene.json").read_text())
    assert record["scene"] == "bouncing" and record["parameters"]["count"] == 3


def test_info_describes_a_series(tmp_path, capsys):
    _run_cli(capsys, "run", "bouncing", "--duration", "0.2", "--out", str(tmp_path), "-q",
             "--set", "count=2")
    code, out, _ = _run_cli(capsys, "info", str(tmp_path / "particles.pvd"))
    assert code == 0
    assert "7 frames" in out and "velocity (3)" in out and "points per frame: 8 .. 8" in out


@pytest.mark.parametrize("argv, needle", [
    (["run", "no_such_scene"], "unknown scene 'no_such_scene'; scenes: bouncing"),
    (["run", "bouncing", "--set", "colour=red"], "no parameter 'colour'; parameters: count"),
    (["run", "bouncing", "--set", "count=many"], "parameter 'count' takes an integer"),
    (["run", "bouncing", "--set", "count"], "--set takes name=value"),
    (["run", "bouncing", "--set", "count=0"], "count must be an integer in [1, 200]"),
    (["run", "bouncing", "--set", "restitution=2"], "restitution must be in [0, 1]"),
    (["run", "bouncing", "--fps", "0"], "--fps must be > 0"),
    (["run", "bouncing", "--frames", "0"], "--frames must be >= 1"),
    (["run", "bouncing", "--frames", "3", "--duration", "1"], "not allowed with argument"),
    (["info", "missing.pvd"], "no such series file"),
    (["frobnicate"], "invalid choice"),
])
def test_bad_input_gives_one_line_and_exit_code_2(tmp_path, capsys, argv, needle):
    argv = [a if a != "missing.pvd" else str(tmp_path / a) for a in argv]
    if argv[0] == "run":
        argv += ["--out", str(tmp_path / "out")]
    code, out, err = _run_cli(capsys, *argv)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("blobflow: error: "), err
    assert needle in err
    assert not (tmp_path / "out").exists(), "an invalid run must not write anything"


def test_unwritable_output_folder(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    code, _, err = _run_cli(capsys, "run", "bouncing", "--out", str(blocker / "sub"))
    assert code == 2 and "not a folder" in err and err.count("\n") == 1


def test_malformed_series_gives_exit_code_2(tmp_path, capsys):
    bad = tmp_path / "bad.pvd"
    bad.write_text("this is not xml")
    code, _, err = _run_cli(capsys, "info", str(bad))
    assert code == 2 and "not a valid series file" in err and err.count("\n") == 1


def test_failed_run_overwrites_nothing(tmp_path, capsys):
    out_dir = tmp_path / "b"
    assert _run_cli(capsys, "run", "bouncing", "--frames", "3", "--out", str(out_dir), "-q")[0] == 0
    before = {p: p.read_bytes() for p in out_dir.rglob("*") if p.is_file()}
    code, _, _ = _run_cli(capsys, "run", "bouncing", "--frames", "5", "--out", str(out_dir),
                          "--set", "spacing=-1")
    assert code == 2
    assert {p: p.read_bytes() for p in out_dir.rglob("*") if p.is_file()} == before


def test_resume_with_other_parameters_is_refused(tmp_path, capsys):
    out_dir = tmp_path / "b"
    _run_cli(capsys, "run", "bouncing", "--frames", "3", "--out", str(out_dir), "-q")
    code, _, err = _run_cli(capsys, "run", "bouncing", "--frames", "6", "--out", str(out_dir),
                            "--resume", "--set", "count=4")
    assert code == 2 and "count" in err
    code, _, _ = _run_cli(capsys, "run", "bouncing", "--frames", "6", "--out", str(out_dir),
                          "--resume", "-q")
    assert code == 0
    assert len(read_series(out_dir / "particles.pvd")[0]) == 6


_SCRIPT = str(Path(sys.executable).with_name("blobflow"))  # installed beside this interpreter


@pytest.mark.parametrize("arguments", [["run", "nope"], ["list", "--verbose"],
                                       ["info", "missing.pvd"], ["surface"]])
def test_console_script_and_module_agree(arguments, tmp_path):
    # the installed `blobflow` script and `python -m pipeline` are the same program: the same
    # exit code, the same output and the same error, byte for byte
    script, module = (subprocess.run(command + arguments, capture_output=True, text=True,
                                     timeout=120, cwd=tmp_path)
                      for command in ([_SCRIPT], [sys.executable, "-m", "pipeline"]))
    assert (script.returncode, script.stdout, script.stderr) == (
        module.returncode, module.stdout, module.stderr)
    assert "Traceback" not in script.stderr
    if arguments[0] == "list":
        assert script.returncode == 0 and "dam_break" in script.stdout
    else:
        assert script.returncode == 2 and script.stderr.count("\n") == 1
        assert script.stderr.startswith("blobflow: error: ")
    if arguments == ["run", "nope"]:
        assert "unknown scene 'nope'; scenes: " in script.stderr


def test_surface_of_a_scene_run_rebuilds_the_scene_surface(tmp_path, capsys):
    # `blobflow surface` reads the producing run's record (spacing, tank, smoothing): with no
    # option it writes, bitwise, the surface the scene wrote
    run = tmp_path / "drop"
    code, _, _ = _run_cli(capsys, "run", "drop", "--frames", "2", "--set", "spacing=0.02",
                          "--out", str(run), "--no-render", "-q")
    assert code == 0
    code, _, _ = _run_cli(capsys, "surface", str(run / "particles.pvd"), "--out",
                          str(tmp_path / "again"), "-q")
    assert code == 0
    _, scene = read_series(run / "surface.pvd")
    _, again = read_series(tmp_path / "again" / "surface.pvd")
    assert len(scene) == len(again) == 2
    for a, b in zip(scene, again, strict=False):
        assert a.n_points > 0
        np.testing.assert_array_equal(a.points, b.points)
        np.testing.assert_array_equal(a.faces, b.faces)
        assert a.point_data.keys() == b.point_data.keys()
        for name in a.point_data.keys():
            np.testing.assert_array_equal(a.point_data[name], b.point_data[name])
    # a flag given on the command line wins over the record
    code, _, _ = _run_cli(capsys, "surface", str(run / "particles.pvd"), "--out",
                          str(tmp_path / "iso"), "--option", "anisotropic=no", "-q")
    assert code == 0
    _, iso = read_series(tmp_path / "iso" / "surface.pvd")
    assert iso[0].n_points != scene[0].n_points or not np.array_equal(iso[0].points,
                                                                      scene[0].points)


def test_version_prints_the_package_version(capsys):
    from importlib.metadata import version

    code, out, err = _run_cli(capsys, "--version")
    assert code == 0 and out == f"blobflow {version('blobflow')}\n" and not err


def test_list_verbose_gives_every_description_whole(capsys):
    # one line per parameter, each description complete: a sentence with its final period
    # (the docstrings' continuation lines included), no reST literal markup
    from pipeline.scene import available_scenes, load_scene

    code, out, _ = _run_cli(capsys, "list", "--verbose")
    assert code == 0
    lines = [line for line in out.splitlines() if line.startswith("    ") and " = " in line]
    expected = sum(len(load_scene(n).parameters) for n in available_scenes())
    assert len(lines) == expected
    for line in lines:
        assert line.endswith("."), line
        assert "``" not in line and "  " not in line.split(") ", 1)[1], line
    assert any("Halving it multiplies the particle count by 8" in line for line in lines)


@pytest.mark.parametrize("command", ["run", "surface", "render", "export", "list", "info",
                                     "paraview"])
def test_every_help_shows_defaults(capsys, command):
    code, out, _ = _run_cli(capsys, command, "--help")
    assert code == 0 and out.startswith("usage: blobflow " + command)
    out = " ".join(out.split())  # argparse wraps lines
    if command == "run":
        assert "dam_break: 1.5 s at 30 fps" in out and "hair: 3 s at 30 fps" in out
    if command == "surface":
        assert "one of blobby, metaball, sph, zhu_bridson (default: sph)" in out
        assert "(default: 30)" in out and "feature_smoothing=25" in out
    if command == "render":
        assert "(default: 640x480)" in out


def test_resumed_run_removes_the_renders_of_the_shorter_run(tmp_path, capsys):
    out_dir = tmp_path / "b"
    argv = ["run", "bouncing", "--out", str(out_dir), "--set", "count=2", "-q", "--no-render"]
    assert _run_cli(capsys, *argv, "--frames", "3")[0] == 0
    for name in ("turntable.gif", "movie.mp4"):
        (out_dir / name).write_bytes(b"previous run")
    mine = out_dir / "notes.txt"
    mine.write_text("not blobflow's")
    assert _run_cli(capsys, *argv, "--frames", "5", "--resume")[0] == 0
    assert not (out_dir / "turntable.gif").exists() and not (out_dir / "movie.mp4").exists()
    assert mine.read_text() == "not blobflow's"
    for name in ("turntable.gif", "movie.mp4"):
        (out_dir / name).write_bytes(b"previous run")
    assert _run_cli(capsys, *argv, "--frames", "2")[0] == 0  # a fresh run over it
    assert not (out_dir / "turntable.gif").exists() and not (out_dir / "movie.mp4").exists()


def test_one_line_notice_when_numba_compiles(capsys):
    # the notice listens to Numba's compile events, which fire only on a cache miss
    from numba import njit

    from pipeline.cli.tools import announce_compilation

    announce_compilation()

    @njit(cache=False)
    def twice(x):
        return 2 * x

    @njit(cache=False)
    def thrice(x):
        return 3 * x

    assert twice(2) == 4 and thrice(2) == 6
    err = capsys.readouterr().err
    assert err.count("blobflow: compiling Numba kernels") == 1 and err.count("\n") == 1


def test_paraview_command_names_the_plugin(capsys):
    code, out, _ = _run_cli(capsys, "paraview")
    plugin = Path(out.split("ParaView plugin: ", 1)[1].split("\n", 1)[0])
    assert code == 0 and plugin.name == "plugin.py" and plugin.parent.name == "paraview"
    assert plugin.is_file()
    assert f"--script={plugin.with_name('startup.py')}" in out
    code, _, err = _run_cli(capsys, "paraview", "file.pvd")
    assert code == 2 and "need --launch" in err


def test_paraview_launch_without_a_display_says_what_to_install(tmp_path, capsys, monkeypatch):
    # a `paraview` on PATH that would fail loudly if it were started
    fake = tmp_path / "bin" / "paraview"
    fake.parent.mkdir()
    fake.write_text("#!/bin/sh\necho started >&2\nexit 250\n")
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", f"{fake.parent}:/usr/bin:/bin")
    monkeypatch.delenv("QT_QPA_PLATFORM", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    data = tmp_path / "data.pvd"
    data.write_text("<VTKFile/>")
    for display in (None, ":4711"):  # none at all; one nobody serves
        if display is None:
            monkeypatch.delenv("DISPLAY", raising=False)
        else:
            monkeypatch.setenv("DISPLAY", display)
        code, out, err = _run_cli(capsys, "paraview", "--launch", str(data))
        assert code == 2 and out == "" and err.count("\n") == 1, err
        assert "xvfb-run" in err and "apt-get install xvfb" in err and "started" not in err
    code, _, err = _run_cli(capsys, "paraview", "--launch", str(tmp_path / "missing.pvd"))
    assert code == 2 and "no such file" in err
