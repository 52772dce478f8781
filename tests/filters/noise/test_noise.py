"""Tests of filters.noise: Perlin's improved noise (exactness, smoothness, derivatives), fractal
sums and curl noise (zero divergence, boundary ramp)."""

import math

import numpy as np
import pytest

from filters.fields import CurlNoise
from filters.geometry import Box, Plane, Sphere, union_distance
from filters.noise import (
    PERMUTATION,
    fbm3,
    perlin3,
    perlin3_gradient,
    perlin3_hessian,
    permutation_table,
    turbulence3,
)


def curl_noise(points, t=0.0, **parameters):
    """Curl-noise velocities at ``points`` (the field evaluated once)."""
    return CurlNoise(**parameters).velocity(points, t)

RNG = np.random.default_rng(12345)
POINTS = RNG.uniform(-20.0, 20.0, (400, 3))


# --- exactness ----------------------------------------------------------------------------------
def test_reference_check_value_is_exact():
    # Perlin's published check value for his reference implementation (Perlin 2002).
    assert perlin3(3.14, 42, 7) == 0.13691995878400012
    assert perlin3(np.array([[3.14, 42.0, 7.0]]))[0] == 0.13691995878400012


def test_gradient_table_is_perlins_grad_function():
    from filters.noise import GRADIENTS

    def reference_grad(h, x, y, z):  # Perlin 2002, transcribed branch by branch
        h &= 15
        u = x if h < 8 else y
        v = y if h < 4 else (x if h in (12, 14) else z)
        return (u if h & 1 == 0 else -u) + (v if h & 2 == 0 else -v)

    for h in range(16):
        g = [reference_grad(h, *e) for e in np.eye(3)]
        assert GRADIENTS[h].tolist() == g


def _reference_noise(perm, x, y, z):
    """Perlin's reference ``ImprovedNoise.noise`` (Perlin 2002, Java), transcribed line by line
    in Python floats (IEEE doubles, as Java's), on the doubled permutation ``perm``."""
    def fade(t):
        return t * t * t * (t * (t * 6 - 15) + 10)

    def lerp(t, a, b):
        return a + t * (b - a)

    def grad(hash_, x, y, z):
        h = hash_ & 15
        u = x if h < 8 else y
        v = y if h < 4 else (x if h == 12 or h == 14 else z)
        return (u if (h & 1) == 0 else -u) + (v if (h & 2) == 0 else -v)

    p = [int(v) for v in perm]
    X = math.floor(x) & 255
    Y = math.floor(y) & 255
    Z = math.floor(z) & 255
    x -= math.floor(x)
    y -= math.floor(y)
    z -= math.floor(z)
    u, v, w = fade(x), fade(y), fade(z)
    A = p[X] + Y
    AA = p[A] + Z
    AB = p[A + 1] + Z
    B = p[X + 1] + Y
    BA = p[B] + Z
    BB = p[B + 1] + Z
    return lerp(w, lerp(v, lerp(u, grad(p[AA], x, y, z), grad(p[BA], x - 1, y, z)),
                        lerp(u, grad(p[AB], x, y - 1, z), grad(p[BB], x - 1, y - 1, z))),
                lerp(v, lerp(u, grad(p[AA + 1], x, y, z - 1), grad(p[BA + 1], x - 1, y, z - 1)),
                        lerp(u, grad(p[AB + 1], x, y - 1, z - 1),
                             grad(p[BB + 1], x - 1, y - 1, z - 1))))


def _awkward_points(n=600):
    """Random points over several wraps of the lattice, with lattice points, the last double
    below a lattice point, tiny and negative coordinates."""
    rng = np.random.default_rng(2002)
    pts = rng.uniform(-600.0, 600.0, (n, 3))
    pts[: n // 6] = np.round(pts[: n // 6])
    pts[n // 6: n // 3] = np.nextafter(np.round(pts[n // 6: n // 3]), -np.inf)
    pts[n // 3: n // 2] *= 1e-3
    pts[n // 2: n // 2 + 20, 0] = 1e-300
    pts[n // 2 + 20: n // 2 + 40, 1] = -0.0
    return pts


@pytest.mark.parametrize("seed", [0, 7, 2**63 + 5])
def test_array_path_equals_the_reference_transcription_bitwise(seed):
    # the array path's loop has its own tables and operation layout (pairs of entries, the
    # reference's grad as selects, 512-bit vectors): it must give the reference's bits
    pts = _awkward_points()
    perm = permutation_table(seed)
    expected = np.array([_reference_noise(perm, *pt) for pt in pts.tolist()])
    got = perlin3(pts, seed=seed)
    assert np.array_equal(got.view(np.int64), expected.view(np.int64))  # bits, signed zeros too
    # and the point kernel that fractal sums, curl noise and fields call gives them too
    from filters.noise.perlin import kernel_table, perlin_value

    table = kernel_table(seed)
    assert all(perlin_value(table, *pt) == e for pt, e in zip(pts.tolist(), expected, strict=False))


def test_value_loop_is_512_bits_wide_where_the_cpu_has_avx512():
    # filters.noise.lattice.wide_vectors marks the loop's function; the claim in its docstring
    # (8 doubles a vector on AVX-512 CPUs) is checked on the compiled code of a fresh
    # (uncached: cached code cannot be inspected) copy of perlin3's loop
    import llvmlite.binding as llvm
    import numba

    from filters.noise.perlin import _pair_table, _perlin_many

    fresh = numba.njit(parallel=True)(_perlin_many.py_func)
    pts = POINTS[:64].copy()
    out = np.empty(len(pts))
    fresh(_pair_table(0), pts, 1.0, out)
    assert np.array_equal(out, perlin3(pts))
    asm = fresh.inspect_asm(fresh.signatures[0])
    if "+avx512f" in llvm.get_host_cpu_features().flatten():
        assert "zmm" in asm
    else:
        assert "zmm" not in asm


def test_reference_permutation_is_a_permutation_and_seed_zero():
    assert sorted(PERMUTATION.tolist()) == list(range(256))
    table = permutation_table(0)
    assert np.array_equal(table[:256], PERMUTATION) and np.array_equal(table[256:], PERMUTATION)


def test_seeded_tables_are_deterministic_shuffles():
    import zlib
    for seed in (1, 42, 2**63 + 5, -3):
        table = permutation_table(seed)
        assert sorted(table[:256].tolist()) == list(range(256))
        assert np.array_equal(table[:256], table[256:])
        assert not np.array_equal(table[:256], PERMUTATION)
    # pinned: the shuffle must not change between versions (it defines the noise of a seed)
    assert permutation_table(1)[:8].tolist() == [92, 220, 68, 237, 109, 183, 108, 255]
    assert zlib.crc32(permutation_table(42).tobytes()) == 3834283880
    a = perlin3(POINTS, seed=7)
    assert np.array_equal(a, perlin3(POINTS, seed=7))
    assert np.abs(a - perlin3(POINTS)).max() > 0.1


def test_zero_at_every_integer_lattice_point():
    lattice = RNG.integers(-300, 300, (500, 3)).astype(np.float64)
    for seed in (0, 3):
        assert np.all(perlin3(lattice, seed=seed) == 0.0)
        values, grads = perlin3_gradient(lattice, seed=seed)
        assert np.all(values == 0.0)
        # at a lattice point the gradient is the corner's gradient vector: entries in {0, +-1}
        assert np.all(np.isin(grads, (-1.0, 0.0, 1.0)))
        assert np.all(np.abs(grads).sum(axis=1) == 2.0)


def test_scalar_array_and_derivative_values_agree_bitwise():
    values = perlin3(POINTS)
    assert values[5] == perlin3(*POINTS[5])
    v_grad, _ = perlin3_gradient(POINTS)
    v_hess, _, _ = perlin3_hessian(POINTS)
    assert np.array_equal(values, v_grad) and np.array_equal(values, v_hess)
    assert np.abs(values).max() <= 1.0


def test_frequency_rescales_coordinates():
    f = 2.5
    assert np.array_equal(perlin3(POINTS, frequency=f), perlin3(POINTS * f))
    _, g = perlin3_gradient(POINTS, frequency=f)
    _, g_scaled = perlin3_gradient(POINTS * f)
    np.testing.assert_allclose(g, f * g_scaled, rtol=0, atol=1e-14)


# --- derivatives and smoothness -----------------------------------------------------------------
def _central_gradient(fun, pts, h):
    grad = np.empty_like(pts)
    for axis in range(3):
        e = np.zeros(3)
        e[axis] = h
        grad[:, axis] = (fun(pts + e) - fun(pts - e)) / (2.0 * h)
    return grad


def test_gradient_matches_central_differences():
    _, grad = perlin3_gradient(POINTS)
    fd = _central_gradient(perlin3, POINTS, 1e-5)
    assert np.abs(grad - fd).max() < 1e-7


def test_hessian_matches_differences_of_gradient_and_is_symmetric():
    _, _, hess = perlin3_hessian(POINTS, seed=9)
    h = 1e-5
    for axis in range(3):
        e = np.zeros(3)
        e[axis] = h
        gp = perlin3_gradient(POINTS + e, seed=9)[1]
        gm = perlin3_gradient(POINTS - e, seed=9)[1]
        assert np.abs(hess[:, :, axis] - (gp - gm) / (2 * h)).max() < 1e-6
    assert np.array_equal(hess, np.transpose(hess, (0, 2, 1)))


def test_c2_continuity_across_cell_faces():
    base = RNG.uniform(-10.0, 10.0, (300, 3))
    for axis in range(3):
        on_face = base.copy()
        # exactly on a face: such a point belongs to the upper cell
        on_face[:, axis] = np.round(on_face[:, axis])
        below = on_face.copy()
        below[:, axis] = np.nextafter(on_face[:, axis], -np.inf)  # last point of the lower cell
        v1, g1, h1 = perlin3_hessian(on_face)
        v0, g0, h0 = perlin3_hessian(below)
        assert np.abs(v1 - v0).max() < 1e-12
        assert np.abs(g1 - g0).max() < 1e-12
        assert np.abs(h1 - h0).max() < 1e-10  # second derivatives continuous: C2


def test_hessian_is_not_trivially_zero_on_faces():
    # guards the C2 test: second derivatives along the face are genuinely non-zero there
    pts = RNG.uniform(-10.0, 10.0, (100, 3))
    pts[:, 0] = np.round(pts[:, 0])
    _, _, hess = perlin3_hessian(pts)
    assert np.abs(hess[:, 1, 1]).max() > 0.1


# --- fractal sums ------------------------------------------------------------------------------
def test_fbm_one_octave_is_perlin_and_gradient_matches_fd():
    assert np.array_equal(fbm3(POINTS, octaves=1, frequency=0.7), perlin3(POINTS, frequency=0.7))
    kwargs = dict(octaves=5, lacunarity=2.1, gain=0.45, seed=4, frequency=0.3, time=1.7,
                  time_scale=0.4)
    _, grad = fbm3(POINTS, gradient=True, **kwargs)
    fd = _central_gradient(lambda p: fbm3(p, **kwargs), POINTS, 1e-5)
    assert np.abs(grad - fd).max() < 1e-7


def test_fbm_is_the_weighted_sum_of_octaves():
    pts = POINTS[:50]
    total = fbm3(pts, octaves=3, gain=0.5, lacunarity=2.0)
    first = perlin3(pts)
    # octave 0 is unshifted, the rest are shifted copies: the sum differs from octave 0 alone
    assert np.abs(total - first).max() > 1e-3
    # linearity in the gain: f(gain) - octave0 scales like gain for 2 octaves
    two_a = fbm3(pts, octaves=2, gain=0.2) - first
    two_b = fbm3(pts, octaves=2, gain=0.4) - first
    np.testing.assert_allclose(two_b, 2 * two_a, rtol=0, atol=1e-14)


def test_turbulence_is_sum_of_absolute_values():
    pts = POINTS[:100]
    turb = turbulence3(pts, octaves=1)
    assert np.array_equal(turb, np.abs(perlin3(pts)))
    assert np.all(turbulence3(pts, octaves=4) >= 0.0)


def test_time_varying_noise_drifts_smoothly():
    a = fbm3(POINTS, octaves=2, time=0.0, time_scale=0.5)
    b = fbm3(POINTS, octaves=2, time=1e-6, time_scale=0.5)
    c = fbm3(POINTS, octaves=2, time=3.0, time_scale=0.5)
    assert 0 < np.abs(a - b).max() < 1e-5
    assert np.abs(a - c).max() > 0.1
    assert np.array_equal(a, fbm3(POINTS, octaves=2, time=3.0, time_scale=0.0))


# --- curl noise --------------------------------------------------------------------------------
def _fd_divergence(field, pts, h):
    div = np.zeros(pts.shape[0])
    for axis in range(3):
        e = np.zeros(3)
        e[axis] = h
        div += (field(pts + e)[:, axis] - field(pts - e)[:, axis]) / (2 * h)
    return div


def test_curl_noise_divergence_free_with_h2_convergence():
    cn = CurlNoise(amplitude=1.5, frequency=0.8, octaves=3, seed=11, time_scale=0.3)
    pts = RNG.uniform(-5.0, 5.0, (500, 3))
    field = lambda p: cn.velocity(p, 0.9)  # noqa: E731
    speed = np.linalg.norm(field(pts), axis=1)
    assert speed.mean() > 0.3  # a real flow, not a zero field
    errors = [np.abs(_fd_divergence(field, pts, h)) for h in (4e-2, 2e-2, 1e-2)]
    # shrinks as h^2: each halving divides the error by ~4
    for coarse, fine in zip(errors[:-1], errors[1:], strict=False):
        ratio = np.median(coarse / np.maximum(fine, 1e-300))
        assert 3.5 < ratio < 4.5
    assert errors[-1].max() < errors[0].max() / 10.0
    # small enough h: truncation ~ 0.3 (h / 1e-2)^2 and round-off ~ 1e-16 / h are both tiny
    assert np.abs(_fd_divergence(field, pts, 2e-6)).max() < 1e-6


def test_curl_noise_jacobian_is_traceless_and_matches_fd():
    cn = CurlNoise(amplitude=1.0, frequency=1.3, octaves=2, seed=5, time_scale=0.2)
    pts = RNG.uniform(-4.0, 4.0, (200, 3))
    vel, jac = cn.jacobian(pts, 0.4)
    np.testing.assert_allclose(vel, cn.velocity(pts, 0.4), rtol=0, atol=1e-13)
    windy = CurlNoise(amplitude=1.0, frequency=1.3, octaves=2, seed=5, time_scale=0.2,
                      base_velocity=(0.0, 0.0, 2.0))
    v_w, jac_w = windy.jacobian(pts, 0.4)
    np.testing.assert_allclose(v_w, vel + [0.0, 0.0, 2.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(jac_w, jac, rtol=0, atol=1e-12)
    assert np.abs(np.trace(jac, axis1=1, axis2=2)).max() < 1e-12
    h = 1e-5
    for axis in range(3):
        e = np.zeros(3)
        e[axis] = h
        fd = (cn.velocity(pts + e, 0.4) - cn.velocity(pts - e, 0.4)) / (2 * h)
        assert np.abs(jac[:, :, axis] - fd).max() < 1e-8 * np.abs(jac).max() + 1e-9


def test_curl_noise_is_the_curl_of_its_potential():
    cn = CurlNoise(amplitude=0.7, frequency=0.9, octaves=2, seed=2,
                   colliders=(Sphere((0, 0, 0), 1.0), Plane((0, 0, -2.0), (0, 0, 1))),
                   ramp_distance=0.8, base_velocity=(0.1, -0.2, 0.5))
    pts = RNG.uniform(-2.0, 2.0, (300, 3))
    pts = pts[union_distance(pts, cn.colliders)[0] > 0.05]
    h = 1e-5
    d = [None, None, None]
    for axis in range(3):
        e = np.zeros(3)
        e[axis] = h
        d[axis] = (cn.potential(pts + e) - cn.potential(pts - e)) / (2 * h)  # d psi / d x_axis
    curl = np.stack([d[1][:, 2] - d[2][:, 1], d[2][:, 0] - d[0][:, 2], d[0][:, 1] - d[1][:, 0]], 1)
    assert np.abs(cn.velocity(pts) - curl).max() < 1e-7


@pytest.mark.parametrize("collider", [Plane((0, 0, 0.2), (0, 0, 1)),
                                      Sphere((0.1, -0.2, 0.3), 0.8),
                                      ~Sphere((0, 0, 0), 3.0)])
def test_boundary_ramp_makes_flow_tangent_and_stays_divergence_free(collider):
    base = (0.3, 0.0, 0.8)  # a uniform wind, also deflected by the ramp
    cn = CurlNoise(amplitude=1.0, frequency=1.1, octaves=2, seed=8, colliders=(collider,),
                   ramp_distance=0.6, base_velocity=base)
    free = CurlNoise(amplitude=1.0, frequency=1.1, octaves=2, seed=8, base_velocity=base)
    # points exactly on the surface: project random points onto it
    pts = RNG.uniform(-2.0, 2.0, (300, 3))
    for _ in range(3):
        d, n = union_distance(pts, (collider,))
        pts = pts - d[:, None] * n
    d, n = union_distance(pts, (collider,))
    assert np.abs(d).max() < 1e-12
    v = cn.velocity(pts)
    normal_speed = np.abs(np.einsum("ij,ij->i", v, n))
    free_normal = np.abs(np.einsum("ij,ij->i", free.velocity(pts), n))
    assert free_normal.max() > 0.1  # without the ramp the flow crosses the surface
    assert normal_speed.max() < 1e-12
    # inside the ramp band the field is still a curl: divergence -> 0 like h^2
    band = pts + n * RNG.uniform(0.05, 0.5, (pts.shape[0], 1))
    div = _fd_divergence(cn.velocity, band, 2e-6)
    assert np.abs(div).max() < 1e-6
    # beyond the band the ramp has no effect, and the base flow simply adds
    far = pts + n * 0.7
    np.testing.assert_array_equal(cn.velocity(far), free.velocity(far))
    plain = CurlNoise(amplitude=1.0, frequency=1.1, octaves=2, seed=8).velocity(far)
    np.testing.assert_allclose(free.velocity(far), plain + base, rtol=0, atol=1e-12)


def test_curl_noise_function_and_validation():
    pts = POINTS[:10]
    np.testing.assert_array_equal(curl_noise(pts, 0.0, seed=3), CurlNoise(seed=3).velocity(pts))
    with pytest.raises(ValueError, match="frequency"):
        CurlNoise(frequency=0.0)
    with pytest.raises(ValueError, match="octaves"):
        fbm3(pts, octaves=0)
    with pytest.raises(ValueError, match="gain"):
        fbm3(pts, gain=1.5)
    with pytest.raises(ValueError, match="points"):
        perlin3(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="points"):
        perlin3(np.array([[0.0, np.nan, 1.0]]))
    with pytest.raises(TypeError, match="colliders"):
        CurlNoise(colliders=("floor",))
    with pytest.raises(ValueError, match="radius"):
        Sphere((0, 0, 0), -1.0)
    with pytest.raises(TypeError):
        perlin3(1.0, 2.0)
    with pytest.raises(ValueError, match="x"):
        perlin3(math.inf, 0.0, 0.0)


def test_vectorised_array_paths_equal_the_point_kernels_bitwise():
    # The array functions evaluate octave by octave in blocks (so the loops vectorise); the
    # point kernels that fields and simulations call from Numba must give the same bits.
    from filters.noise.curl import curl_point
    from filters.noise.fractal import fbm_value, fbm_value_grad
    from filters.noise.perlin import kernel_table, kernel_tables

    pts = RNG.uniform(-6.0, 6.0, (60, 3))
    kwargs = dict(octaves=4, lacunarity=2.2, gain=0.45, frequency=0.9)
    table = kernel_table(5)
    for turbulence in (False, True):
        values, grads = fbm3(pts, seed=5, turbulence=turbulence, gradient=True, **kwargs)
        values_only = fbm3(pts, seed=5, turbulence=turbulence, **kwargs)
        for i, (x, y, z) in enumerate(pts):
            args = (table, x, y, z, 0.9, 4, 2.2, 0.45, 0.0, 0.0, 0.0, turbulence)
            assert values_only[i] == fbm_value(*args)
            v, gx, gy, gz = fbm_value_grad(*args)
            assert values[i] == v and grads[i].tolist() == [gx, gy, gz]
    cn = CurlNoise(amplitude=0.6, frequency=1.4, octaves=3, seed=9, time_scale=0.3,
                   colliders=(Sphere((0, 0, 0), 2.0),), ramp_distance=0.7,
                   base_velocity=(0.0, 0.2, 0.4))
    vel = cn.velocity(pts, 1.1)
    tables = kernel_tables(9, 3)
    for i, (x, y, z) in enumerate(pts):
        expected = curl_point(tables, cn.packed_colliders, x, y, z, 1.1, 0.6, 1.4, 3, 2.0, 0.5,
                              0.3, 0.7, 0.0, 0.2, 0.4)
        assert vel[i].tolist() == list(expected)


def test_one_set_of_shapes_for_colliders_and_the_noise_ramp():
    from filters.elastic.contact import Colliders

    shapes = (Plane((0, 0, -1.0), (0, 0, 2.0)), Sphere((0.2, 0, 0), 0.5), ~Sphere((0, 0, 0), 4.0))
    contact = Colliders()
    for shape in shapes:
        contact.add(shape)
    assert contact.shapes == shapes
    pts = RNG.uniform(-3.0, 3.0, (200, 3))
    d_contact, n_contact = contact.sdf(pts)
    d_ramp, n_ramp = union_distance(pts, contact.shapes)
    np.testing.assert_allclose(d_ramp, d_contact, rtol=0, atol=1e-12)
    np.testing.assert_allclose(n_ramp, n_contact, rtol=0, atol=1e-12)
    # the same convention as the shapes' own signed distances: negative inside the solid
    np.testing.assert_allclose(d_ramp, np.min([s(pts) for s in shapes], axis=0), atol=1e-12)
    a = CurlNoise(colliders=contact.shapes, ramp_distance=0.4).velocity(pts)
    b = CurlNoise(colliders=list(shapes), ramp_distance=0.4).velocity(pts)
    np.testing.assert_array_equal(a, b)
    with pytest.raises(TypeError, match="colliders.*boxes"):
        CurlNoise(colliders=(Box((0, 0, 0), (1, 1, 1)),), ramp_distance=0.1)


# --- the whole finite domain (issue 16, item 7) -------------------------------------------------
@pytest.mark.parametrize("far", [1e19, 1e300, -1e300, 2.0**60, -(2.0**63), 1.7e308])
def test_noise_is_defined_for_every_finite_coordinate(far):
    # floor(x) mod 256 wraps the lattice as the reference does; every float64 with |x| >= 2**60
    # is a multiple of 256, so along that axis the noise is the one at lattice coordinate 0.
    # Before: ~1e116 at 1e19 (an out-of-range float -> int64 conversion) and NaN at 1e300.
    yz = np.array([[0.3, 0.7], [4.6, -2.2], [-11.25, 0.5]])
    for axis in range(3):
        pts = np.insert(yz, axis, far, axis=1)
        ref = np.insert(yz, axis, 0.0, axis=1)
        np.testing.assert_array_equal(perlin3(pts), perlin3(ref))
        v, g = perlin3_gradient(pts)
        assert np.isfinite(g).all() and np.abs(v).max() <= 1.0
        _, _, h = perlin3_hessian(pts)
        assert np.isfinite(h).all()
        # one octave, no drift: the curl there is the curl at the wrapped point, bit for bit
        np.testing.assert_array_equal(curl_noise(pts, octaves=1, seed=4),
                                      curl_noise(ref, octaves=1, seed=4))
    pts = np.array([[far, far, far], [far, -0.4, 3.3], [2.5, far, -far]])
    octaves, gain = 6, 0.5
    bound = sum(gain**k for k in range(octaves))
    for fractal in (fbm3(pts, octaves=octaves, gain=gain, time=2.0, time_scale=0.7),
                    fbm3(pts, octaves=octaves, gain=gain, frequency=3.0, gradient=True)[1],
                    turbulence3(pts, octaves=octaves, gain=gain)):
        assert np.isfinite(fractal).all()
    assert np.abs(fbm3(pts, octaves=octaves, gain=gain)).max() <= bound
    assert 0.0 <= turbulence3(pts, octaves=octaves, gain=gain).min()
    assert turbulence3(pts, octaves=octaves, gain=gain).max() <= bound
    vel = curl_noise(pts, 1.5, amplitude=2.0, octaves=4, time_scale=0.3)
    # |curl| <= amplitude * sum_k (gain lacunarity)^k * 2 max|grad N|, max|grad N| < 3 (loose)
    assert np.isfinite(vel).all() and np.abs(vel).max() <= 2.0 * 4 * 2 * 3.0
    # coordinates that overflow to inf inside (frequency * x) wrap the same way
    assert np.isfinite(fbm3(np.array([[1e308, 0.2, 0.3]]), frequency=10.0, octaves=4)).all()


def test_non_finite_inputs_raise_naming_the_parameter():
    pts = POINTS[:4]
    for bad in (math.nan, math.inf, -math.inf):
        with pytest.raises(ValueError, match="points"):
            perlin3(np.array([[0.0, bad, 1.0]]))
        with pytest.raises(ValueError, match="points"):
            fbm3(np.array([[bad, 0.0, 1.0]]))
        with pytest.raises(ValueError, match="points"):
            curl_noise(np.array([[0.0, 0.0, bad]]))
        with pytest.raises(ValueError, match="z"):
            perlin3(0.0, 1.0, bad)
        with pytest.raises(ValueError, match="time"):
            fbm3(pts, time=bad, time_scale=1.0)
        with pytest.raises(ValueError, match="time_scale"):
            fbm3(pts, time_scale=bad)
        with pytest.raises(ValueError, match="t "):
            curl_noise(pts, bad)
        with pytest.raises(ValueError, match="frequency"):
            perlin3(pts, frequency=abs(bad))
        with pytest.raises(ValueError, match="amplitude"):
            CurlNoise(amplitude=abs(bad))
    with pytest.raises(ValueError, match="lacunarity"):
        fbm3(pts, frequency=1e300, lacunarity=16.0, octaves=16)  # last octave overflows
