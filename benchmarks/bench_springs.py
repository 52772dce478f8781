"""Benchmark: mass-spring cloth — implicit Newton steps, and explicit substeps against NVIDIA Warp.

Run (under the project's benchmark lock)::

    flock /tmp/blobflow-bench.lock env OPENBLAS_NUM_THREADS=1 python benchmarks/bench_springs.py

1. **Implicit**: a cloth of 64x64 and 128x128 particles (0.1 m cells, 0.1 kg particles — the
   scales of Warp's cloth benchmark), structural + shear + bend springs of stiffness
   ``k_e = 1e4`` N/m (Hooke form, i.e. the seed-form ``k = 1e4 L`` N), pinned at two corners and
   released horizontal under gravity; backward Euler by Newton with line search at
   ``h = 1/60`` s with each linear solver (block-Jacobi PCG in Numba, SuperLU direct, auto).  Reported:
   ms per step, Newton iterations and PCG iterations per step.
2. **Explicit**: symplectic Euler substeps of the same 64x64 cloth with Warp's cloth-benchmark
   parameters (``k_e = 1000`` N/m, axial damping 10 N s/m, 16 substeps per 1/60 s frame), against
   Warp's own ``benchmark_cloth_warp.WpIntegrator`` on its CPU device, with the same particles and
   springs, in the same process.

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

from filters import springs as springs_module  # noqa: E402
from filters.integrators import backward_euler, linearized_backward_euler  # noqa: E402
from filters.simulation import State  # noqa: E402
from filters.springs import SpringSystem  # noqa: E402
from filters.topology import cloth_grid  # noqa: E402

RESULTS = Path(__file__).parent / "results" / "springs.json"
CELL = 0.1
MASS = 0.1


def _cloth(n, plane="xy"):
    top = cloth_grid(n, n, size=((n - 1) * CELL, (n - 1) * CELL), origin=(0, 0, 0), plane=plane,
                     areal_density=MASS / CELL ** 2)
    return top.with_pins([0, n - 1])


def implicit(n, solver, steps, k_hooke=1e4, scheme="newton", plane="xy"):
    top = _cloth(n, plane)
    rest = top.rest_lengths
    # uniform particle masses, as in Warp's benchmark
    system = SpringSystem(top.springs, rest, k_hooke * rest, np.full(n * n, MASS),
                          pinned=top.pinned)
    state = State(top.positions)
    h = 1.0 / 60.0
    step = backward_euler if scheme == "newton" else linearized_backward_euler
    step(system, state, h, solver=solver)  # compile, pattern
    times, newton, linear, direct = [], [], [], []
    for _ in range(steps):
        t0 = time.perf_counter()
        info = step(system, state, h, solver=solver)
        times.append(time.perf_counter() - t0)
        newton.append(info.newton_iterations)
        linear.append(info.linear_iterations)
        direct.append(info.direct_solves)
    return dict(particles=n * n, springs=int(top.springs.shape[0]), unknowns=3 * n * n,
                start="hanging" if plane == "xz" else "horizontal, pinned at two corners",
                nnz=int(system.system_matrix(state.positions, state.positions, h).nnz),
                scheme=scheme, solver=solver, h=h, k_hooke_N_per_m=k_hooke, steps=steps,
                ms_per_step_median=1e3 * float(np.median(times)),
                ms_per_step_mean=1e3 * float(np.mean(times)),
                newton_iterations_mean=float(np.mean(newton)),
                pcg_iterations_mean=float(np.mean(linear)),
                direct_solves_mean=float(np.mean(direct)),
                final_energy_J=system.energy(state.positions, state.velocities))


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

    The machine is shared, so the implementations take turns (ours as configured — parallel
    on 2 threads above ``PARALLEL_MIN_SPRINGS_EXPLICIT`` springs —, ours forced serial, Warp) and each keeps its fastest block of ``frames * substeps`` substeps: a slow block
    caused by another process then hits all of them alike instead of one.
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


def main():
    limit = threadpool_limits(1) if threadpool_limits else None
    out = dict(machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                            numba_threads=numba.get_num_threads(),
                            load_average=os.getloadavg()),
               implicit=[])
    # three rounds: on this shared 2-core machine a whole round can be slowed for one side
    rounds = [explicit() for _ in range(3)]
    out["explicit_rounds"] = rounds
    out["explicit"] = dict(
        particles=rounds[0]["particles"], springs=rounds[0]["springs"],
        substep_s=rounds[0]["substep_s"],
        **{f"{name}_us_per_substep_median": float(np.median([r[name]["us_per_substep"]
                                                             for r in rounds]))
           for name in ("blobflow_numba_default", "blobflow_numba_serial", "warp_cpu")},
        speedup_vs_warp_median=float(np.median([r["speedup_vs_warp"] for r in rounds])),
        speedup_vs_warp_serial_median=float(np.median([r["speedup_vs_warp_serial"]
                                                       for r in rounds])),
        speedup_vs_warp_range=[float(min(r["speedup_vs_warp"] for r in rounds)),
                               float(max(r["speedup_vs_warp"] for r in rounds))])
    print(json.dumps(out["explicit"], indent=1), flush=True)
    for n, solvers, steps in ((64, ("pcg", "direct", "auto"), 8), (128, ("pcg", "direct"), 3)):
        for solver in solvers:
            row = implicit(n, solver, steps)
            out["implicit"].append(row)
            print(json.dumps(row), flush=True)
    # the stiffer reading of "k = 1e4": seed-form k = 1e4 N, i.e. k_e = 1e4 / 0.1 = 1e5 N/m
    out["implicit"].append(implicit(64, "auto", 4, k_hooke=1e5))
    print(json.dumps(out["implicit"][-1]), flush=True)
    # one linearised Newton step (Baraff & Witkin 1998) on a hanging cloth (stable at any h)
    out["implicit"].append(implicit(64, "auto", 8, scheme="linearized", plane="xz"))
    print(json.dumps(out["implicit"][-1]), flush=True)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(out, indent=1))
    if limit is not None:
        limit.unregister() if hasattr(limit, "unregister") else None
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
