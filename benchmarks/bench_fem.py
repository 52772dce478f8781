"""Benchmark: the FEM jello against the spring jello, marching tetrahedra against flying edges.

Run (under the project's benchmark lock when the machine is free)::

    flock /tmp/blobflow-bench.lock env OPENBLAS_NUM_THREADS=1 python benchmarks/bench_fem.py

1. **Implicit jello steps**: an icosphere of radius 0.15 m (density 1000 kg/m^3) cut on a
   lattice into about 10,000 and 100,000 tetrahedra (:func:`filters.elastic.tetmesh.
   tets_from_mesh`), resting 5 mm above a floor with friction 0.5 and moving at 0.5 m/s
   sideways and 1 m/s down, so that every step has contacts (the mesh's vertices against the
   floor: IPC barrier, lagged friction, normal damping, :mod:`filters.elastic.contact_model`);
   backward Euler (Newton, line search, the default solver) at ``h = 1/240`` s, the scene's
   defaults (``jello_fem``: stable Neo-Hookean, E = 5e4 Pa, nu = 0.45, Rayleigh beta 0.002 s;
   also the corotated material), against the spring jello (:class:`filters.elastic.
   mass_spring.JelloSimulation`, stiffness 300 N, damping 0.5 N s/m)
   on the *same lattice* (the spring lattice and the tetrahedra share the voxelisation; the
   tetrahedra also fill the cells the surface cuts, each with its volume fraction), steps
   interleaved between the models.  Reported per model: ms per step (median, min), Newton and PCG
   iterations and direct solves per step, the share of steps at the Newton limit; :data:`BEFORE`
   keeps the numbers of the run before Newton converged in contact (diagonal contact Hessian of the
   embedded surface, slip velocity 1 mm/s).
2. **Contouring**: the 100k and 1M jittered blocks of ``bench_surface.py`` splatted once
   (``splat_sparse``, sph kernel, radius 0.01 m, cell 0.005 m, iso 0.6), then contoured with
   flying edges (``contour_sparse``) and with marching tetrahedra (``contour_grid``),
   alternating, best of ``--repeats``: seconds, triangles, vertices, closed and manifold
   (``--no-1m`` skips the 1M block).

Results go to ``benchmarks/results/fem.json`` with the Numba thread count and the load average
before and after, because the development machine is shared: compare the ratios, measured
side by side in one run, not the seconds.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402

from filters.elastic.contact import Colliders  # noqa: E402
from filters.elastic.fem_simulation import FEMSimulation  # noqa: E402
from filters.elastic.mass_spring import JelloSimulation  # noqa: E402
from filters.elastic.topology import icosphere  # noqa: E402
from filters.geometry import Plane  # noqa: E402

RESULTS = Path(__file__).parent / "results" / "fem.json"
RADIUS = 0.15
H = 1.0 / 240.0
#: Lattice spacings giving about 10k and 100k tetrahedra in the ball.
SPACINGS = {"10k": 0.0219, "100k": 0.0095}
#: The implicit rows of the run before Newton converged in contact (commit d0dafd5's fem.json,
#: load average 4): every FEM step stopped at the limit of 10 Newton iterations.
BEFORE = {
    "jello_10k": {"fem_neo_hookean": dict(ms_per_step_median=197.4, newton_iterations_mean=10.0,
                                          pcg_iterations_mean=55.15, tets=9876),
                  "fem_corotated": dict(ms_per_step_median=339.3, newton_iterations_mean=10.0,
                                        pcg_iterations_mean=67.65, tets=9876),
                  "springs": dict(ms_per_step_median=18.69, newton_iterations_mean=6.15,
                                  pcg_iterations_mean=24.65)},
    "jello_100k": {"fem_neo_hookean": dict(ms_per_step_median=2430.0, newton_iterations_mean=10.0,
                                           tets=100800),
                   "fem_corotated": dict(ms_per_step_median=3710.0, newton_iterations_mean=10.0,
                                         tets=100800),
                   "springs": dict(ms_per_step_median=310.0, newton_iterations_mean=6.8)},
}


def _mesh():
    p, t = icosphere(RADIUS, 3)
    return p - [0.0, 0.0, p[:, 2].min() - 0.005], t


def _floor():
    return Colliders(friction=0.5).add(Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)))


def _models(spacing):
    p, t = _mesh()
    models = {}
    for material in ("neo_hookean", "corotated"):
        models[f"fem_{material}"] = FEMSimulation.from_mesh(
            p, t, spacing=spacing, material=material, youngs_modulus=5e4, poisson_ratio=0.45,
            stiffness_damping=0.002, colliders=_floor(), max_dt=H)
    models["springs"] = JelloSimulation(p, t, spacing=spacing, stretch_stiffness=300.0,
                                        damping=0.5, colliders=_floor(), max_dt=H)
    for sim in models.values():
        sim.state.velocities[:] = [0.5, 0.0, -1.0]
    return models


def implicit(size, steps):
    spacing = SPACINGS[size]
    models = _models(spacing)
    fem = models["fem_neo_hookean"]
    rows = {name: dict(times=[], newton=[], pcg=[], direct=[]) for name in models}
    for sim in models.values():  # compile and settle into contact
        sim.step(H)
    for _ in range(steps):
        for name, sim in models.items():
            start = time.perf_counter()
            sim.step(H)
            rows[name]["times"].append(time.perf_counter() - start)
            info = sim.last_info
            rows[name]["newton"].append(info.newton_iterations)
            rows[name]["pcg"].append(info.linear_iterations)
            rows[name]["direct"].append(info.direct_solves)
    out = []
    for name, r in rows.items():
        sim = models[name]
        limit = sim.newton_options["max_newton"]
        row = dict(case=f"jello_{size}", model=name, spacing_m=spacing,
                   nodes=int(sim.state.positions.shape[0]), steps=steps, h=H,
                   ms_per_step_median=1e3 * float(np.median(r["times"])),
                   ms_per_step_min=1e3 * float(np.min(r["times"])),
                   newton_iterations_mean=float(np.mean(r["newton"])),
                   newton_iterations_max=int(np.max(r["newton"])),
                   newton_limit=int(limit),
                   share_of_steps_at_newton_limit=float(np.mean(np.array(r["newton"]) >= limit)),
                   slip_velocity_m_per_s=float(sim.contact.slip_velocity),
                   pcg_iterations_mean=float(np.mean(r["pcg"])),
                   direct_solves_mean=float(np.mean(r["direct"])))
        if name.startswith("fem"):
            row["tets"] = int(sim.system.n_tets)
            row["tets_cut_by_the_surface"] = int(np.sum(sim.system.fractions < 1.0))
        else:
            row["springs"] = int(sim.system.pairs.shape[0])
        row["before"] = BEFORE[f"jello_{size}"][name]
        out.append(row)
    base = next(r for r in out if r["model"] == "springs")["ms_per_step_median"]
    for row in out:
        row["time_vs_springs"] = row["ms_per_step_median"] / base
    # the same lattice: the FEM mesh has the spring lattice's cells plus those the surface cuts
    assert fem.state.positions.shape[0] >= 0.8 * models["springs"].state.positions.shape[0]
    return out


def profile(size="10k", steps=8):
    """Where a FEM jello step's time goes: ``steps`` steps of each FEM model (after the
    interleaved benchmark's first step) under :mod:`cProfile`, with each function's share of
    the total (own time, so a Numba kernel's share is its work), the top 8; the spring jello
    likewise.  Shares, not seconds: they hold on a busy machine."""
    import cProfile
    import pstats

    models = _models(SPACINGS[size])
    out = {}
    for name, sim in models.items():
        sim.step(H)
        prof = cProfile.Profile()
        newton = 0
        prof.enable()
        for _ in range(steps):
            sim.step(H)
            newton += sim.last_info.newton_iterations
        prof.disable()
        stats = pstats.Stats(prof).stats
        total = sum(v[2] for v in stats.values())
        top = sorted(stats.items(), key=lambda kv: -kv[1][2])[:8]
        out[name] = dict(steps=steps, newton_iterations_mean=newton / steps,
                         share_of_time={f"{Path(k[0]).name}:{k[2]}": round(v[2] / total, 3)
                                        for k, v in top},
                         calls_per_newton_iteration={f"{Path(k[0]).name}:{k[2]}":
                                                     round(v[1] / max(newton, 1), 2)
                                                     for k, v in top})
        print(json.dumps({name: out[name]}), flush=True)
    return out


def _block(n):
    rng = np.random.default_rng(0)
    g = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), -1)
    g = g.reshape(-1, 3).astype(np.float64)
    return np.ascontiguousarray(g * 0.02 + rng.uniform(-0.002, 0.002, g.shape))


def contouring(case, repeats):
    from filters.surface.mesh import mesh_stats
    from filters.surface.splat import splat_sparse
    from filters.surface.tetra import contour_grid
    from pipeline.surface.contour import contour_sparse

    n = {"block_100k": (50, 50, 40), "block_1m": (100, 100, 100)}[case]
    x = _block(n)
    grid = splat_sparse(x, 0.01, 0.005, kernel="sph", iso=0.6)
    tools = {"flying_edges": lambda: contour_sparse(grid),
             "marching_tetrahedra": lambda: contour_grid(grid)}
    times = {k: [] for k in tools}
    meshes = {}
    for _ in range(repeats):
        for name, fn in tools.items():
            start = time.perf_counter()
            meshes[name] = fn()
            times[name].append(time.perf_counter() - start)
    rows = []
    for name, (pts, tris) in meshes.items():
        st = mesh_stats(pts, tris)
        rows.append(dict(case=case, particles=int(x.shape[0]), method=name,
                         seconds_best=min(times[name]), seconds_all=times[name],
                         triangles=int(tris.shape[0]), vertices=int(pts.shape[0]),
                         closed=st.closed, manifold=st.manifold, volume_m3=st.volume,
                         area_m2=st.area))
    fe = rows[0]
    for row in rows:
        row["time_vs_flying_edges"] = row["seconds_best"] / fe["seconds_best"]
        row["triangles_vs_flying_edges"] = row["triangles"] / fe["triangles"]
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=20, help="implicit steps per model")
    parser.add_argument("--repeats", type=int, default=3, help="contouring repeats")
    parser.add_argument("--no-1m", action="store_true", help="skip the 1M block")
    parser.add_argument("--only", choices=("implicit", "contour", "profile"),
                        help="one part only (profile: the FEM step's kernels, kept beside the "
                             "earlier implicit and contouring rows)")
    args = parser.parse_args(argv)
    out = dict(machine=dict(platform=platform.platform(), cpus=os.cpu_count(),
                            numba_threads=numba.get_num_threads(),
                            load_average_before=os.getloadavg()),
               implicit=[], contouring=[])
    if args.only in (None, "implicit"):
        for size, steps in (("10k", args.steps), ("100k", max(3, args.steps // 4))):
            for row in implicit(size, steps):
                out["implicit"].append(row)
                print(json.dumps(row), flush=True)
    if args.only == "profile":
        out["profile_10k"] = profile()
    if args.only in (None, "contour"):
        cases = ["block_100k"] if args.no_1m else ["block_100k", "block_1m"]
        for case in cases:
            for row in contouring(case, args.repeats):
                out["contouring"].append(row)
                print(json.dumps({k: v for k, v in row.items() if k != "seconds_all"}),
                      flush=True)
    out["machine"]["load_average_after"] = os.getloadavg()
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    if RESULTS.exists() and args.only:  # keep the other part of an earlier run
        previous = json.loads(RESULTS.read_text())
        for other in ("implicit", "contouring", "profile_10k"):
            if not out.get(other):
                out[other] = previous.get(other, [])
        if args.only == "profile":  # the machine line stays the implicit rows'
            out["profile_10k"]["machine"] = out["machine"]
            out["machine"] = previous.get("machine", out["machine"])
    RESULTS.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
