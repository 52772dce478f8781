"""Colliders: every scene writes colliders.vtp, read back by VTK's own reader, matching its
parameters; the file round-trips the exact shapes; bad declarations are refused."""

import numpy as np
import pytest
from _helpers import ballistic
from vtkmodules.util import numpy_support
from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

from filters.geometry import Box, Plane, Sphere
from pipeline import Flow, SimulationSource
from pipeline.io.colliders import (
    COLLIDERS_FILE,
    ROLES,
    Collider,
    collider_mesh,
    colliders_dataset,
    read_colliders,
    write_colliders,
)
from pipeline.scene import available_scenes, load_scene

#: Small runs of every scene (one frame), with parameters that differ from the defaults so that
#: the geometry is seen to follow them.
SCENE_RUNS = {
    "bouncing": {"count": 2},
    "cloth_drape": {"resolution": 4, "sphere_radius": 0.2, "height": 0.5},
    "dam_break": {"spacing": 0.025, "tank_length": 0.5, "depth": 0.12, "tank_height": 0.35,
                  "surface": False},
    "drop": {"spacing": 0.02, "tank_length": 0.2, "tank_width": 0.22, "tank_height": 0.28,
             "pool_depth": 0.04, "drop_radius": 0.03, "drop_height": 0.15, "surface": False},
    "hair": {"strands": 3, "segments": 2, "head_radius": 0.12},
    "jello_drop": {"spacing": 0.08, "radius": 0.1},
    "jello_fem": {"spacing": 0.08, "radius": 0.1},
    "noise_smoke": {"rate": 100.0, "max_particles": 20, "ball_radius": 0.1, "ball_height": 0.5},
    "floating": {"spacing": 0.02, "box_height": 0.06, "surface": False},
    "jello_splash": {"spacing": 0.025, "surface": False},
}


def _expected(name, p):
    """What the scene's colliders must be, from its parameters: {name: (role, kind, params)}."""
    floor = ("floor", "plane", [0, 0, 0, 0, 0, 1])
    if name == "bouncing":
        return {"floor": floor}
    if name == "cloth_drape":
        r = p["sphere_radius"]
        return {"floor": floor, "sphere": ("solid", "sphere", [0, 0, r, r])}
    if name == "dam_break":
        return {"tank": ("container", "box_container",
                         [0, 0, 0, p["tank_length"], p["depth"], p["tank_height"]])}
    if name == "drop":
        return {"tank": ("container", "box_container",
                         [0, 0, 0, p["tank_length"], p["tank_width"], p["tank_height"]])}
    if name in ("floating", "jello_splash"):  # the scenes' default tanks
        from pipeline.scene import load_scene

        d = load_scene(name).parameters
        return {"tank": ("container", "box_container",
                         [0, 0, 0] + [d[k].default for k in ("tank_length", "tank_width",
                                                             "tank_height")])}
    if name == "hair":  # the head the roots sit on
        return {"head": ("solid", "sphere", [0, 0, 1.5, p["head_radius"]])}
    if name in ("jello_drop", "jello_fem"):
        return {"floor": floor}
    if name == "noise_smoke":
        return {"floor": floor, "ball": ("solid", "sphere", [0, 0, p["ball_height"],
                                                             p["ball_radius"]])}
    raise KeyError(name)


def test_every_scene_has_a_collider_case():
    assert set(available_scenes()) <= set(SCENE_RUNS), "add the new scene to SCENE_RUNS"


def _vtk_read(path):
    reader = vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    assert reader.GetErrorCode() == 0
    return reader.GetOutput()


@pytest.mark.parametrize("name", sorted(SCENE_RUNS))
def test_scene_writes_colliders_matching_its_parameters(name, tmp_path):
    parameters = SCENE_RUNS[name]
    flow = load_scene(name).build(**parameters)
    flow.source.set_frames(flow.source.fps, frames=1)
    flow.run(tmp_path, progress=False)
    path = tmp_path / COLLIDERS_FILE
    assert path.is_file()
    data = _vtk_read(path)  # VTK's own reader, not ours
    field = data.GetFieldData()
    names = [field.GetAbstractArray("collider_names").GetValue(i)
             for i in range(field.GetAbstractArray("collider_names").GetNumberOfValues())]
    roles = [field.GetAbstractArray("collider_roles").GetValue(i) for i in range(len(names))]
    kinds = [field.GetAbstractArray("collider_kinds").GetValue(i) for i in range(len(names))]
    expected = _expected(name, parameters)
    assert names == list(expected)
    points = numpy_support.vtk_to_numpy(data.GetPoints().GetData())
    conn = numpy_support.vtk_to_numpy(data.GetPolys().GetConnectivityArray())
    offsets = numpy_support.vtk_to_numpy(data.GetPolys().GetOffsetsArray())
    index = numpy_support.vtk_to_numpy(data.GetCellData().GetArray("collider"))
    role_code = numpy_support.vtk_to_numpy(data.GetCellData().GetArray("role"))
    for i, (n, role, kind) in enumerate(zip(names, roles, kinds, strict=False)):
        exp_role, exp_kind, exp_params = expected[n]
        assert (role, kind) == (exp_role, exp_kind)
        params = numpy_support.vtk_to_numpy(field.GetArray(n))
        np.testing.assert_allclose(params[:len(exp_params)], exp_params, atol=1e-12)
        # the drawn geometry itself, not only the parameters
        cells = np.flatnonzero(index == i)
        assert len(cells) and (role_code[cells] == ROLES.index(role)).all()
        used = np.unique(np.concatenate([conn[offsets[c]:offsets[c + 1]] for c in cells]))
        pts = points[used]
        if kind == "box_container":  # the inner box of the tank, exactly
            lo, hi = np.array(exp_params[:3]), np.array(exp_params[3:])
            np.testing.assert_allclose(pts.min(axis=0), lo, atol=1e-12)
            np.testing.assert_allclose(pts.max(axis=0), hi, atol=1e-12)
            assert len(pts) == 8
        elif kind == "sphere":  # every vertex on the sphere
            c, r = np.array(exp_params[:3]), exp_params[3]
            np.testing.assert_allclose(np.linalg.norm(pts - c, axis=1), r, rtol=1e-12)
            np.testing.assert_allclose(pts.min(axis=0), c - r, atol=1e-12)
        elif kind == "plane":  # a horizontal square through the floor's point
            np.testing.assert_allclose(pts[:, 2], exp_params[2], atol=1e-12)
            assert len(pts) == 4


def test_round_trip_gives_back_the_exact_shapes(tmp_path):
    colliders = [Collider("floor", Plane((0.0, 0.0, -0.25), (0.0, 0.0, 1.0)), "floor", 3.0),
                 Collider("tank", ~Box((0.1, 0.2, 0.3), (0.5, 0.7, 0.9)), "container"),
                 Collider("bowl", ~Sphere((0.0, 0.0, 1.0), 0.4), "container"),
                 Collider("ball", Sphere((0.3, -0.2, 0.5), 0.125)),
                 Collider("brick", Box((-1.0, -1.0, 0.0), (-0.5, -0.8, 0.1)))]
    path = write_colliders(colliders, tmp_path / COLLIDERS_FILE)
    back = read_colliders(path)
    assert back == colliders  # frozen dataclasses: names, roles, sizes and shapes equal


def test_container_faces_point_inwards_and_solid_faces_outwards():
    def mean_normal_dot(collider):
        points, cells = collider_mesh(collider, resolution=8)
        a, b, c = (points[cells[:, k]] for k in range(3))
        normals = np.cross(b - a, c - a)
        centroid = (a + b + c) / 3.0
        return np.einsum("ij,ij->i", normals, centroid - points.mean(axis=0))

    assert (mean_normal_dot(Collider("b", Box((0, 0, 0), (1, 2, 3)))) > 0).all()
    assert (mean_normal_dot(Collider("t", ~Box((0, 0, 0), (1, 2, 3)), "container")) < 0).all()
    assert (mean_normal_dot(Collider("s", Sphere((1, 2, 3), 0.5))) > 0).all()


def test_combination_of_shapes_is_contoured_within_its_bounds():
    shape = Sphere((0.0, 0.0, 0.0), 1.0) - Box((0.0, -2.0, -2.0), (2.0, 2.0, 2.0))  # half ball
    points, cells = collider_mesh(Collider("half", shape), resolution=16)
    assert len(cells) > 100
    assert np.abs(shape(points)).max() < 0.08  # on the surface, to the sampling's precision
    assert points[:, 0].max() < 0.05


@pytest.mark.parametrize("kwargs, error, match", [
    (dict(name="a b", shape=Sphere()), ValueError, "name"),
    (dict(name="ball", shape="sphere"), TypeError, "shape"),
    (dict(name="ball", shape=Sphere(), role="glass"), ValueError, "role"),
    (dict(name="ball", shape=Sphere(), size=0.0), ValueError, "size"),
    (dict(name="half", shape=~Sphere() | Plane()), ValueError, "bounded"),
])
def test_bad_colliders_are_refused(kwargs, error, match):
    with pytest.raises(error, match=match):
        Collider(**kwargs)


def test_flow_refuses_duplicate_names_and_writes_nothing_without_colliders(tmp_path):
    flow = Flow(SimulationSource(ballistic(n=5), fps=10, duration=0.1))
    flow.add_collider("floor", Plane(), role="floor")
    with pytest.raises(ValueError, match="exists already"):
        flow.add_collider("floor", Plane((0, 0, 1), (0, 0, 1)), role="floor")
    with pytest.raises(ValueError, match="unique"):
        colliders_dataset([Collider("a", Sphere()), Collider("a", Sphere())])
    plain = Flow(SimulationSource(ballistic(n=5), fps=10, duration=0.1))
    plain.run(tmp_path, progress=False)
    assert not (tmp_path / COLLIDERS_FILE).exists()
