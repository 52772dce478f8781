"""The ParaView plugin's other end: ``python -m pipeline.paraview.bridge`` describes the scenes and
answers surface requests (one-shot and as a worker) with blobflow's own reconstruction."""

import io
import json
import subprocess
import sys

import numpy as np
import pyvista as pv

from pipeline.io.series import read_frame, write_frame
from pipeline.paraview.bridge import describe, serve
from pipeline.scene import available_scenes, load_scene
from pipeline.surface import reconstruct
from pipeline.surface.options import SURFACE_DEFAULTS


def _cloud(tmp_path):
    x = (np.mgrid[0:5, 0:5, 0:5].reshape(3, -1).T + 0.5) * 0.01
    cloud = pv.PolyData(x)
    cloud.point_data["velocity"] = np.tile([0.0, 0.0, -1.0], (len(x), 1))
    return write_frame(cloud, tmp_path / "particles.vtp"), cloud


def test_describe_lists_every_scene_with_its_parameters():
    seen = describe()
    assert set(seen["scenes"]) == set(available_scenes()) and not seen["broken"]
    for name, entry in seen["scenes"].items():
        scene = load_scene(name)
        assert entry["fps"] == scene.fps and entry["duration"] == scene.duration
        assert [p["name"] for p in entry["parameters"]] == list(scene.parameters)
    assert seen["surface"]["defaults"]["kernel"] == SURFACE_DEFAULTS["kernel"]
    json.dumps(seen)  # all of it JSON


def test_worker_answers_requests_with_reconstruct(tmp_path):
    source, cloud = _cloud(tmp_path)
    options = {"radius": 0.005, "feature_smoothing": 3, "smooth_iterations": 5,
               "attributes": ["velocity"]}
    requests = [{"command": "surface", "source": str(source), "target": str(tmp_path / "a.vtp"),
                 "options": options},
                {"command": "surface", "source": str(source), "target": str(tmp_path / "b.vtp"),
                 "options": dict(options, kernel="gauss")},
                {"command": "surface", "source": str(tmp_path / "missing.vtp"),
                 "target": str(tmp_path / "c.vtp"), "options": options},
                "not json"]
    lines = "".join((r if isinstance(r, str) else json.dumps(r)) + "\n" for r in requests)
    out = io.StringIO()
    serve(io.StringIO(lines), out)
    answers = [json.loads(line) for line in out.getvalue().splitlines()]
    assert answers[0] == {"ok": True}
    assert answers[1]["code"] == 2 and "kernel" in answers[1]["error"]
    assert answers[2]["code"] == 2 and "missing" in answers[2]["error"]
    assert answers[3]["code"] == 2 and "bad request" in answers[3]["error"]
    expected = reconstruct(cloud, 0.005, feature_smoothing=3, smooth_iterations=5)
    written = pv.wrap(read_frame(tmp_path / "a.vtp"))
    np.testing.assert_array_equal(written.points, expected.points)
    np.testing.assert_array_equal(written.faces, expected.faces)
    assert not (tmp_path / "b.vtp").exists()


def test_one_shot_command_and_its_errors(tmp_path):
    source, _ = _cloud(tmp_path)
    command = [sys.executable, "-m", "pipeline.paraview.bridge", "surface", str(source)]
    ok = subprocess.run(command + [str(tmp_path / "s.vtp"), '{"radius": 0.005}'],
                        capture_output=True, text=True, timeout=240)
    assert ok.returncode == 0, ok.stderr
    assert read_frame(tmp_path / "s.vtp").GetNumberOfPolys() > 0
    bad = subprocess.run(command + [str(tmp_path / "t.vtp"), '{"kernel": "sph"}'],
                         capture_output=True, text=True, timeout=240)
    assert bad.returncode == 2 and bad.stderr.strip() == (
        "blobflow: error: OPTIONS_JSON needs a 'radius' (m)")
