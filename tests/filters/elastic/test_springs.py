"""Springs: forces, Jacobians against finite differences, system matrix, validation."""

import numpy as np
import pytest

from filters.elastic.springs import (
    SpringSystem,
    effective_stiffness,
    spring_energy,
    spring_forces,
    spring_jacobians,
)

PAIRS = np.array([[0, 1], [1, 2], [2, 3], [3, 4], [0, 4], [1, 3]])


def _random_case(seed=0):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(5, 3))
    v = rng.normal(size=(5, 3))
    d = np.linalg.norm(x[PAIRS[:, 0]] - x[PAIRS[:, 1]], axis=1)
    # stretched, compressed (rest > length), zero rest length, and mixed
    rest = d * np.array([0.5, 2.0, 0.0, 1.3, 0.7, 0.0])
    k = np.array([2.0, 3.0, 4.0, 5.0, 6.0, 7.0])
    c = np.array([0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    return x, v, rest, k, c


def _fd(fun, x, i, eps=1e-6):
    cols = []
    for q in range(3):
        xp = x.copy()
        xm = x.copy()
        xp[i, q] += eps
        xm[i, q] -= eps
        cols.append((fun(xp) - fun(xm)) / (2 * eps))
    return np.stack(cols, axis=-1)  # (S, 3, 3): d f_s / d x_iq


@pytest.mark.parametrize("mode", ["axial", "relative"])
def test_jacobians_match_central_differences(mode):
    x, v, rest, k, c = _random_case()
    jx, jv = spring_jacobians(x, PAIRS, rest, k, v, c, mode)
    assert np.any(np.linalg.norm(x[PAIRS[:, 0]] - x[PAIRS[:, 1]], axis=1) < rest)  # compressed
    for s, (a, b) in enumerate(PAIRS):
        def fx(xx, s=s):
            return spring_forces(xx, PAIRS, rest, k, v, c, mode)[s][None]

        def fv(vv, s=s):
            return spring_forces(x, PAIRS, rest, k, vv, c, mode)[s][None]

        for end, sign in ((a, 1.0), (b, -1.0)):
            num_x = _fd(fx, x, end)[0]
            num_v = _fd(fv, v, end)[0]
            scale = np.abs(jx[s]).max()
            assert np.abs(num_x - sign * jx[s]).max() / scale < 1e-6
            assert np.abs(num_v - sign * jv[s]).max() / np.abs(jv[s]).max() < 1e-6


def test_definite_jacobian_is_negative_semidefinite_for_compressed_springs():
    x, v, rest, k, c = _random_case(1)
    rest = 3.0 * np.linalg.norm(x[PAIRS[:, 0]] - x[PAIRS[:, 1]], axis=1)  # all compressed
    jx_exact, _ = spring_jacobians(x, PAIRS, rest, k, definite=False)
    jx, _ = spring_jacobians(x, PAIRS, rest, k, definite=True)
    assert max(np.linalg.eigvalsh(-j).min() for j in jx_exact) < -1e-3  # exact is indefinite
    for j in jx:
        assert np.allclose(j, j.T)
        assert np.linalg.eigvalsh(-j).min() > -1e-12


def test_seed_force_form_and_zero_rest_length():
    x = np.array([[1.5, 0.0, 0.0], [0.0, 0.0, 0.0]])
    f = spring_forces(x, [[0, 1]], 1.0, 10.0)
    assert np.allclose(f, [[-10.0 * (1.5 / 1.0 - 1.0), 0.0, 0.0]])
    f0 = spring_forces(x, [[0, 1]], 0.0, 4.0)  # linear spring, k in N/m
    assert np.allclose(f0, [[-6.0, 0.0, 0.0]])
    # coincident ends of a positive-rest-length spring: no direction, no force, no NaN
    assert np.allclose(spring_forces(np.zeros((2, 3)), [[0, 1]], 1.0, 1.0), 0.0)
    assert np.allclose(effective_stiffness([10.0, 4.0], [0.5, 0.0]), [20.0, 4.0])
    v = np.array([[1.0, 2.0, 0.0], [0.0, 0.0, 0.0]])
    assert np.allclose(spring_forces(x, [[0, 1]], 1.5, 0.0, v, 3.0, "axial"), [[-3.0, 0, 0]])
    assert np.allclose(spring_forces(x, [[0, 1]], 1.5, 0.0, v, 3.0, "relative"), [[-3.0, -6.0, 0]])


def test_forces_are_minus_energy_gradient():
    x, _, rest, k, _ = _random_case(2)
    sysm = SpringSystem(PAIRS, rest, k, np.ones(5), gravity=(0, 0, 0))
    f = sysm.forces(x, np.zeros_like(x))
    eps = 1e-6
    for i in range(5):
        for q in range(3):
            xp, xm = x.copy(), x.copy()
            xp[i, q] += eps
            xm[i, q] -= eps
            g = (spring_energy(xp, PAIRS, rest, k) - spring_energy(xm, PAIRS, rest, k)) / (2 * eps)
            assert abs(-g - f[i, q]) < 1e-6 * max(1.0, abs(f[i, q]))
    assert np.allclose(f.sum(axis=0), 0.0, atol=1e-12)  # action = reaction


@pytest.mark.parametrize("mode", ["axial", "relative"])
def test_system_matrix_matches_dense_assembly(mode):
    x, v, rest, k, c = _random_case(3)
    m = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    pinned = np.array([False, True, False, False, False])
    h, drag = 0.01, 0.25
    sysm = SpringSystem(PAIRS, rest, k, m, damping=c, damping_mode=mode, drag=drag,
                        pinned=pinned)
    mat = sysm.system_matrix(x, x, h).toarray()
    jx, jv = spring_jacobians(x, PAIRS, rest, k, np.zeros_like(x), c, mode, definite=True,
                              damping_dx=False)
    dense = np.zeros((15, 15))
    for i in range(5):
        dense[3 * i:3 * i + 3, 3 * i:3 * i + 3] += (m[i] / h ** 2 + drag / h) * np.eye(3)
    for s, (a, b) in enumerate(PAIRS):
        blk = -jx[s] - jv[s] / h
        for p, q, sg in ((a, a, 1), (b, b, 1), (a, b, -1), (b, a, -1)):
            dense[3 * p:3 * p + 3, 3 * q:3 * q + 3] += sg * blk
    for i in np.flatnonzero(pinned):
        dense[3 * i:3 * i + 3, :] = 0.0
        dense[:, 3 * i:3 * i + 3] = 0.0
        dense[3 * i:3 * i + 3, 3 * i:3 * i + 3] = np.eye(3)
    assert np.allclose(mat, dense, rtol=1e-13, atol=1e-10)
    assert np.allclose(mat, mat.T)
    assert np.linalg.eigvalsh(mat).min() > 0.0


@pytest.mark.parametrize("kwargs, match", [
    (dict(stiffness=-1.0), "stiffness"),
    (dict(rest_lengths=-0.1), "rest_lengths"),
    (dict(damping=-2.0), "damping"),
    (dict(springs=[[0, 0]]), "different"),
    (dict(springs=[[0, 7]]), "springs"),
    (dict(springs=[0, 1]), "springs"),
    (dict(damping_mode="viscous"), "damping_mode"),
])
def test_bad_input_raises_value_error(kwargs, match):
    args = dict(springs=[[0, 1]], rest_lengths=1.0, stiffness=1.0, damping=0.0,
                damping_mode="axial")
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        spring_forces(np.zeros((2, 3)) + [[0, 0, 0], [1, 0, 0]], args["springs"],
                      args["rest_lengths"], args["stiffness"], None, args["damping"],
                      args["damping_mode"])


def test_system_bad_masses_and_pins():
    with pytest.raises(ValueError, match="masses"):
        SpringSystem([[0, 1]], 1.0, 1.0, [1.0, 0.0])
    with pytest.raises(ValueError, match="pinned"):
        SpringSystem([[0, 1]], 1.0, 1.0, [1.0, 1.0], pinned=[True])
    with pytest.raises(ValueError, match="drag"):
        SpringSystem([[0, 1]], 1.0, 1.0, [1.0, 1.0], drag=-1.0)



@pytest.mark.parametrize("mode", [0, 1])
def test_vectorised_forces_are_the_scalar_formula_bit_for_bit(mode):
    """spring_forces_into (branch-free, vectorised) gives the bits of spring_force3 (the
    branching per-spring formula), also for zero-length and zero-rest-length springs, and the
    serial explicit step sums them per particle in spring order."""
    from filters.elastic.spring_kernels import per_spring_forces, spring_forces_into

    rng = np.random.default_rng(3)
    n, s = 60, 400
    x = rng.standard_normal((n, 3))
    x[8] = x[7]  # spring 0 below has zero length
    v = rng.standard_normal((n, 3))
    pairs = rng.integers(0, n, (s, 2))
    pairs[:, 1] = np.where(pairs[:, 1] == pairs[:, 0], (pairs[:, 0] + 1) % n, pairs[:, 1])
    pairs[0] = (7, 8)
    rest = rng.uniform(0.1, 2.0, s)
    rest[::9] = 0.0
    rest[0] = 0.5
    c = rng.uniform(0.0, 3.0, s)
    masses = rng.uniform(0.5, 2.0, n)
    system = SpringSystem(pairs, rest, rng.uniform(1.0, 100.0, s), masses, damping=c,
                          damping_mode=("axial", "relative")[mode], drag=0.2)
    ke = system.ke
    fs = np.empty((s, 3))
    per_spring_forces(x, v, pairs, ke, rest, c, mode, fs)
    buf = np.empty((6, s))
    ends = [np.ascontiguousarray(pairs[:, k], dtype=np.uint32) for k in (0, 1)]
    spring_forces_into(x, v, *ends, ke, rest, c, mode, buf, 0, s)
    assert np.array_equal(buf[:3].T, fs)
    if mode == 0:
        assert np.all(buf[:3, 0] == 0.0)  # no direction, no axial force
    f = masses[:, None] * system.gravity - 0.2 * v
    for k in range(s):  # the scatter in spring order
        f[pairs[k, 0]] += fs[k]
        f[pairs[k, 1]] -= fs[k]
    h = 1e-3
    x1, v1 = x.copy(), v.copy()
    system.symplectic_step(x1, v1, h)
    v_ref = v + (h * (1.0 / masses))[:, None] * f
    assert np.array_equal(v1, v_ref)
    assert np.array_equal(x1, x + h * v_ref)


@pytest.mark.parametrize("mode", ["axial", "relative"])
def test_the_parallel_explicit_step_gives_the_serial_steps_bits(mode, monkeypatch):
    """Above PARALLEL_MIN_SPRINGS_EXPLICIT the explicit step gathers each particle's forces in
    parallel; in spring order (the incidence lists of incidence_in_spring_order) it adds them
    as the serial kernel's scatter does, so where the threshold lies changes no bit."""
    import filters.elastic.springs as springs_module

    rng = np.random.default_rng(5)
    n, s = 300, 2000
    x0 = rng.standard_normal((n, 3))
    v0 = rng.standard_normal((n, 3))
    pairs = rng.integers(0, n, (s, 2))
    pairs[:, 1] = np.where(pairs[:, 1] == pairs[:, 0], (pairs[:, 0] + 1) % n, pairs[:, 1])
    rest = rng.uniform(0.1, 2.0, s)
    rest[::7] = 0.0
    system = SpringSystem(pairs, rest, rng.uniform(1.0, 100.0, s), rng.uniform(0.5, 2.0, n),
                          damping=rng.uniform(0.0, 3.0, s), damping_mode=mode, drag=0.1,
                          pinned=np.arange(n) < 3)
    runs = []
    for threshold in (2**62, 0):  # serial, then parallel
        monkeypatch.setattr(springs_module, "PARALLEL_MIN_SPRINGS_EXPLICIT", threshold)
        x, v = x0.copy(), v0.copy()
        for _ in range(50):
            system.symplectic_step(x, v, 1e-3)
        runs.append((x, v))
    (xs, vs), (xp, vp) = runs
    assert not np.array_equal(xs, x0)
    assert np.array_equal(xs, xp) and np.array_equal(vs, vp)
