"""One-call surfaces: ``reconstruct``, the ``dataset.blobflow`` accessor and a Flow's surface
stage give the same surface, bit for bit; Flow outputs are PyVista datasets."""

import numpy as np
import pytest
import pyvista as pv

from filters import BallisticParticles
from pipeline import Flow, SimulationSource
from pipeline.surface import reconstruct, surface_stages

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
     "no option 'kernal'; options: cell_size, kernel"),
    (lambda: reconstruct(_block(2), RADIUS, kernel="gauss"), ValueError, "kernel"),
    (lambda: reconstruct(_block(2), RADIUS, smooth_iterations=-1), ValueError,
     "smooth_iterations"),
    (lambda: reconstruct("particles.vtp", RADIUS), TypeError, "points_or_dataset"),
    (lambda: reconstruct(pv.MultiBlock(), RADIUS), TypeError, "vtkMultiBlockDataSet"),
    (lambda: pv.PolyData(_block(2)).blobflow.surface(radius=-1), ValueError, "radius"),
])
def test_bad_arguments_are_named(call, error, needle):
    with pytest.raises(error, match=needle.replace("(", r"\(").replace("[", r"\[")):
        call()


def test_no_particles_give_an_empty_surface():
    surface = reconstruct(np.zeros((0, 3)), RADIUS)
    assert isinstance(surface, pv.PolyData) and surface.n_points == 0
