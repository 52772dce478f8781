"""One-call surfaces: ``reconstruct``, the ``dataset.blobflow`` accessor (on datasets, multiblocks
and whole series) and a Flow's surface stage give the same surface, bit for bit; Flow outputs are
PyVista datasets; reconstruct's options, warnings and notices."""

import inspect
import re
import subprocess
import sys
import warnings

import numpy as np
import pytest
import pyvista as pv

from filters import BallisticParticles
from pipeline import Flow, SimulationSource, read_series
from pipeline.feedback import BlobflowWarning, CompileNotice, compile_notice
from pipeline.surface import reconstruct, surface_stages
from pipeline.surface.options import OPTION_DEFAULTS, SURFACE_PARAMETERS

RADIUS = 0.005
OPTIONS = dict(kernel="sph", anisotropic=True, feature_smoothing=5, smooth_iterations=10)


def _block(n=6, spacing=0.01):
    """A resting block of n^3 particles one metre up (falls under gravity)."""
    g = (np.mgrid[0:n, 0:n, 0:n].reshape(3, -1).T + 0.5) * spacing
    return g + [0.0, 0.0, 1.0]


def _assert_same_surface(a, b):
    assert a.n_points > 0 and a.n_cells > 0
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.faces, b.faces)
    assert a.point_data.keys() == b.point_data.keys()
    for name in a.point_data.keys():
        np.testing.assert_array_equal(a.point_data[name], b.point_data[name])


def test_accessor_reconstruct_and_flow_surface_are_bitwise_equal():
    x = _block()
    flow = Flow(SimulationSource(BallisticParticles(x, np.zeros_like(x)), fps=10, duration=0.2))
    flow.add("surface", *surface_stages(RADIUS, **OPTIONS), input="particles")
    particles = flow.output("particles", 0.1)
    from_flow = flow.output("surface", 0.1)
    assert isinstance(particles, pv.PolyData) and isinstance(from_flow, pv.PolyData)
    assert "velocity" in from_flow.point_data  # carried from the particles
    one_call = reconstruct(particles, RADIUS, **OPTIONS)
    accessor = particles.blobflow.surface(radius=RADIUS, **OPTIONS)
    assert isinstance(one_call, pv.PolyData) and isinstance(accessor, pv.PolyData)
    _assert_same_surface(from_flow, one_call)
    _assert_same_surface(from_flow, accessor)
    # a closed surface around the block: no boundary edges, volume near the block's
    assert from_flow.n_open_edges == 0
    assert 0.5 * 0.06 ** 3 < abs(from_flow.volume) < 2.0 * 0.06 ** 3


def test_points_array_gives_the_surface_of_the_same_cloud():
    x = _block(5)
    from_array = reconstruct(x, RADIUS, **OPTIONS)
    from_cloud = pv.PolyData(x).blobflow.surface(radius=RADIUS, **OPTIONS)
    _assert_same_surface(from_array, from_cloud)
    assert "velocity" not in from_array.point_data
    grid = pv.ImageData(dimensions=(5, 5, 5), spacing=(0.01,) * 3, origin=(0.005, 0.005, 1.005))
    _assert_same_surface(reconstruct(grid, RADIUS, **OPTIONS),  # its points
                         reconstruct(np.asarray(grid.points), RADIUS, **OPTIONS))


def test_frames_yields_every_frame_as_pyvista():
    x = _block(3)
    flow = Flow(SimulationSource(BallisticParticles(x, np.zeros_like(x)), fps=10, duration=0.2))
    frames = list(flow.frames("particles"))
    assert [t for t, _ in frames] == [0.0, 0.1, 0.2]
    # free fall from rest: z drops by g t^2 / 2
    for t, data in frames:
        assert isinstance(data, pv.PolyData)
        np.testing.assert_allclose(data.points[:, 2], x[:, 2] - 0.5 * 9.81 * t ** 2, atol=1e-12)


@pytest.mark.parametrize("call, error, needle", [
    (lambda: reconstruct(_block(2), 0.0), ValueError, "radius"),
    (lambda: reconstruct(_block(2), RADIUS, kernal="sph"), TypeError,
     "unexpected keyword argument 'kernal'"),
    (lambda: reconstruct(_block(2), RADIUS, kernel="gauss"), ValueError, "kernel"),
    (lambda: reconstruct(_block(2), RADIUS, smooth_iterations=-1), ValueError,
     "smooth_iterations"),
    (lambda: reconstruct("particles.vtp", RADIUS), TypeError, "points_or_dataset"),
    (lambda: reconstruct(pv.MultiBlock(), RADIUS), TypeError,
     "vtkMultiBlockDataSet (one surface per block: multiblock.blobflow.surface(radius))"),
    (lambda: reconstruct(_block(2), RADIUS, liquid="yes"), TypeError, "liquid"),
    (lambda: pv.MultiBlock([pv.PolyData(_block(2))]).blobflow.surface(RADIUS, kernel="x"),
     ValueError, "kernel"),
    (lambda: pv.MultiBlock([pv.PolyData(_block(2))]).blobflow.write_series("x/s.pvd"),
     ValueError, "block 0 has no TimeValue"),
    (lambda: pv.PolyData(_block(2)).blobflow.surface(radius=-1), ValueError, "radius"),
])
def test_bad_arguments_are_named(call, error, needle):
    with pytest.raises(error, match=re.escape(needle)):
        call()


def test_no_particles_give_an_empty_surface():
    surface = reconstruct(np.zeros((0, 3)), RADIUS)
    assert isinstance(surface, pv.PolyData) and surface.n_points == 0


# -- the options ---------------------------------------------------------------------------------
def test_signatures_list_every_option_with_the_one_table_of_defaults():
    names = list(SURFACE_PARAMETERS)
    for func in (reconstruct, surface_stages, pv.PolyData().blobflow.surface,
                 pv.MultiBlock().blobflow.surface):
        parameters = inspect.signature(func).parameters
        assert not any(p.kind is p.VAR_KEYWORD for p in parameters.values()), func
        for name in names:
            assert name in parameters, (func, name)
            if name != "radius" or func is surface_stages:
                assert parameters[name].default == OPTION_DEFAULTS[name], (func, name)
        assert {"implicit", "anisotropy"} <= set(parameters)
    options = inspect.signature(reconstruct).parameters
    assert options["progress_bar"].default is False
    assert all(p.kind is p.KEYWORD_ONLY for n, p in options.items()
               if n not in ("points_or_dataset", "radius"))
    # every option documented in reconstruct's docstring (numpydoc "name : type" lines)
    documented = {line.split(" : ")[0].strip() for line in reconstruct.__doc__.splitlines()
                  if " : " in line}
    documented |= {"block_size", "brick_blocks"}  # documented together
    assert set(options) - {"points_or_dataset"} <= documented


def _ball(n=3000, radius=0.02, seed=3):
    """``n`` points uniformly in a ball of ``radius`` (m): denser than a liquid's particles."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    return u * radius * rng.random(n)[:, None] ** (1.0 / 3.0)


def test_a_generic_cloud_is_not_inflated_by_default():
    # 3,000 points in a 2 cm ball, 2.2 mm apart on average, splatted at r = 4 mm: as a
    # liquid's particles (2r)^3 each they would fill 27 times the ball
    x, r, R = _ball(), 0.004, 0.02
    default = reconstruct(x, r, normals=False)
    uncorrected = reconstruct(x, r, normals=False, volume_correction=False)
    np.testing.assert_array_equal(default.points, uncorrected.points)
    assert default.n_open_edges == 0
    # the surface of the ball: every vertex within one particle radius of its boundary
    distance = np.linalg.norm(default.points, axis=1)
    assert np.all(np.abs(distance - R) < r) and np.median(distance) < R
    assert default.field_data["blobflow_kind"][0] == "particle_surface"
    # a liquid's particles: the correction moves the surface out, toward n (2r)^3
    liquid = reconstruct(x, r, normals=False, liquid=True)
    assert liquid.field_data["blobflow_kind"][0] == "liquid_surface"
    assert np.median(np.linalg.norm(liquid.points, axis=1)) > R
    assert abs(liquid.volume) > 1.25 * abs(default.volume)
    # ... and volume_correction still decides where it is given
    np.testing.assert_array_equal(
        reconstruct(x, r, normals=False, liquid=True, volume_correction=False).points,
        default.points)
    np.testing.assert_array_equal(
        reconstruct(x, r, normals=False, volume_correction=True).points, liquid.points)


def _ours(caught, category):
    return [w for w in caught if w.category is category]


def test_an_attribute_the_particles_lack_is_named_in_a_warning():
    cloud = pv.PolyData(_block(4))
    cloud.point_data["velocity"] = np.ones((cloud.n_points, 3))
    with pytest.warns(BlobflowWarning, match=r"no point array 'density' \(their arrays: "
                                             r"velocity\)") as caught:
        surface = reconstruct(cloud, RADIUS, attributes=("velocity", "density"), **{
            k: v for k, v in OPTIONS.items()})
    assert [w.filename for w in _ours(caught, BlobflowWarning)] == [__file__]
    assert "velocity" in surface.point_data and "density" not in surface.point_data
    # the default (velocity) is carried where there is one, silently
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        reconstruct(_block(4), RADIUS, **OPTIONS)
    assert not _ours(caught, BlobflowWarning)


def test_compile_notice_once_when_numba_compiles_none_from_its_cache():
    from numba import njit

    @njit(cache=False)
    def twice(x):
        return 2 * x

    @njit(cache=False)
    def thrice(x):
        return 3 * x

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with compile_notice("a test"):
            assert twice(2) == 4 and thrice(2) == 6  # two compilations: one notice
        with compile_notice("a test"):
            assert twice(3) == 6  # compiled already: nothing to say
    notices = _ours(caught, CompileNotice)
    assert len(notices) == 1 and "compiling Numba kernels for a test" in str(notices[0].message)
    assert notices[0].filename == __file__  # the user's line, not numba's
    # a second reconstruct of the same kind finds its kernels compiled: no notice
    reconstruct(_block(3), RADIUS, **OPTIONS)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        reconstruct(_block(3), RADIUS, **OPTIONS)
    assert not _ours(caught, CompileNotice)
    # what users silence it with
    @njit(cache=False)
    def again(x):
        return x + 1

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warnings.filterwarnings("ignore", category=CompileNotice)
        with compile_notice("a test"):
            assert again(1) == 2
    assert not _ours(caught, CompileNotice)


def test_progress_bar_over_the_stages(capsys):
    x = _block(4)
    plain = reconstruct(x, RADIUS, **OPTIONS)
    capsys.readouterr()
    shown = reconstruct(x, RADIUS, progress_bar=True, **OPTIONS)
    err = capsys.readouterr().err
    _assert_same_surface(plain, shown)
    n = len(surface_stages(RADIUS, **OPTIONS))
    assert "surface" in err and f"{n}/{n}" in err and "MetaballSplat" in err
    reconstruct(x, RADIUS, **OPTIONS)
    assert capsys.readouterr().err == ""  # off by default


# -- the accessor on multiblocks and series ------------------------------------------------------
@pytest.fixture(scope="module")
def falling(tmp_path_factory):
    """A series of a falling block of particles (with velocities)."""
    x = _block()
    flow = Flow(SimulationSource(BallisticParticles(x, np.zeros_like(x)), fps=10, duration=0.2))
    return flow.run(tmp_path_factory.mktemp("falling"), progress=False)["particles"]


def test_accessor_on_the_multiblock_pv_read_gives(falling):
    data = pv.read(falling)  # a MultiBlock: the blocks of the first time step
    assert isinstance(data, pv.MultiBlock)
    surfaces = data.blobflow.surface(RADIUS, **OPTIONS)
    assert isinstance(surfaces, pv.MultiBlock) and surfaces.keys() == data.keys()
    _assert_same_surface(surfaces[0], reconstruct(data[0], RADIUS, **OPTIONS))
    # nested multiblocks, names and empty blocks keep their places
    nested = pv.MultiBlock({"a": data[0], "group": pv.MultiBlock({"b": data[0]})})
    nested.append(None, "nothing")
    out = nested.blobflow.surface(RADIUS, **OPTIONS)
    assert out.keys() == ["a", "group", "nothing"] and out["nothing"] is None
    assert out["group"].keys() == ["b"]
    _assert_same_surface(out["group"]["b"], surfaces[0])


def test_accessor_on_a_whole_series_as_a_multiblock_and_written(falling, tmp_path):
    times, frames = read_series(falling)
    surfaces = pv.MultiBlock(frames).blobflow.surface(RADIUS, liquid=True, **OPTIONS)
    assert len(surfaces) == len(frames) == 3
    for surface, frame, t in zip(surfaces, frames, times, strict=False):
        _assert_same_surface(surface, reconstruct(frame, RADIUS, liquid=True, **OPTIONS))
        assert surface.field_data["TimeValue"][0] == t  # the frame's time, carried
        assert not any(k.startswith("state:") for k in surface.field_data.keys())
    path = surfaces.blobflow.write_series(tmp_path / "surface.pvd")
    written_times, written = read_series(path)
    np.testing.assert_array_equal(written_times, times)
    for surface, frame in zip(written, surfaces, strict=False):
        _assert_same_surface(surface, frame)
        assert surface.field_data["blobflow_kind"][0] == "liquid_surface"
    with pytest.raises(ValueError, match="one time per block"):
        surfaces.blobflow.write_series(tmp_path / "other.pvd", times=[0.0])


def test_accessor_on_a_multiblock_after_a_bare_import_pyvista(falling):
    # the pyvista.accessors entry point: no import of blobflow in the user's code
    code = (f"import pyvista as pv; s = pv.read(r'{falling}').blobflow.surface(0.005, "
            "feature_smoothing=0, smooth_iterations=0); print(type(s).__name__, "
            "s[0].n_open_edges, s[0].n_points > 0)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=240)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["MultiBlock", "0", "True"]
