"""SPH benchmarks, side by side in one run: blobflow's WCSPH against pySPlisHSPlasH and NVIDIA Warp.

Run under the benchmark lock::

    flock /tmp/blobflow-bench.lock env OPENBLAS_NUM_THREADS=1 /tmp/venv/bin/python benchmarks/bench_sph.py

Parts (each in its own subprocess, so that peers with their own runtimes and the memory probe do
not disturb each other):

``nsearch``
    Fixed-radius neighbour search at the SPH support radius (2 spacings) on a jittered lattice
    of 100k and 1M points: blobflow's grid (build + full CSR lists, and build + pairs i < j)
    against ``scipy.spatial.cKDTree`` (build + ``query_pairs``); plus the CSR-lists vs
    cell-iteration comparison that decided how the SPH kernels visit neighbours.
``memory``
    Peak resident memory per fluid particle of a 1M-particle dam break (construction and two
    steps), measured by sampling RSS in a thread, over a baseline taken after compilation.
``wcsph``
    Particle-steps per second on the same dam break at ~50k and ~200k fluid particles with the
    same fixed time step: blobflow WCSPH vs pySPlisHSPlasH WCSPH (simulationMethod 0, Akinci
    2012 boundary particles).
``warp``
    NVIDIA Warp's SPH example (``warp.examples.core.example_sph``) on the CPU device with its
    smoothing length set for ~50k particles: time per sub-step.
``realtime``
    Wall seconds per simulated second on a ~10k-particle dam break over the first 0.1 s:
    blobflow WCSPH (adaptive CFL step; its maximum density error is reported) vs
    pySPlisHSPlasH DFSPH (its default solver, maxError 1 %, CFL-adaptive steps).

All engines run with one thread (NUMBA_NUM_THREADS=1, OMP_NUM_THREADS=1; Warp's CPU kernels are
serial): the machine has 2 cores shared with other jobs, which makes two-thread timings noisy.
Writes ``benchmarks/results/sph.json`` and prints a markdown table.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "sph.json"
GLDISPATCH = "/lib/x86_64-linux-gnu/libGLdispatch.so.0"
THREADS = 1


# =============================================================================================
# Shared set-up: the dam break.
# =============================================================================================
def dam_break_dims(n_target):
    """Column a x depth x 2a in spacings with depth = a / 2, about n_target particles."""
    na = int(round((n_target) ** (1.0 / 3.0)))
    while na * (na // 2) * (2 * na) < n_target:
        na += 1
    return na, na // 2, 2 * na


def blobflow_dam_break(n_target, spacing=0.01, **kw):
    from filters.sph.scenarios import dam_break_liquid

    na, nd, nh = dam_break_dims(n_target)
    sim = dam_break_liquid(column_width=na * spacing, column_height=nh * spacing,
                           depth=nd * spacing, spacing=spacing, threads=THREADS, **kw)
    return sim, (na, nd, nh)


def splishsplash_scene(path, n_target, spacing, method, dt, stop_at, *, stiffness=None,
                       max_error=None, cfl=False):
    """Write the same dam break as a SPlisHSPlasH JSON scene (z up, walls by a unit box)."""
    na, nd, nh = dam_break_dims(n_target)
    a, depth, hcol = na * spacing, nd * spacing, nh * spacing
    length, height = 4 * a, 1.5 * hcol
    r = spacing / 2
    box = Path(path).with_suffix(".obj")
    verts = [(x, y, z) for z in (-0.5, 0.5) for y in (-0.5, 0.5) for x in (-0.5, 0.5)]
    faces = [(1, 3, 2), (2, 3, 4), (5, 6, 7), (6, 8, 7), (1, 2, 5), (2, 6, 5), (3, 7, 4),
             (4, 7, 8), (1, 5, 3), (3, 5, 7), (2, 4, 6), (4, 8, 6)]
    box.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in verts)
                   + "".join(f"f {i} {j} {k}\n" for i, j, k in faces))
    config = {
        "particleRadius": r, "simulationMethod": method, "gravitation": [0, 0, -9.81],
        "timeStepSize": dt, "cflMethod": 1 if cfl else 0, "cflFactor": 1.0,
        "cflMaxTimeStepSize": 0.005, "stopAt": stop_at, "boundaryHandlingMethod": 0,
        "enableVTKExport": False, "enablePartioExport": False, "enableRigidBodyExport": False,
        "enableStateExport": False, "exponent": 7, "maxIterations": 100,
        "maxIterationsV": 100, "maxErrorV": 0.1, "enableDivergenceSolver": True,
    }
    if stiffness is not None:
        config["stiffness"] = stiffness
    if max_error is not None:
        config["maxError"] = max_error
    scene = {
        "Configuration": config,
        "Materials": [{"id": "Fluid", "viscosity": 0.01, "viscosityMethod": 1}],
        "RigidBodies": [{
            "geometryFile": str(box), "translation": [length / 2, depth / 2, height / 2],
            "rotationAxis": [1, 0, 0], "rotationAngle": 0, "scale": [length, depth, height],
            "isDynamic": False, "isWall": True, "mapInvert": True, "mapThickness": 0.0,
            "mapResolution": [20, 20, 20]}],
        # SPlisHSPlasH samples a block at start + r + i * 2r while inside [start, end]; half a
        # spacing of slack gives the same na x nd x nh lattice as blobflow.
        "FluidBlocks": [{"id": "Fluid", "denseMode": 0, "start": [0, 0, 0],
                         "end": [a + r, depth + r, hcol + r]}],
    }
    Path(path).write_text(json.dumps(scene, indent=1))


def run_splishsplash(scene_path, warmup):
    """Run a scene to its stopAt; per-step wall times from the time-step callback."""
    import pysplishsplash as sph

    base = sph.Exec.SimulatorBase()
    out = tempfile.mkdtemp(prefix="sph_out_")
    base.init(useGui=False, sceneFile=str(scene_path), outputDir=out)
    base.initSimulation()
    sim = sph.Simulation.getCurrent()
    n = sim.getFluidModel(0).numActiveParticles()
    try:
        nb = int(sum(sim.getBoundaryModel(i).numberOfParticles()
                     for i in range(sim.numberOfBoundaryModels())))
    except Exception:  # noqa: BLE001 - only informative
        nb = None
    stamps = []
    base.setTimeStepCB(lambda: stamps.append(time.perf_counter()))
    t0 = time.perf_counter()
    base.runSimulation()
    total = time.perf_counter() - t0
    tm = sph.TimeManager.getCurrent()
    steps = len(stamps)
    timed = stamps[warmup:]
    per_step = (timed[-1] - timed[0]) / (len(timed) - 1) if len(timed) > 1 else float("nan")
    return {"fluid_particles": int(n), "boundary_particles": nb, "steps": steps,
            "wall_s": total, "s_per_step": per_step, "sim_time": float(tm.getTime())}


# =============================================================================================
# Parts.
# =============================================================================================
def part_nsearch(compare_passes=True):
    import numpy as np
    from numba import njit, prange
    from scipy.spatial import cKDTree

    from filters.kernels import cubic_dw, cubic_w
    from filters.binning import cell_keys as _grid_keys, counting_sort as _counting_sort
    from filters.neighbors import NeighborSearch, grid_query_padded

    out = {}
    s = 0.01
    radius = 2 * s
    rng = np.random.default_rng(0)
    for n in (100_000, 1_000_000):
        side = int(round(n ** (1 / 3)))
        g = (np.arange(side) + 0.5) * s
        pts = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
        pts = np.ascontiguousarray(pts + rng.uniform(-0.2 * s, 0.2 * s, pts.shape))
        reps = 3 if n <= 100_000 else 2
        NeighborSearch(radius).build(pts[:1000]).query()  # compile
        NeighborSearch(radius).build(pts[:1000]).pairs(sort=False)
        t_full, t_half, t_kd_build, t_kd = [], [], [], []
        for _ in range(reps):
            t0 = time.perf_counter()
            ns = NeighborSearch(radius).build(pts)
            off, idx = ns.query()
            t_full.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            ns = NeighborSearch(radius).build(pts)
            mine = ns.pairs(sort=False)
            t_half.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            tree = cKDTree(pts)
            t_kd_build.append(time.perf_counter() - t0)
            pairs = tree.query_pairs(radius, output_type="ndarray")
            t_kd.append(time.perf_counter() - t0)
        assert pairs.shape[0] == mine.shape[0], (pairs.shape, mine.shape)
        out[str(n)] = {
            "points": int(pts.shape[0]), "radius_m": radius, "pairs": int(pairs.shape[0]),
            "neighbours_per_point": float(off[-1] / pts.shape[0]),
            "blobflow_grid_full_lists_s": min(t_full), "blobflow_grid_pairs_s": min(t_half),
            "ckdtree_build_plus_query_pairs_s": min(t_kd),
            "ckdtree_build_s": min(t_kd_build),
            "speedup_pairs_vs_ckdtree": min(t_kd) / min(t_half),
            "speedup_full_lists_vs_ckdtree_pairs": min(t_kd) / min(t_full),
        }
        del pairs, off, idx, mine, tree

    if not compare_passes:
        return out

    # ---- CSR lists (build once, two passes) vs cell iteration inside both passes ------------
    @njit(parallel=True, cache=True, error_model="numpy")
    def pass_lists(x, tab, cnt, h, out):
        for i in prange(x.shape[0]):
            s0 = 0.0
            g0 = 0.0
            for k in range(cnt[i]):
                j = tab[i, k]
                dx = x[i, 0] - x[j, 0]
                dy = x[i, 1] - x[j, 1]
                dz = x[i, 2] - x[j, 2]
                r = np.sqrt(dx * dx + dy * dy + dz * dz)
                s0 += cubic_w(r, h)
                g0 += cubic_dw(r, h) * dx
            out[i] = s0 + g0

    @njit(parallel=True, cache=True, error_model="numpy")
    def pass_cells(x, start, origin, cell, dims, reach, h, out):
        inv = 1.0 / cell
        h2 = h * h
        for i in prange(x.shape[0]):
            ix = int((x[i, 0] - origin[0]) * inv)
            iy = int((x[i, 1] - origin[1]) * inv)
            iz = int((x[i, 2] - origin[2]) * inv)
            s0 = 0.0
            g0 = 0.0
            for cz in range(max(iz - reach, 0), min(iz + reach, dims[2] - 1) + 1):
                for cy in range(max(iy - reach, 0), min(iy + reach, dims[1] - 1) + 1):
                    row = (cz * dims[1] + cy) * dims[0]
                    lo = start[row + max(ix - reach, 0)]
                    hi = start[row + min(ix + reach, dims[0] - 1) + 1]
                    for j in range(lo, hi):
                        if j == i:
                            continue
                        dx = x[i, 0] - x[j, 0]
                        dy = x[i, 1] - x[j, 1]
                        dz = x[i, 2] - x[j, 2]
                        r2 = dx * dx + dy * dy + dz * dz
                        if r2 <= h2:
                            r = np.sqrt(r2)
                            s0 += cubic_w(r, h)
                            g0 += cubic_dw(r, h) * dx
            out[i] = s0 + g0

    side = 46
    g = (np.arange(side) + 0.5) * s
    pts = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    pts = pts + rng.uniform(-0.2 * s, 0.2 * s, pts.shape)
    res = {}
    for reach in (1, 2):
        cell = radius * (1 + 1e-9) / reach
        lo = pts.min(axis=0)
        dims = (np.floor((pts.max(axis=0) - lo) / cell) + 1).astype(np.int64)
        keys = _grid_keys(pts, lo, 1.0 / cell, dims)
        start, order = _counting_sort(keys, int(np.prod(dims)), 1)
        xs = np.ascontiguousarray(pts[order])
        ident = np.arange(xs.shape[0], dtype=np.int32)
        outv = np.empty(xs.shape[0])
        tab, cnt, _ = grid_query_padded(xs, True, False, xs, start, ident, lo, cell, dims, reach,
                                        radius * radius)
        pass_lists(xs, tab, cnt, radius, outv)
        pass_cells(xs, start, lo, cell, dims, reach, radius, outv)
        tl, tc = [], []
        for _ in range(3):
            t0 = time.perf_counter()
            tab, cnt, _ = grid_query_padded(xs, True, False, xs, start, ident, lo, cell, dims,
                                            reach, radius * radius)
            pass_lists(xs, tab, cnt, radius, outv)
            pass_lists(xs, tab, cnt, radius, outv)
            tl.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            pass_cells(xs, start, lo, cell, dims, reach, radius, outv)
            pass_cells(xs, start, lo, cell, dims, reach, radius, outv)
            tc.append(time.perf_counter() - t0)
        res[f"cells_per_radius_{reach}"] = {
            "points": int(xs.shape[0]), "lists_build_plus_2_passes_s": min(tl),
            "cell_iteration_2_passes_s": min(tc)}
    out["lists_vs_cells"] = res
    return out


def part_memory():
    import threading

    import numpy as np
    import psutil

    proc = psutil.Process()
    small, _ = blobflow_dam_break(2000)
    small.step(small.max_step())
    small.frame()
    del small
    import gc

    gc.collect()
    base = proc.memory_info().rss
    peak = [base]
    stop = [False]

    def sample():
        while not stop[0]:
            peak[0] = max(peak[0], proc.memory_info().rss)
            time.sleep(0.002)

    th = threading.Thread(target=sample, daemon=True)
    th.start()
    t0 = time.perf_counter()
    sim, dims = blobflow_dam_break(1_000_000)
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    for _ in range(2):
        sim.step(sim.max_step())
    t_steps = (time.perf_counter() - t0) / 2
    stop[0] = True
    th.join()
    n = sim.state.n_points
    nb = sim.model.boundary_points.shape[0]
    arrays = sum(a.nbytes for a in (sim.state.positions, sim.state.velocities,
                                    sim.state.extra["id"], sim._rho, sim._p, sim._a, sim._nrm,
                                    sim._tab, sim._cnt, sim._btab, sim._bcnt))
    return {"fluid_particles": n, "boundary_particles": nb,
            "peak_rss_increase_bytes": peak[0] - base,
            "peak_bytes_per_fluid_particle": (peak[0] - base) / n,
            "resident_arrays_bytes_per_fluid_particle": arrays / n,
            "build_s": t_build, "s_per_step_1M": t_steps}


def part_wcsph_blobflow(n_target, dt, steps, warmup=3, **kw):
    sim, dims = blobflow_dam_break(n_target, **kw)
    for _ in range(warmup):
        sim.step(dt)
    t0 = time.perf_counter()
    for _ in range(steps):
        sim.step(dt)
    per = (time.perf_counter() - t0) / steps
    return {"fluid_particles": sim.state.n_points,
            "boundary_particles": int(sim.model.boundary_points.shape[0]), "steps": steps,
            "s_per_step": per, "particle_steps_per_s": sim.state.n_points / per,
            "cfl_dt": sim.max_step(), "speed_of_sound": sim.model.speed_of_sound,
            "max_density_error": sim.density_error}


def part_wcsph_splishsplash(n_target, dt, steps, stiffness, warmup=3):
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "dam.json"
        splishsplash_scene(scene, n_target, 0.01, 0, dt, (steps + warmup + 0.5) * dt,
                           stiffness=stiffness)
        r = run_splishsplash(scene, warmup)
    r["particle_steps_per_s"] = r["fluid_particles"] / r["s_per_step"]
    return r


def part_warp(n_target, substeps=10):
    import numpy as np
    import warp as wp

    wp.config.quiet = True
    wp.init()
    from warp.examples.core import example_sph

    with wp.ScopedDevice("cpu"):
        # n = 80 * 20 * 20 / sl^3 in the example: pick sl for ~n_target particles.
        sl = (32000.0 / n_target) ** (1.0 / 3.0)

        # The example hard-codes smoothing_length = 0.8; rebuild its state for our length.
        ex = example_sph.Example(stage_path=None)
        ex.smoothing_length = sl
        ex.particle_mass = 0.01 * sl ** 3
        ex.dt = 0.01 * sl
        ex.n = int(ex.height * (ex.width / 4.0) * (ex.height / 4.0) / (sl ** 3))
        ex.density_normalization = (315.0 * ex.particle_mass) / (64.0 * np.pi * sl ** 9)
        ex.pressure_normalization = -(45.0 * ex.particle_mass) / (np.pi * sl ** 6)
        ex.viscous_normalization = (45.0 * ex.dynamic_visc * ex.particle_mass) / (np.pi * sl ** 6)
        ex.x = wp.empty(ex.n, dtype=wp.vec3)
        ex.v = wp.zeros(ex.n, dtype=wp.vec3)
        ex.rho = wp.zeros(ex.n, dtype=float)
        ex.a = wp.zeros(ex.n, dtype=wp.vec3)
        wp.launch(kernel=example_sph.initialize_particles, dim=ex.n,
                  inputs=[ex.x, sl, ex.width, ex.height, ex.length])
        grid_size = int(ex.height / (4.0 * sl))
        ex.grid = wp.HashGrid(grid_size, grid_size, grid_size)
        ex.renderer = None
        ex.sim_step_to_frame_ratio = 2
        ex.step()  # compile + warm up
        wp.synchronize()
        ex.sim_step_to_frame_ratio = substeps
        t0 = time.perf_counter()
        ex.step()
        wp.synchronize()
        per = (time.perf_counter() - t0) / substeps
        # neighbours per particle at the start (the example spaces particles one support apart)
        x = ex.x.numpy()
        from scipy.spatial import cKDTree

        nb = cKDTree(x).query_pairs(sl * 0.999999, output_type="ndarray").shape[0] * 2 / ex.n
        return {"particles": ex.n, "smoothing_length": sl, "s_per_substep": per,
                "particle_steps_per_s": ex.n / per, "neighbours_per_particle_at_start": nb}


def part_realtime(n_target, t_end):
    import numpy as np

    sim, dims = blobflow_dam_break(n_target)
    sim.step(sim.max_step())  # compile outside the timing
    sim2, _ = blobflow_dam_break(n_target)
    worst = 0.0
    mean_worst = 0.0
    t0 = time.perf_counter()
    steps = 0
    frame = 1.0 / 60.0
    t = 0.0
    while t < t_end - 1e-12:
        t = min(t + frame, t_end)
        while sim2.state.time < t:
            dt = min(sim2.max_step(), t - sim2.state.time)
            sim2.step(dt)
            steps += 1
            worst = max(worst, sim2.density_error)
            mean_worst = max(mean_worst, sim2.mean_density_error)
    wall = time.perf_counter() - t0
    blob = {"fluid_particles": sim2.state.n_points, "sim_time": t_end, "steps": steps,
            "wall_s": wall, "wall_s_per_sim_s": wall / t_end,
            "max_density_error": worst, "max_mean_density_error": mean_worst}
    return blob


def part_realtime_dfsph(n_target, t_end, max_error_percent=1.0):
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "dam.json"
        splishsplash_scene(scene, n_target, 0.01, 4, 0.001, t_end, max_error=max_error_percent,
                           cfl=True)
        r = run_splishsplash(scene, 0)
    r["wall_s_per_sim_s"] = r["wall_s"] / r["sim_time"]
    r["maxError_percent"] = max_error_percent
    return r


# =============================================================================================
# Orchestration.
# =============================================================================================
PARTS = {
    "nsearch": lambda: part_nsearch(),
    "nsearch_2threads": lambda: part_nsearch(compare_passes=False),
    "memory": lambda: part_memory(),
    "wcsph_blobflow_50k": lambda: part_wcsph_blobflow(50_000, DT, 30),
    "wcsph_blobflow_200k": lambda: part_wcsph_blobflow(200_000, DT, 8),
    "wcsph_blobflow_50k_noskin": lambda: part_wcsph_blobflow(50_000, DT, 30, skin=0.0),
    "wcsph_blobflow_200k_noskin": lambda: part_wcsph_blobflow(200_000, DT, 8, skin=0.0),
    "wcsph_splishsplash_50k": lambda: part_wcsph_splishsplash(50_000, DT, 30, STIFFNESS),
    "wcsph_splishsplash_200k": lambda: part_wcsph_splishsplash(200_000, DT, 8, STIFFNESS),
    "warp_50k": lambda: part_warp(50_000),
    "realtime_blobflow": lambda: part_realtime(REALTIME_N, REALTIME_T),
    "realtime_dfsph": lambda: part_realtime_dfsph(REALTIME_N, REALTIME_T),
}
#: The fixed time step of the particle-steps comparison (s): blobflow's CFL step for the
#: 50k dam break with spacing 1 cm.
DT = 1e-4
#: Tait stiffness B = rho0 c^2 / 7 for SPlisHSPlasH, c as blobflow's default for the 50k column.
STIFFNESS = None
REALTIME_N = 10_000
REALTIME_T = 0.1


def run_part(name, timeout=420):
    env = dict(os.environ)
    threads = 2 if name.endswith("_2threads") else THREADS
    env.update(NUMBA_NUM_THREADS=str(threads), OMP_NUM_THREADS=str(threads),
               OPENBLAS_NUM_THREADS="1")
    if "splishsplash" in name or "dfsph" in name:
        env["LD_PRELOAD"] = GLDISPATCH
    t0 = time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, __file__, "--part", name], env=env,
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout} s"}
    wall = time.perf_counter() - t0
    for line in reversed(proc.stdout.splitlines()):
        if line.startswith("RESULT "):
            result = json.loads(line[7:])
            result["part_wall_s"] = wall
            return result
    tail = (proc.stdout + proc.stderr)[-1500:]
    return {"error": f"exit {proc.returncode}", "tail": tail}


def main():
    global STIFFNESS
    import numpy as np

    sys.path.insert(0, str(HERE.parent))
    # blobflow's default speed of sound for the 50k column: 10 sqrt(2 g H).
    na, nd, nh = dam_break_dims(50_000)
    c = 10 * np.sqrt(2 * 9.81 * (nh * 0.01))
    STIFFNESS = float(1000.0 * c * c / 7.0)
    os.environ["BENCH_STIFFNESS"] = repr(STIFFNESS)
    results = {"machine": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
               "threads": THREADS, "fixed_dt_s": DT, "splishsplash_stiffness": STIFFNESS,
               "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    only = sys.argv[1:] or list(PARTS)
    for name in only:
        print(f"--- {name}", flush=True)
        results[name] = run_part(name)
        print(json.dumps(results[name], indent=1), flush=True)
    summary = summarise(results)
    results["summary"] = summary
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    previous = json.loads(RESULTS.read_text()) if RESULTS.exists() and sys.argv[1:] else {}
    previous.update(results)
    RESULTS.write_text(json.dumps(previous, indent=1))
    print(table(previous))


def _get(d, *keys):
    for k in keys:
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d


def summarise(r):
    s = {}
    for n in ("50k", "200k"):
        a = _get(r, f"wcsph_blobflow_{n}", "particle_steps_per_s")
        b = _get(r, f"wcsph_splishsplash_{n}", "particle_steps_per_s")
        if a and b:
            s[f"wcsph_ratio_vs_splishsplash_{n}"] = a / b
    a = _get(r, "wcsph_blobflow_50k", "particle_steps_per_s")
    w = _get(r, "warp_50k", "particle_steps_per_s")
    if a and w:
        s["wcsph_ratio_vs_warp_cpu_50k"] = a / w
    a = _get(r, "realtime_blobflow", "wall_s_per_sim_s")
    b = _get(r, "realtime_dfsph", "wall_s_per_sim_s")
    if a and b:
        s["wall_per_sim_s_ratio_dfsph_over_blobflow"] = b / a
    for n in ("50k", "200k"):
        a = _get(r, f"wcsph_blobflow_{n}_noskin", "particle_steps_per_s")
        b = _get(r, f"wcsph_splishsplash_{n}", "particle_steps_per_s")
        if a and b:
            s[f"wcsph_noskin_ratio_vs_splishsplash_{n}"] = a / b
    for part in ("nsearch", "nsearch_2threads"):
        for n in ("100000", "1000000"):
            v = _get(r, part, n, "speedup_pairs_vs_ckdtree")
            if v:
                s[f"{part}_speedup_{n}"] = v
    m = _get(r, "memory", "peak_bytes_per_fluid_particle")
    if m:
        s["memory_bytes_per_particle_1M"] = m
    return s


def table(r):
    s = r.get("summary", {})
    fmt = lambda v, f="{:.3g}": "n/a" if v is None else f.format(v)
    rows = ["| measure | blobflow | peer | ratio (target) |", "|---|---|---|---|"]
    for n in ("50k", "200k"):
        a = _get(r, f"wcsph_blobflow_{n}")
        b = _get(r, f"wcsph_splishsplash_{n}")
        rows.append(
            f"| WCSPH particle-steps/s, dam break {n} (fixed dt {r.get('fixed_dt_s')}) | "
            f"{fmt(_get(a, 'particle_steps_per_s'))} ({_get(a, 'fluid_particles')} p) | "
            f"SPlisHSPlasH WCSPH {fmt(_get(b, 'particle_steps_per_s'))} "
            f"({_get(b, 'fluid_particles')} p) | "
            f"{fmt(s.get(f'wcsph_ratio_vs_splishsplash_{n}'))} (>= 1.5) |")
    for n in ("50k", "200k"):
        a = _get(r, f"wcsph_blobflow_{n}_noskin")
        rows.append(
            f"| same, lists rebuilt every step (skin = 0) {n} | "
            f"{fmt(_get(a, 'particle_steps_per_s'))} | SPlisHSPlasH WCSPH (as above) | "
            f"{fmt(s.get(f'wcsph_noskin_ratio_vs_splishsplash_{n}'))} (>= 1.5) |")
    w = _get(r, "warp_50k")
    rows.append(f"| particle-steps/s vs Warp SPH example, CPU | "
                f"{fmt(_get(r, 'wcsph_blobflow_50k', 'particle_steps_per_s'))} | "
                f"Warp {fmt(_get(w, 'particle_steps_per_s'))} ({_get(w, 'particles')} p) | "
                f"{fmt(s.get('wcsph_ratio_vs_warp_cpu_50k'))} (>= 1.0) |")
    a = _get(r, "realtime_blobflow")
    b = _get(r, "realtime_dfsph")
    rows.append(f"| wall s per simulated s, dam break {_get(a, 'fluid_particles')} p, "
                f"first {_get(a, 'sim_time')} s | {fmt(_get(a, 'wall_s_per_sim_s'))} "
                f"(max density error {fmt(_get(a, 'max_density_error'))}) | "
                f"SPlisHSPlasH DFSPH {fmt(_get(b, 'wall_s_per_sim_s'))} | "
                f"{fmt(s.get('wall_per_sim_s_ratio_dfsph_over_blobflow'))} (>= 1.0) |")
    for part, n in [(p, n) for p in ("nsearch", "nsearch_2threads") for n in ("100000", "1000000")]:
        d = _get(r, part, n)
        threads = 2 if part.endswith("2threads") else THREADS
        rows.append(f"| neighbour pairs at r = 2 spacings, {n} points, {threads} thread(s) | "
                    f"{fmt(_get(d, 'blobflow_grid_pairs_s'))} s "
                    f"(full lists {fmt(_get(d, 'blobflow_grid_full_lists_s'))} s) | "
                    f"cKDTree build + query_pairs {fmt(_get(d, 'ckdtree_build_plus_query_pairs_s'))} s | "
                    f"{fmt(_get(d, 'speedup_pairs_vs_ckdtree'))} (>= 5) |")
    m = _get(r, "memory")
    rows.append(f"| peak memory per fluid particle, 1M dam break | "
                f"{fmt(_get(m, 'peak_bytes_per_fluid_particle'), '{:.0f}')} B | - | (<= 1024 B) |")
    return "\n".join(rows)


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--part":
        sys.path.insert(0, str(HERE.parent))
        if os.environ.get("BENCH_STIFFNESS"):
            STIFFNESS = float(os.environ["BENCH_STIFFNESS"])
        result = PARTS[sys.argv[2]]()
        print("RESULT " + json.dumps(result), flush=True)
    else:
        main()
