"""Benchmark: mass-spring cloth — implicit Newton steps, and explicit substeps against NVIDIA Warp.

Run (under the project's benchmark lock)::

    flock /tmp/blobflow-bench.lock env OPENBLAS_NUM_THREADS=1 python benchmarks/bench_springs.py

1. **Implicit**: a cloth of 64x64 and 128x128 particles (0.1 m cells, 0.1 kg particles — the
   scales of Warp's cloth benchmark), structural + shear + bend springs of stiffness
   ``k_e = 1e4`` N/m (Hooke form, i.e. the seed-form ``k = 1e4 L`` N), pinned at two corners and
   released horizontal under gravity; backward Euler by Newton with line search at
   ``h = 1/60`` s with each solver variant of :data:`VARIANTS` (block-Jacobi PCG on the CSR
   matrix with a fixed tolerance — the solver before the matrix-free operator —; matrix-free PCG
   with block Jacobi, symmetric Gauss-Seidel or SSOR with Eisenstat's trick (the default), with
   a fixed tolerance or an Eisenstat-Walker forcing sequence; SuperLU direct), interleaved step
   by step.  Reported: ms per step (median
   and min), Newton and PCG iterations per step, and the largest difference of the final state
   to the direct-solve run.
2. **Explicit**: symplectic Euler substeps of the same 64x64 cloth with Warp's cloth-benchmark
   parameters (``k_e = 1000`` N/m, axial damping 10 N s/m, 16 substeps per 1/60 s frame), against
   Warp's own ``benchmark_cloth_warp.WpIntegrator`` on its CPU device, with the same particles and
   springs, in the same process.

``--explicit-only`` re-times part 2 alone (and profiles the serial substep: gather, force loop,
scatter, :func:`explicit_profile`) and replaces its entries in the results file (the
implicit rows stay as they were, with their own machine record).

BLAS is pinned to one thread before NumPy loads (threadpoolctl as well), because this machine's
multithreaded OpenBLAS makes sparse iterative solves 30-150x slower.  Results go to
``benchmarks/results/springs.json``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import json  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from types import SimpleNamespace  # noqa: E402

import numpy as np  # noqa: E402

try:
    from threadpoolctl import threadpool_limits  # noqa: E402
except ImportError:  # pragma: no cover
    threadpool_limits = None

import numba  # noqa: E402

from filters.elastic import springs as springs_module  # noqa: E402
from filters.elastic.springs import SpringSystem  # noqa: E402
from filters.elastic.topology import cloth_grid  # noqa: E402
from filters.integrators import backward_euler, linearized_backward_euler  # noqa: E402
from filters.simulation import State  # noqa: E402

RESULTS = Path(__file__).parent / "results" / "springs.json"

#: The implicit numbers of commit 10d0909 (CSR block-Jacobi PCG, fixed tol 1e-3, parallel
#: incremental-potential reduction), from its springs.json, for the record; the same solver is
#: re-timed in every run as the ``csr_block_jacobi_fixed_tol`` variant.
BEFORE = {
    "64x64_newton_pcg": dict(ms_per_step_median=85.7, newton_iterations_mean=3.25,
                             pcg_iterations_mean=127.75),
    "128x128_newton_pcg": dict(ms_per_step_median=382.0, newton_iterations_mean=2.67,
                               pcg_iterations_mean=112.0),
    "64x64_k1e5_newton_auto": dict(ms_per_step_median=214.2, newton_iterations_mean=3.75,
                                   pcg_iterations_mean=344.5),
    "64x64_hanging_linearized_auto": dict(ms_per_step_median=53.2, pcg_iterations_mean=91.5),
}
#: The implicit numbers of commit be7fe6e (matrix-free operator, block-Jacobi PCG with
#: Eisenstat-Walker forcing as the default), from its springs.json, for the record: the default
#: is now SSOR with Eisenstat's trick (``operator_ssor_ew`` / ``auto_default``).
BEFORE_SSOR = {
    "64x64_newton_auto_default": dict(ms_per_step_median=20.9, ms_per_step_min=12.9,
                                      newton_iterations_mean=3.33, pcg_iterations_mean=102.25),
    "128x128_newton_operator_block_jacobi_ew": dict(ms_per_step_median=89.7,
                                                    ms_per_step_min=52.0,
                                                    newton_iterations_mean=2.67,
                                                    pcg_iterations_mean=86.7),
    "64x64_k1e5_newton_operator_block_jacobi_ew": dict(ms_per_step_median=43.6,
                                                       ms_per_step_min=38.5,
                                                       newton_iterations_mean=3.75,
                                                       pcg_iterations_mean=259.2),
    "64x64_hanging_linearized_auto": dict(ms_per_step_median=19.2, pcg_iterations_mean=91.5),
}
CELL = 0.1
MASS = 0.1


def _cloth(n, plane="xy"):
    top = cloth_grid(n, n, size=((n - 1) * CELL, (n - 1) * CELL), origin=(0, 0, 0), plane=plane,
                     areal_density=MASS / CELL ** 2)
    return top.with_pins([0, n - 1])


class _CSROnly:
    """A SpringSystem seen without its matrix-free operator: the integrators then run PCG on the
    assembled CSR matrix (the solver of commit 10d0909, kept as the "before" variant)."""

    def __init__(self, system):
        self._system = system

    def __getattr__(self, name):
        return getattr(self._system, name)

    def implicit_operator(self, x, xdir, h):
        return None  # no matrix-free form: the solvers assemble the CSR matrix


#: Implicit solver variants timed side by side (name -> (solver, options, CSR only)).
VARIANTS = {
    # before: block-Jacobi PCG on the CSR matrix, every Newton solve to tol = 1e-3
    "csr_block_jacobi_fixed_tol": ("pcg", dict(forcing=None), True),
    # matrix-free operator, same iterations as before
    "operator_block_jacobi_fixed_tol": ("pcg", dict(forcing=None,
                                                    preconditioner="block_jacobi"), False),
    # matrix-free + Eisenstat-Walker forcing (the default of backward_euler)
    "operator_block_jacobi_ew": ("pcg", dict(preconditioner="block_jacobi"), False),
    "operator_sgs_ew": ("pcg", dict(preconditioner="sgs"), False),
    # block SSOR with Eisenstat's trick (the default preconditioner of backward_euler)
    "operator_ssor_ew": ("pcg", dict(preconditioner="ssor"), False),
    "auto_default": ("auto", dict(), False),
    "direct": ("direct", dict(), False),
}


def implicit(n, variants, steps, k_hooke=1e4, scheme="backward_euler", plane="xy"):
    """Time implicit steps of each variant, interleaved step by step (so that a slow spell of
    the shared machine hits all variants alike); each variant advances its own cloth."""
    top = _cloth(n, plane)
    rest = top.rest_lengths
    h = 1.0 / 60.0
    step = backward_euler if scheme == "backward_euler" else linearized_backward_euler
    runs = {}
    for name in variants:
        solver, options, csr_only = VARIANTS[name]
        if scheme != "backward_euler":
            options = {k: v for k, v in options.items() if k != "forcing"}
        # uniform particle masses, as in Warp's benchmark
        system = SpringSystem(top.springs, rest, k_hooke * rest, np.full(n * n, MASS),
                              pinned=top.pinned)
        target = _CSROnly(system) if csr_only else system
        state = State(top.positions.copy())
        step(target, state, h, solver=solver, **options)  # compile, pattern, first step
        runs[name] = (system, target, state, solver, options, dict(t=[], nw=[], li=[], di=[]))
    for _ in range(steps):
        for _name, (_system, target, state, solver, options, rec) in runs.items():
            t0 = time.perf_counter()
            info = step(target, state, h, solver=solver, **options)
            rec["t"].append(time.perf_counter() - t0)
            rec["nw"].append(info.newton_iterations)
            rec["li"].append(info.linear_iterations)
            rec["di"].append(info.direct_solves)
    rows = []
    ref = runs[variants[-1]][2] if variants[-1] == "direct" else None
    for name, (system, _target, state, solver, options, rec) in runs.items():
        row = dict(particles=n * n, springs=int(top.springs.shape[0]), unknowns=3 * n * n,
                   start="hanging" if plane == "xz" else "horizontal, pinned at two corners",
                   nnz_csr=int(system.system_matrix(state.positions, state.positions, h).nnz),
                   scheme=scheme, variant=name, solver=solver,
                   options={k: v for k, v in options.items()}, h=h,
                   k_hooke_N_per_m=k_hooke, steps=steps,
                   ms_per_step_median=1e3 * float(np.median(rec["t"])),
                   ms_per_step_min=1e3 * float(np.min(rec["t"])),
                   ms_per_step_mean=1e3 * float(np.mean(rec["t"])),
                   newton_iterations_mean=float(np.mean(rec["nw"])),
                   pcg_iterations_mean=float(np.mean(rec["li"])),
                   direct_solves_mean=float(np.mean(rec["di"])),
                   final_energy_J=system.energy(state.positions, state.velocities))
        if ref is not None:
            # difference to the direct-solve run after the same steps (inexact-Newton accuracy)
            row["max_position_diff_to_direct_m"] = float(np.abs(state.positions
                                                                - ref.positions).max())
            row["max_velocity_diff_to_direct_m_per_s"] = float(np.abs(
                state.velocities - ref.velocities).max())
        rows.append(row)
    return rows


def _warp_integrator(top, damping):
    sys.path.insert(0, str(Path(__import__("warp").__file__).parent / "examples" / "benchmarks"))
    import benchmark_cloth_warp  # Warp's own integrator of its cloth benchmark

    rest = top.rest_lengths.astype(np.float32)
    inv = np.where(top.pinned, 0.0, 1.0 / MASS).astype(np.float32)
    # Warp's benchmark cloth hangs in the x-y plane with gravity along -y: same geometry.
    pos = top.positions[:, [0, 2, 1]].astype(np.float32)
    cloth = SimpleNamespace(
        positions=pos, inv_masses=inv, spring_indices=top.springs.astype(np.int32).ravel(),
        spring_lengths=rest, spring_stiffness=np.full(len(rest), 1000.0, np.float32),
        spring_damping=np.full(len(rest), damping, np.float32),
        num_particles=pos.shape[0], num_springs=len(rest))
    return benchmark_cloth_warp.WpIntegrator(cloth, "cpu")


def explicit(n=64, frames=10, substeps=16, repeats=9):
    """Symplectic Euler substeps, ours and Warp's, interleaved; best of ``repeats`` each.

    The machine is shared, so the implementations take turns (ours as configured — parallel on 2
    threads above ``PARALLEL_MIN_SPRINGS_EXPLICIT`` springs —, ours forced serial, Warp) and each
    keeps its fastest block of ``frames * substeps`` substeps: a slow block caused by another
    process then hits all of them alike instead of one.
    """
    import warp as wp

    wp.config.quiet = True
    wp.init()
    top = _cloth(n, plane="xz")  # hanging, like Warp's benchmark
    rest = top.rest_lengths
    damping = 10.0
    h_frame = 1.0 / 60.0
    h = h_frame / substeps
    system = SpringSystem(top.springs, rest, 1000.0 * rest, np.full(n * n, MASS),
                          damping=damping, damping_mode="axial", pinned=top.pinned)
    x = top.positions.copy()
    v = np.zeros_like(x)

    default_threshold = springs_module.PARALLEL_MIN_SPRINGS_EXPLICIT

    def ours(threshold):
        springs_module.PARALLEL_MIN_SPRINGS_EXPLICIT = threshold
        try:
            t0 = time.perf_counter()
            for _ in range(frames * substeps):
                system.symplectic_step(x, v, h)
            return time.perf_counter() - t0
        finally:
            springs_module.PARALLEL_MIN_SPRINGS_EXPLICIT = default_threshold

    integrator = _warp_integrator(top, damping)

    def warp():
        t0 = time.perf_counter()
        for _ in range(frames):
            integrator.simulate(h_frame, substeps)
        return time.perf_counter() - t0

    runs = {"blobflow_numba_default": lambda: ours(default_threshold),
            "blobflow_numba_serial": lambda: ours(2**62),
            "warp_cpu": warp}
    for run in runs.values():  # compile and warm up
        run()
    best = {name: np.inf for name in runs}
    for _ in range(repeats):
        for name, run in runs.items():
            best[name] = min(best[name], run() / (frames * substeps))
    results = {name: dict(us_per_substep=1e6 * t) for name, t in best.items()}
    results["warp_cpu"]["version"] = wp.config.version
    results["speedup_vs_warp"] = best["warp_cpu"] / best["blobflow_numba_default"]
    results["speedup_vs_warp_serial"] = best["warp_cpu"] / best["blobflow_numba_serial"]
    results["numba_threads"] = numba.get_num_threads()
    results["default_is_parallel"] = bool(top.springs.shape[0] >= default_threshold)
    results["particles"] = n * n
    results["springs"] = int(top.springs.shape[0])
    results["substep_s"] = h
    results["finite"] = bool(np.isfinite(x).all())
    return results


def explicit_profile(n=64, repeats=15, inner=200):
    """Where one serial explicit substep's time goes (1 thread, the cloth of :func:`explicit`).

    Best time of: the whole step (``symplectic_serial``); the springs' forces alone
    (``spring_forces_into``: end-point differences gathered, then the vectorised force loop);
    the gather alone (12 loads from the particles' arrays and 6 stores per spring).  The compute
    is forces minus gather, the scatter and update the step minus forces.  Each part is set
    against what bounds it on this core: the gather's and the scatter's memory operations per
    spring, the force loop's square root and division per spring (both on the divider).
    """
    from numba import njit

    from filters.elastic.spring_kernels import spring_forces_into, symplectic_serial

    @njit(cache=False)
    def gather(x, v, pa, pb, buf, reps):
        for _ in range(reps):
            for s in range(pa.shape[0]):
                a = pa[s]
                b = pb[s]
                for q in range(3):
                    buf[q, s] = x[a, q] - x[b, q]
                    buf[3 + q, s] = v[a, q] - v[b, q]

    @njit(cache=False, error_model="numpy")
    def forces(x, v, pa, pb, ke, rest, c, mode, buf, reps):
        for _ in range(reps):
            spring_forces_into(x, v, pa, pb, ke, rest, c, mode, buf, 0, pa.shape[0])

    @njit(cache=False, error_model="numpy")
    def step(x, v, pa, pb, ke, rest, c, mode, masses, inv_mass, gravity, drag, h, f, buf, reps):
        for _ in range(reps):
            symplectic_serial(x, v, pa, pb, ke, rest, c, mode, masses, inv_mass, gravity, drag,
                              h, f, buf)

    top = _cloth(n, plane="xz")
    rest = top.rest_lengths
    sy = SpringSystem(top.springs, rest, 1000.0 * rest, np.full(n * n, MASS), damping=10.0,
                      damping_mode="axial", pinned=top.pinned)
    x = top.positions.copy()
    v = np.zeros_like(x)
    f = np.empty_like(x)
    buf = np.empty((6, rest.size))
    h = 1.0 / 60.0 / 16
    args = (sy._pa, sy._pb, sy.ke, sy.rest, sy.damping, sy.mode)
    step(x, v, *args, sy.masses, sy.inv_mass, sy.gravity, sy.drag, h, f, buf, 200)  # moving
    runs = {"step": lambda r: step(x, v, *args, sy.masses, sy.inv_mass, sy.gravity, sy.drag, h,
                                   f, buf, r),
            "forces": lambda r: forces(x, v, *args, buf, r),
            "gather": lambda r: gather(x, v, sy._pa, sy._pb, buf, r)}
    for run in runs.values():
        run(1)
    best = {name: np.inf for name in runs}
    for _ in range(repeats):  # in turns: a slow spell of the machine hits all alike
        for name, run in runs.items():
            t0 = time.perf_counter()
            run(inner)
            best[name] = min(best[name], (time.perf_counter() - t0) / inner)
    us = {name: 1e6 * t for name, t in best.items()}
    springs = rest.size
    parts = {"gather": us["gather"], "force_loop": us["forces"] - us["gather"],
             "scatter_and_update": us["step"] - us["forces"]}
    return dict(particles=n * n, springs=springs, step_us=us["step"],
                parts_us=parts, parts_ns_per_spring={k: 1e3 * t / springs
                                                     for k, t in parts.items()},
                kernels="serial (one thread)")


def _best_us(fn, repeats=30, inner=5):
    """Best time (us) of ``fn`` over ``repeats`` blocks of ``inner`` calls (after one call)."""
    fn()
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(inner):
            fn()
        best = min(best, (time.perf_counter() - t0) / inner)
    return 1e6 * best


def profile(sizes=(32, 64, 128), steps=3):
    """Where an implicit step's time goes, and why the PCG iterations cannot go much faster.

    Per cloth size: the default step's Newton and PCG iterations, and the best time of each
    kernel of one Newton iteration on the state after ``steps`` steps: forces, the operator's
    blocks, the SSOR set-up, one PCG iteration's product (``_ssor_apply``: a backward and a
    forward sweep over the springs), the CSR-free product ``H p`` and the two sweeps alone;
    then the sweeps' data (bytes a sweep reads and writes) against their time, next to a
    streaming triad over the same number of bytes.  A sweep that costs the same nanoseconds
    per particle at every size (its data in L1, L2 or beyond) is bound by the latency of the
    Gauss-Seidel recurrence (particle ``i`` needs ``i + 1``'s result, summed in a fixed order
    for the same bits), not by memory bandwidth.
    """
    from numba import njit

    from filters.linalg import ssor as ssor_module
    from filters.linalg.operator import block_matvec

    @njit(cache=False)
    def triad(a, b, c, s):
        for i in range(a.shape[0]):
            a[i] = b[i] + s * c[i]

    rows = []
    h = 1.0 / 60.0
    for n in sizes:
        top = _cloth(n)
        rest = top.rest_lengths
        system = SpringSystem(top.springs, rest, 1e4 * rest, np.full(n * n, MASS),
                              pinned=top.pinned)
        state = State(top.positions.copy())
        info = None
        newton, pcg = [], []
        for _ in range(steps):
            info = backward_euler(system, state, h)
            newton.append(info.newton_iterations)
            pcg.append(info.linear_iterations)
        x = state.positions
        op = system.implicit_operator(x, x, h)
        work = ssor_module.SSORWorkspace().get(op.diag.shape[0], op.upper[1].shape[0])
        dsc, dinv, _, t, qv, acc, w, r, pv, ax, res, acc6 = work
        up_ptr, up_spring, up_other = op.upper
        free, omega = op.free, ssor_module.DEFAULT_OMEGA
        rhs = np.random.default_rng(0).standard_normal((n * n, 3))
        f = np.empty_like(x)
        ke, rl, dm = system._op_params
        ns = op.pairs.shape[0]
        kernels = dict(
            forces=lambda: system.conservative_forces(x, f),
            operator_blocks=lambda: system.implicit_operator(x, x, h),
            ssor_setup=lambda: ssor_module._ssor_setup(free, op.blocks, op.diag, up_ptr,
                                                       up_spring, up_other, omega, dsc, dinv,
                                                       op.blocks, False, acc6),
            pcg_iteration_product=lambda: ssor_module._ssor_apply(
                up_ptr, up_other, op.blocks, dinv, free, omega, rhs, 0.5, pv, t, qv, acc, w),
            forward_sweep=lambda: ssor_module._ssor_forward(up_ptr, up_other, op.blocks, dinv,
                                                           free, rhs, t, acc),
            backward_sweep=lambda: ssor_module._ssor_backward(up_ptr, up_other, op.blocks,
                                                             dinv, free, rhs, t),
            matvec=lambda: block_matvec(op.pairs, free, op.blocks, op.diag, rhs, res),
        )
        us = {name: _best_us(fn) for name, fn in kernels.items()}
        # a sweep streams the blocks (6 float64) and other end (int64) of every spring, and per
        # particle reads D'^-1 (9), its right-hand side (3) and writes its result (3)
        sweep_bytes = ns * (6 * 8 + 8 + 8) + n * n * (9 + 3 + 3 + 3) * 8
        m = sweep_bytes // 24
        a, b, c = np.zeros(m), np.ones(m), np.ones(m)
        triad_us = _best_us(lambda: triad(a, b, c, 0.5))
        sweep_us = 0.5 * (us["forward_sweep"] + us["backward_sweep"])
        rows.append(dict(
            particles=n * n, springs=ns, newton_iterations_mean=float(np.mean(newton)),
            pcg_iterations_mean=float(np.mean(pcg)), kernel_us_best=us,
            pcg_iterations_floor_ms=1e-3 * float(np.mean(pcg)) * us["pcg_iteration_product"],
            sweep_ns_per_particle=1e3 * sweep_us / (n * n),
            sweep_ns_per_spring=1e3 * sweep_us / ns,
            sweep_bytes=int(sweep_bytes), sweep_GB_per_s=sweep_bytes / (1e3 * sweep_us),
            triad_same_bytes_GB_per_s=sweep_bytes / (1e3 * triad_us)))
        print(json.dumps(rows[-1]), flush=True)
    return rows


def _machine():
    return dict(platform=platform.platform(), cpus=os.cpu_count(),
                numba_threads=numba.get_num_threads(), load_average=os.getloadavg())


def _explicit_summary(rounds):
    return dict(
        particles=rounds[0]["particles"], springs=rounds[0]["springs"],
        substep_s=rounds[0]["substep_s"],
        **{f"{name}_us_per_substep_median": float(np.median([r[name]["us_per_substep"]
                                                             for r in rounds]))
           for name in ("blobflow_numba_default", "blobflow_numba_serial", "warp_cpu")},
        speedup_vs_warp_median=float(np.median([r["speedup_vs_warp"] for r in rounds])),
        speedup_vs_warp_serial_median=float(np.median([r["speedup_vs_warp_serial"]
                                                       for r in rounds])),
        speedup_vs_warp_range=[float(min(r["speedup_vs_warp"] for r in rounds)),
                               float(max(r["speedup_vs_warp"] for r in rounds))],
        speedup_vs_warp_serial_range=[float(min(r["speedup_vs_warp_serial"] for r in rounds)),
                                      float(max(r["speedup_vs_warp_serial"] for r in rounds))])


def main():
    limit = threadpool_limits(1) if threadpool_limits else None
    # three rounds: on this shared 2-core machine a whole round can be slowed for one side
    rounds = [explicit() for _ in range(3)]
    if "--explicit-only" in sys.argv[1:]:
        out = json.loads(RESULTS.read_text())
        out["explicit_rounds"] = rounds
        out["explicit"] = _explicit_summary(rounds)
        out["explicit"]["machine"] = _machine()
        out["explicit_profile"] = explicit_profile()
        print(json.dumps(out["explicit_profile"], indent=1))
        RESULTS.write_text(json.dumps(out, indent=1))
        print(json.dumps(out["explicit"], indent=1))
        print(f"wrote {RESULTS} (explicit rows only)")
        return
    out = dict(machine=_machine(), implicit=[])
    out["explicit_rounds"] = rounds
    out["explicit"] = _explicit_summary(rounds)
    out["explicit_profile"] = explicit_profile()
    print(json.dumps(out["explicit"], indent=1), flush=True)
    cases = [
        (64, tuple(VARIANTS), 12, {}),
        (128, ("csr_block_jacobi_fixed_tol", "operator_block_jacobi_ew", "operator_sgs_ew",
               "operator_ssor_ew", "direct"), 3, {}),
        # the stiffer reading of "k = 1e4": seed-form k = 1e4 N, i.e. k_e = 1e4 / 0.1 = 1e5 N/m
        (64, ("csr_block_jacobi_fixed_tol", "operator_block_jacobi_ew", "operator_sgs_ew",
              "operator_ssor_ew"), 4, dict(k_hooke=1e5)),
        # one linearised Newton step (Baraff & Witkin 1998) on a hanging cloth (stable at any h)
        (64, ("csr_block_jacobi_fixed_tol", "auto_default"), 8,
         dict(scheme="linearized_backward_euler", plane="xz")),
    ]
    for n, variants, steps, kw in cases:
        for row in implicit(n, variants, steps, **kw):
            out["implicit"].append(row)
            print(json.dumps(row), flush=True)
    out["implicit_profile"] = profile()
    out["before_commit_10d0909"] = BEFORE
    out["before_commit_be7fe6e"] = BEFORE_SSOR
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(out, indent=1))
    if limit is not None:
        limit.unregister() if hasattr(limit, "unregister") else None
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
