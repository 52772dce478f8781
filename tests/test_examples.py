"""Every script of examples/ runs as a user runs it, and writes what it says it writes.

Each example runs in a subprocess (``python examples/NAME.py``) from an empty temporary folder,
with ``BLOBFLOW_EXAMPLE_SMALL=1`` (the small size every example offers), no display, and must
exit 0 having written its picture to ``outputs/examples/NAME/NAME.png`` -- the picture the
documentation's gallery shows. The files the examples say they write are read back with real
readers (VTK, pxr).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest

from pipeline import read_series

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = sorted(p for p in (ROOT / "examples").glob("*.py") if not p.name.startswith("_"))


def test_at_least_eight_examples():
    assert len(EXAMPLES) >= 8, [p.name for p in EXAMPLES]


def run_example(path: Path, cwd: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items()
           if k not in ("DISPLAY", "BLOBFLOW_EXAMPLES_OUT", "PYVISTA_OFF_SCREEN")}
    env["BLOBFLOW_EXAMPLE_SMALL"] = "1"
    # this checkout's packages, also where another copy is installed
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get("PYTHONPATH", "")
                                                       .split(os.pathsep) if p])
    return subprocess.run([sys.executable, str(path)], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=280)


def check_picture(path: Path) -> np.ndarray:
    """A picture, not a blank canvas: its pixels differ from its corner's colour on more than 3 %
    of the image and it has more than 64 distinct colours."""
    assert path.is_file(), f"no picture at {path}"
    image = np.asarray(imageio.imread(path))
    assert image.ndim == 3 and image.shape[0] >= 300 and image.shape[1] >= 300, image.shape
    rgb = image[..., :3].astype(np.int16)
    background = rgb[2, 2]
    drawn = np.any(np.abs(rgb - background) > 12, axis=-1).mean()
    colours = len(np.unique(rgb.reshape(-1, 3), axis=0))
    assert drawn > 0.03 and colours > 64, (path.name, drawn, colours)
    return image


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example_runs_and_draws(path, tmp_path):
    result = run_example(path, tmp_path)
    assert result.returncode == 0, \
        f"{path.name} failed:\n{result.stdout[-2000:]}\n{result.stderr[-4000:]}"
    assert "Traceback" not in result.stderr, result.stderr[-4000:]
    out = tmp_path / "outputs" / "examples" / path.stem
    check_picture(out / f"{path.stem}.png")
    # nothing written beside the example's own folder (never into the source tree either)
    assert sorted(p.name for p in (tmp_path / "outputs" / "examples").iterdir()) == [path.stem]
    check = CHECKS.get(path.stem)
    if check is not None:
        check(out, result.stdout)


# -- what the examples say they write, read back ---------------------------------------------------

def _custom_simulation(out, stdout):
    times, frames = read_series(out / "particles.pvd")
    assert len(times) == 31 and times[-1] == 1.0  # 1 s at 30 fps, small size
    assert frames[0].n_points == 60 and "speed" in frames[-1].point_data
    speed = np.asarray(frames[-1].point_data["speed"])
    velocity = np.asarray(frames[-1].point_data["velocity"])
    np.testing.assert_allclose(speed, np.linalg.norm(velocity, axis=1), rtol=1e-12)


def _cloth(out, stdout):
    times, frames = read_series(out / "cloth.pvd")
    assert len(times) == 19 and frames[-1].n_cells == frames[0].n_cells > 0
    assert (out / "cloth.xdmf").is_file() and (out / "colliders.vtp").is_file()
    # the cloth came down onto the balls and stays above the floor
    z = np.asarray(frames[-1].points)[:, 2]
    assert z.max() < 0.6 and z.min() > 0.0


def _dask(out, stdout):
    particles, _ = read_series(out / "particles.pvd")
    times, surfaces = read_series(out / "surface.pvd")
    assert list(times) == list(particles) and len(times) == 7
    assert all(s.n_cells > 0 and s.n_open_edges == 0 for s in surfaces)
    assert "by 2 worker processes" in stdout


def _paraview_and_usd(out, stdout):
    from pxr import Usd, UsdGeom

    times, frames = read_series(out / "hair.pvd")
    stage = Usd.Stage.Open(str(out / "hair.usd"))
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath("/blobflow/hair"))
    code = stage.GetEndTimeCode()
    assert code == 30 * times[-1]
    counts = np.array(curves.GetCurveVertexCountsAttr().Get(code))
    points = np.array(curves.GetPointsAttr().Get(code))
    # one curve per strand, every point of the last frame, in order
    assert counts.sum() == len(points) == frames[-1].n_points
    np.testing.assert_allclose(points, np.asarray(frames[-1].points), atol=1e-6)
    assert (out / "hair.xdmf").is_file() and (out / "hair.h5").is_file()


def _integrators(out, stdout):
    lines = {line.split(":")[0].strip(): line for line in stdout.splitlines() if ":" in line}
    # forward Euler blows up; the two backward schemes only lose energy
    assert "energy at the end +" in lines["euler"]
    for scheme in ("linearized_backward_euler", "backward_euler"):
        assert "energy at the end -" in lines[scheme]


def _bodies_in_water(out, stdout):
    # small size: 2 cm spacing, 0.8 s; the ball (600 kg/m^3, radius 4 cm) afloat, the brick
    # (2,000 kg/m^3, 4 cm high) down on the floor, both meshes in the bodies series at every frame
    times, water = read_series(out / "particles.pvd")
    _, bodies = read_series(out / "bodies.pvd")
    assert len(times) == len(bodies) == 25 and abs(times[-1] - 0.8) < 1e-9
    assert all(int(w.field_data["container_corrections"][0]) == 0 for w in water)
    z = np.asarray(water[-1].field_data["body_position"]).reshape(-1, 3)[:, 2]
    level = np.percentile(np.asarray(water[-1].points)[:, 2], 99) + 0.01
    assert z[0] + 0.04 > level > z[0] - 0.04  # the ball across the surface
    assert z[1] - 0.02 < 0.02  # the brick within a spacing of the floor
    body = np.asarray(bodies[-1].point_data["body"])
    assert sorted(set(body.tolist())) == [0, 1] and bodies[-1].n_cells > 0
    assert "the ball's top" in stdout


CHECKS = {
    "bodies_in_water": _bodies_in_water,
    "custom_simulation": _custom_simulation,
    "cloth_from_your_mesh": _cloth,
    "dask_surfaces": _dask,
    "paraview_and_usd": _paraview_and_usd,
    "integrators_compared": _integrators,
}
