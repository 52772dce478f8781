"""Matrix-free spring operator and its PCG: same matrix as the CSR assembly, same solutions."""

import numpy as np
import pytest

from filters.elastic.springs import SpringSystem
from filters.elastic.topology import cloth_grid
from filters.integrators import backward_euler
from filters.linalg import LinearSolver, pcg_operator, solve_linear
from filters.simulation import State


def _system(mode, damping, drag=0.0, zero_rest=False):
    top = cloth_grid(6, 5, size=(0.5, 0.4), origin=(0, 0, 0), plane="xy",
                     areal_density=0.5).with_pins([0, 5])
    rest = np.zeros_like(top.rest_lengths) if zero_rest else top.rest_lengths
    system = SpringSystem(top.springs, rest, 50.0, np.full(top.positions.shape[0], 0.02),
                          damping=damping, damping_mode=mode, drag=drag, pinned=top.pinned)
    return top, system


@pytest.mark.parametrize("mode,damping,drag,zero_rest", [("axial", 0.7, 0.0, False),
                                                         ("relative", 0.3, 0.2, False),
                                                         ("axial", 0.0, 0.0, True)])
def test_operator_equals_assembled_matrix(mode, damping, drag, zero_rest):
    top, system = _system(mode, damping, drag, zero_rest=zero_rest)
    rng = np.random.default_rng(3)
    # compress some springs (clamped transverse term) and move the damping directions
    x = top.positions * 0.9 + 0.01 * rng.standard_normal(top.positions.shape)
    xdir = top.positions + 0.02 * rng.standard_normal(top.positions.shape)
    h = 1.0 / 60.0
    dense = system.system_matrix(x, xdir, h).toarray()
    op = system.implicit_operator(x, xdir, h)
    cols = np.stack([op.matvec(e) for e in np.eye(dense.shape[0])], axis=1)
    np.testing.assert_allclose(cols, dense, rtol=1e-12, atol=1e-9 * np.abs(dense).max())


def test_operator_with_contact_blocks_equals_assembled_matrix():
    """The linear solver adds contact blocks to the particles' diagonal blocks the same way
    on the matrix-free operator and on the CSR matrix, leaving pinned rows the identity."""
    top, system = _system("axial", 0.5)
    rng = np.random.default_rng(8)
    x = top.positions + 0.01 * rng.standard_normal(top.positions.shape)
    a = rng.standard_normal((x.shape[0], 3, 3))
    blocks = np.einsum("nij,nkj->nik", a, a)  # SPD
    h = 0.01
    dense = LinearSolver("direct").operator(system, x, x, h, blocks).toarray()
    op = LinearSolver("pcg").operator(system, x, x, h, blocks)
    cols = np.stack([op.matvec(e) for e in np.eye(dense.shape[0])], axis=1)
    np.testing.assert_allclose(cols, dense, rtol=1e-12, atol=1e-9 * np.abs(dense).max())
    plain = system.system_matrix(x, x, h).toarray()
    free = np.repeat(~system.pinned, 3)
    expected = plain.copy()
    for i in np.flatnonzero(~system.pinned):
        expected[3 * i:3 * i + 3, 3 * i:3 * i + 3] += blocks[i]
    np.testing.assert_allclose(dense, expected, rtol=1e-12, atol=1e-12)
    assert np.array_equal(dense[~free][:, ~free], np.eye(int((~free).sum())))


@pytest.mark.parametrize("preconditioner", ["block_jacobi", "sgs", "ssor"])
def test_pcg_operator_matches_direct_solve(preconditioner):
    top, system = _system("axial", 0.5, drag=0.1)
    rng = np.random.default_rng(4)
    x = top.positions + 0.01 * rng.standard_normal(top.positions.shape)
    h = 1.0 / 30.0
    mat = system.system_matrix(x, x, h)
    b = rng.standard_normal(top.positions.shape)
    b[system.pinned] = rng.standard_normal((int(system.pinned.sum()), 3))  # identity rows
    xd, _, _ = solve_linear(mat, b.ravel(), solver="direct")
    xp, it, res = pcg_operator(system.implicit_operator(x, x, h), b, tol=1e-12, max_iter=2000,
                               preconditioner=preconditioner)
    assert res <= 1e-12 and it > 0
    np.testing.assert_allclose(xp.ravel(), xd, rtol=0, atol=1e-9 * np.abs(xd).max())
    # a warm start at the solution needs (almost) no iterations
    _, it_warm, _ = pcg_operator(system.implicit_operator(x, x, h), b, xd.reshape(-1, 3),
                                 tol=1e-8, preconditioner=preconditioner)
    assert it_warm <= 2
    with pytest.raises(ValueError, match="preconditioner"):
        pcg_operator(system.implicit_operator(x, x, h), b, preconditioner="ilu")
    with pytest.raises(ValueError, match="omega"):
        pcg_operator(system.implicit_operator(x, x, h), b, preconditioner="ssor", omega=2.0)


def test_ssor_reports_the_true_residual_and_beats_block_jacobi_on_stiff_cloth():
    # a stiff 16x16 cloth (k_e h^2 / m ~ 3e3), sagging: the case the SSOR default is for
    top = cloth_grid(16, 16, size=(1.5, 1.5), origin=(0, 0, 0), plane="xy",
                     areal_density=10.0).with_pins([0, 15])
    system = SpringSystem(top.springs, top.rest_lengths, 1e5 * top.rest_lengths,
                          top.masses, pinned=top.pinned)
    x = top.positions.copy()
    x[:, 2] -= 0.3 * np.sin(np.pi * x[:, 0] / 1.5) * np.sin(np.pi * x[:, 1] / 3.0)
    h = 1.0 / 30.0
    rng = np.random.default_rng(5)
    b = rng.standard_normal(x.shape)
    b[system.pinned] = 0.0
    op = system.implicit_operator(x, x, h)
    iterations = {}
    for prec, omega in (("block_jacobi", 1.6), ("ssor", 1.0), ("ssor", 1.6)):
        xs, it, res = pcg_operator(op, b, tol=1e-6, max_iter=5000, preconditioner=prec,
                                   omega=omega)
        true = np.linalg.norm(b - op.matvec(xs)) / np.linalg.norm(b)
        assert res <= 1e-6 and true <= 1.01e-6 and true == pytest.approx(res, rel=1e-3)
        iterations[prec, omega] = it
    # over-relaxation helps, and SSOR needs far fewer iterations than block Jacobi
    assert iterations["ssor", 1.6] < iterations["ssor", 1.0]
    assert 2 * iterations["ssor", 1.6] < iterations["block_jacobi", 1.6]


def test_newton_with_forcing_matches_direct_and_is_deterministic():
    top, system = _system("axial", 0.2)
    h = 1.0 / 60.0
    states = {}
    for name, opts in (("direct", dict(solver="direct", newton_tol=1e-7)),
                       ("ew", dict(solver="pcg", newton_tol=1e-7)),
                       ("ew2", dict(solver="pcg", newton_tol=1e-7)),
                       ("sgs", dict(solver="pcg", preconditioner="sgs", newton_tol=1e-7,
                                    forcing=None, tol=1e-8)),
                       ("jacobi", dict(solver="pcg", preconditioner="block_jacobi",
                                       newton_tol=1e-7))):
        state = State(top.positions.copy())
        for _ in range(5):
            backward_euler(system, state, h, **opts)
        states[name] = state
    for name in ("ew", "sgs", "jacobi"):
        np.testing.assert_allclose(states[name].positions, states["direct"].positions,
                                   rtol=0, atol=1e-6)
    np.testing.assert_array_equal(states["ew"].positions, states["ew2"].positions)
    with pytest.raises(ValueError, match="forcing"):
        backward_euler(system, State(top.positions.copy()), h, forcing=1.5)
