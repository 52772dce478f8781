"""SPH benchmarks, side by side in one run: blobflow's DFSPH and WCSPH against SPlisHSPlasH's.

Run on a quiet machine, one benchmark at a time::

    env OPENBLAS_NUM_THREADS=1 python benchmarks/bench_sph.py            # everything (~2 hours)
    env OPENBLAS_NUM_THREADS=1 python benchmarks/bench_sph.py persim_10k_blobflow_dfsph ...

The figure users live by is **wall seconds per simulated second** at a stated density error, so
that is what the ``persim_*`` parts measure, on one scene for all four solvers:

* **The dam break**: a water column ``a x a/2 x 2a`` (spacing 1 cm, ``a`` chosen for ~10k, ~50k
  and ~200k fluid particles) against the left wall of a closed tank ``4a x a/2 x 3a``, gravity
  ``-z``, started at rest, simulated for 0.5 s so that the front crosses the tank (at 10k it
  hits the far wall).  Both codes sample the fluid on the same lattice, cell centres ``(i +
  1/2) s`` one spacing from the wall particles (SPlisHSPlasH: a block from ``-r`` and a wall
  box enlarged by ``2r``; its boundary particles sample the box surface, Akinci et al. 2012).
* **Same physics**: kinematic viscosity ``nu = 0.001 m^2/s`` (about the dam-break scene's
  value), for DFSPH by Weiler et al. (2018)'s implicit solver on both sides (SPlisHSPlasH's
  "Weiler et al. 2018", ``viscoMaxError`` 0.1 %), for WCSPH explicitly (Monaghan's artificial
  viscosity with ``alpha = 10 nu / (c s)``, SPlisHSPlasH's "standard" viscosity with ``nu``);
  no surface tension, rest density 1000 kg/m^3, the cubic spline with support 2 spacings.
* **Same accuracy**: the DFSPH solvers stop at a mean density error of 0.1 % and a mean
  divergence error of 1 % per step (blobflow's defaults; SPlisHSPlasH's ``maxError`` 0.1,
  ``maxErrorV`` 1.0 in its percent); each side reports the density error it actually reached,
  mean over particles and worst particle, sampled every step.  WCSPH: the same Tait equation
  of state on both sides (``B = rho0 c^2 / 7`` with blobflow's speed of sound ``10 sqrt(2 g
  H)``) and blobflow's acoustic CFL step, given to SPlisHSPlasH as its fixed step (its CFL looks
  at velocities only, which is unstable for WCSPH).
* **Each at its natural step**: DFSPH steps from each code's own CFL rule at its default factor
  (blobflow ``cfl`` 0.4 of a spacing per step, plus its solver-aware cap and its wall condition:
  a particle near a wall approaches it by at most 0.1 spacings per step; SPlisHSPlasH
  ``cflFactor`` 0.5, i.e. 0.2 of a spacing, and ``cflMaxTimeStepSize`` 0.005 s).  Density
  errors are reported over the whole run and after the first 50 ms: SPlisHSPlasH's single layer
  of wall particles overestimates the density at walls, so its resting column starts 1.5 %
  compressed on average (13 % at the worst particle, read from its first step) and its first
  ~10 ms peak at 4-5 % whatever the step cap (measured with caps of 5, 2 and 0.5 ms at 10k).
* **WCSPH runs to the end**: blobflow's WCSPH stops a run when one particle is compressed by more
  than 10 % (its ``density_error_limit``; at 10k this happens at t = 0.336 s when the front
  hits the far wall); here the limit is 1 so that both WCSPH runs finish, and the errors they
  reached are reported.
* **One thread each** (``NUMBA_NUM_THREADS=1``, ``OMP_NUM_THREADS=1``); every part runs in its own
  process, and SPlisHSPlasH's settings are **read back from the loaded simulation** (a key the
  loader ignores would otherwise go unnoticed).  Timing starts after the scene is built and,
  for blobflow, after Numba compiled its kernels on a small copy of the scene.
blobflow's rows also record how many particles its tank's safety net had to put back
(``container_corrections``, 0 when its walls hold), and the summary the ratio of the two codes'
worst particle after 50 ms (``dfsph_worst_particle_vs_splishsplash_*``, <= 1: no worse).
Also measured (unchanged from earlier versions of this benchmark): fixed-radius neighbour search
against ``scipy.spatial.cKDTree`` (``nsearch``), and peak memory per fluid particle of a
1M-particle dam break for each solver (``memory_*``).

Writes ``benchmarks/results/sph.json`` and prints a markdown table.
"""

from __future__ import annotations

import json
import math
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
SPACING = 0.01
NU = 0.001  # m^2/s, kinematic viscosity of both codes
MAX_ERROR = 0.001  # mean density error of the DFSPH solves (fraction)
MAX_ERROR_V = 0.01  # mean divergence error per step (fraction)
SIZES = {"10k": 10_000, "50k": 50_000, "200k": 200_000}
T_END = 0.5


# =============================================================================================
# The scene.
# =============================================================================================
def dam_break_dims(n_target):
    """Column a x depth x 2a in spacings with depth = a / 2, at least n_target particles."""
    na = int(round(n_target ** (1.0 / 3.0)))
    while na * (na // 2) * (2 * na) < n_target:
        na += 1
    return na, na // 2, 2 * na


def tank(n_target):
    na, nd, nh = dam_break_dims(n_target)
    a, depth, hcol = na * SPACING, nd * SPACING, nh * SPACING
    return a, depth, hcol, 4 * a, 1.5 * hcol


def wcsph_speed_of_sound(n_target):
    """blobflow's default c = 10 sqrt(2 g H) for the column (H its height plus a spacing)."""
    na, nd, nh = dam_break_dims(n_target)
    return 10.0 * math.sqrt(2 * 9.81 * nh * SPACING)


def blobflow_dam_break(n_target, solver, **kw):
    from filters.sph.scenarios import dam_break_liquid

    a, depth, hcol, length, height = tank(n_target)
    if solver == "dfsph":
        kw.setdefault("kinematic_viscosity", NU)
        kw.setdefault("max_density_error", MAX_ERROR)
        kw.setdefault("max_divergence_error", MAX_ERROR_V)
    else:  # Monaghan's alpha for nu: nu = alpha c h' / 10 with h' = one spacing
        kw.setdefault("viscosity", NU * 10.0 / (wcsph_speed_of_sound(n_target) * SPACING))
        kw.setdefault("density_error_limit", 1.0)
    return dam_break_liquid(column_width=a, column_height=hcol, depth=depth, tank_length=length,
                            tank_height=height, spacing=SPACING, solver=solver, threads=1, **kw)


def splishsplash_scene(path, n_target, method, stop_at, dt=None):
    """The same dam break as a SPlisHSPlasH 2.19 JSON scene (z up, walls from a unit box)."""
    a, depth, hcol, length, height = tank(n_target)
    r = SPACING / 2
    box = Path(path).with_suffix(".obj")
    verts = [(x, y, z) for z in (-0.5, 0.5) for y in (-0.5, 0.5) for x in (-0.5, 0.5)]
    faces = [(1, 3, 2), (2, 3, 4), (5, 6, 7), (6, 8, 7), (1, 2, 5), (2, 6, 5), (3, 7, 4),
             (4, 7, 8), (1, 5, 3), (3, 5, 7), (2, 4, 6), (4, 8, 6)]
    box.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in verts)
                   + "".join(f"f {i} {j} {k}\n" for i, j, k in faces))
    c = wcsph_speed_of_sound(n_target)
    config = {
        "particleRadius": r, "simulationMethod": method, "gravitation": [0, 0, -9.81],
        "timeStepSize": dt if dt else 0.001, "cflMethod": 0 if dt else 1, "cflFactor": 0.5,
        "cflMaxTimeStepSize": 0.005, "stopAt": stop_at, "boundaryHandlingMethod": 0,
        "enableVTKExport": False, "enablePartioExport": False, "enableRigidBodyExport": False,
        "enableStateExport": False,
        # Solver settings are read only from these nested blocks (flat keys are ignored).
        "DFSPH": {"maxError": 100 * MAX_ERROR, "maxIterations": 100,
                  "maxErrorV": 100 * MAX_ERROR_V, "maxIterationsV": 100,
                  "enableDivergenceSolver": True},
        "WCSPH": {"stiffness": 1000.0 * c * c / 7.0, "exponent": 7},
    }
    scene = {
        "Configuration": config,
        # DFSPH: Weiler et al. (2018)'s implicit viscosity, as blobflow's DFSPH; WCSPH: the
        # explicit "standard" viscosity, as blobflow's WCSPH (Monaghan's, alpha = 10 nu / (c s)).
        "Materials": [{"id": "Fluid", "viscosityMethod": 1 if dt else 6,
                       "Standard viscosity": {"viscosity": NU, "viscosityBoundary": NU},
                       "Weiler et al. 2018": {"viscosity": NU, "viscosityBoundary": NU,
                                              "viscoMaxIter": 100, "viscoMaxError": 0.001}}],
        # Wall particles sample the box surface: enlarged by 2r (r per side) the surface lies
        # half a spacing outside the fluid lattice, one spacing from the first fluid particles.
        "RigidBodies": [{
            "geometryFile": str(box), "translation": [length / 2, depth / 2, height / 2],
            "rotationAxis": [1, 0, 0], "rotationAngle": 0,
            "scale": [length + 2 * r, depth + 2 * r, height + 2 * r],
            "isDynamic": False, "isWall": True, "mapInvert": True, "mapThickness": 0.0,
            "mapResolution": [20, 20, 20]}],
        # A block samples start + 2r (k + 1) for k < round((end - start) / 2r) - 1.
        "FluidBlocks": [{"id": "Fluid", "denseMode": 0, "start": [-r, -r, -r],
                         "end": [a + r, depth + r, hcol + r]}],
    }
    Path(path).write_text(json.dumps(scene, indent=1))


# =============================================================================================
# Wall time per simulated second.
# =============================================================================================
def part_persim_blobflow(size, solver):
    import numpy as np

    n_target = SIZES[size]
    t_end = T_END
    warm = blobflow_dam_break(2000, solver)  # compile every kernel outside the timing
    warm.step(warm.max_step())
    warm.frame()
    sim = blobflow_dam_break(n_target, solver)
    steps, iters, worst_mean, worst_max = 0, 0, 0.0, 0.0
    late_mean, late_max = 0.0, 0.0
    dts = []
    t0 = time.perf_counter()
    while sim.state.time < t_end - 1e-12:
        dt = min(sim.max_step(), t_end - sim.state.time)
        sim.step(dt)
        steps += 1
        dts.append(dt)
        iters += sim.last_density_iterations
        worst_mean = max(worst_mean, sim.mean_density_error)  # at the step's start positions
        worst_max = max(worst_max, sim.density_error)
        if sim.state.time - dt >= 0.05:
            late_mean = max(late_mean, sim.mean_density_error)
            late_max = max(late_max, sim.density_error)
    wall = time.perf_counter() - t0
    sim.frame()
    worst_mean = max(worst_mean, sim.mean_density_error)
    worst_max = max(worst_max, sim.density_error)
    v = np.sqrt((sim.state.velocities ** 2).sum(axis=1))
    m = sim.model
    return {"code": "blobflow", "solver": solver, "fluid_particles": sim.state.n_points,
            "boundary_particles": int(m.boundary_points.shape[0]), "sim_time_s": t_end,
            "wall_s": wall, "wall_s_per_sim_s": wall / t_end, "steps": steps,
            "mean_dt_s": float(np.mean(dts)), "density_iterations_per_step": iters / steps,
            "worst_mean_density_error": worst_mean, "worst_particle_density_error": worst_max,
            "worst_mean_density_error_after_50ms": late_mean,
            "worst_particle_density_error_after_50ms": late_max,
            "front_x_m": float(np.sort(sim.state.positions[:, 0])[-10]),
            "max_speed_end_m_s": float(v.max()),
            "container_corrections": int(sim.contained),
            "settings": {"cfl": m.cfl, "max_dt": m.max_dt, "max_density_error":
                         m.max_density_error, "max_divergence_error": m.max_divergence_error,
                         "viscosity": m.viscosity, "kinematic_viscosity": NU if solver == "dfsph"
                         else None, "speed_of_sound": m.speed_of_sound, "support_m": m.support}}


def part_persim_splishsplash(size, solver):
    import numpy as np
    import pysplishsplash as sph

    n_target = SIZES[size]
    wcsph = solver == "wcsph"
    t_end = T_END
    dt = None
    if wcsph:  # blobflow's WCSPH step for this column, fixed
        sim0 = blobflow_dam_break(n_target, "wcsph")
        dt = sim0.max_step()
        del sim0
    out = tempfile.mkdtemp(prefix="sph_bench_")
    scene = Path(out) / "dam.json"
    splishsplash_scene(scene, n_target, 0 if wcsph else 4, t_end, dt)
    base = sph.Exec.SimulatorBase()
    base.init(useGui=False, sceneFile=str(scene), outputDir=out)
    base.initSimulation()
    sim = sph.Simulation.getCurrent()
    fm = sim.getFluidModel(0)
    ts = sim.getTimeStep()
    tm = sph.TimeManager.getCurrent()
    n = fm.numActiveParticles()
    visc = fm.getViscosityBase()
    settings = {  # read back from the loaded simulation
        "simulationMethod": sim.getValueInt(sim.SIMULATION_METHOD),
        "boundaryHandlingMethod": sim.getValueInt(sim.BOUNDARY_HANDLING_METHOD),
        "cflMethod": sim.getValueInt(sim.CFL_METHOD),
        "cflFactor": sim.getValueFloat(sim.CFL_FACTOR),
        "cflMaxTimeStepSize": sim.getValueFloat(sim.CFL_MAX_TIMESTEPSIZE),
        "particleRadius": sim.getValueFloat(sim.PARTICLE_RADIUS),
        "viscosity_method": type(visc).__name__ if visc is not None else None,
        "viscosity": visc.getValueFloat(visc.VISCOSITY_COEFFICIENT) if visc is not None else None,
        "timeStepSize": tm.getTimeStepSize(),
    }
    if wcsph:
        settings["stiffness"] = ts.getValueFloat(ts.STIFFNESS)
        settings["exponent"] = ts.getValueFloat(ts.EXPONENT)
    else:
        settings.update(maxError=ts.getValueFloat(ts.MAX_ERROR),
                        maxErrorV=ts.getValueFloat(ts.MAX_ERROR_V),
                        maxIterations=ts.getValueInt(ts.MAX_ITERATIONS),
                        maxIterationsV=ts.getValueInt(ts.MAX_ITERATIONS_V),
                        enableDivergenceSolver=ts.getValueBool(ts.USE_DIVERGENCE_SOLVER))
    density = np.asarray(fm.getFieldBuffer("density"))
    stats = {"steps": 0, "iters": 0, "worst_mean": 0.0, "worst_max": 0.0, "late_mean": 0.0,
             "late_max": 0.0, "dts": []}

    def callback():  # densities at the step's start positions (a view, no copy)
        d = density[:n] * (1.0 / 1000.0) - 1.0
        stats["steps"] += 1
        stats["dts"].append(tm.getTimeStepSize())
        mean, worst = float(np.maximum(d, 0.0).mean()), float(d.max())
        stats["worst_mean"] = max(stats["worst_mean"], mean)
        stats["worst_max"] = max(stats["worst_max"], worst)
        if tm.getTime() - tm.getTimeStepSize() >= 0.05:
            stats["late_mean"] = max(stats["late_mean"], mean)
            stats["late_max"] = max(stats["late_max"], worst)
        if not wcsph:
            stats["iters"] += ts.getValueInt(ts.SOLVER_ITERATIONS)

    base.setTimeStepCB(callback)
    t0 = time.perf_counter()
    base.runSimulation()
    wall = time.perf_counter() - t0
    nb = int(sum(sim.getBoundaryModel(i).numberOfParticles()
                 for i in range(sim.numberOfBoundaryModels())))
    x = np.asarray(fm.getFieldBuffer("position"))[:n]
    v = np.sqrt((np.asarray(fm.getFieldBuffer("velocity"))[:n].astype(float) ** 2).sum(axis=1))
    steps = stats["steps"]
    return {"code": "SPlisHSPlasH", "solver": solver, "version": "2.19",
            "fluid_particles": int(n), "boundary_particles": nb,
            "sim_time_s": float(tm.getTime()), "wall_s": wall,
            "wall_s_per_sim_s": wall / float(tm.getTime()), "steps": steps,
            "mean_dt_s": float(np.mean(stats["dts"])),
            "density_iterations_per_step": stats["iters"] / steps if not wcsph else None,
            "worst_mean_density_error": stats["worst_mean"],
            "worst_particle_density_error": stats["worst_max"],
            "worst_mean_density_error_after_50ms": stats["late_mean"],
            "worst_particle_density_error_after_50ms": stats["late_max"],
            "front_x_m": float(np.sort(x[:, 0])[-10]), "max_speed_end_m_s": float(v.max()),
            "settings": settings}


# =============================================================================================
# Neighbour search and memory.
# =============================================================================================
def part_nsearch(compare_passes=True):
    import numpy as np
    from numba import njit, prange
    from scipy.spatial import cKDTree

    from filters.binning import cell_keys as _grid_keys
    from filters.binning import counting_sort as _counting_sort
    from filters.kernels import cubic_dw, cubic_w
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


def part_memory(solver):
    import gc
    import threading

    import psutil

    proc = psutil.Process()
    small = blobflow_dam_break(2000, solver)
    small.step(small.max_step())
    small.frame()
    del small
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
    sim = blobflow_dam_break(1_000_000, solver)
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    for _ in range(2):
        sim.step(sim.max_step())
    t_steps = (time.perf_counter() - t0) / 2
    stop[0] = True
    th.join()
    n = sim.state.n_points
    return {"solver": solver, "fluid_particles": n,
            "boundary_particles": int(sim.model.boundary_points.shape[0]),
            "peak_rss_increase_bytes": peak[0] - base,
            "peak_bytes_per_fluid_particle": (peak[0] - base) / n,
            "build_s": t_build, "s_per_step_1M": t_steps}


# =============================================================================================
# Orchestration.
# =============================================================================================
PARTS = {"nsearch": lambda: part_nsearch(), "nsearch_2threads": lambda: part_nsearch(False),
         "memory_dfsph": lambda: part_memory("dfsph"), "memory_wcsph": lambda: part_memory("wcsph")}
for _size in SIZES:
    for _solver in ("dfsph", "wcsph"):
        PARTS[f"persim_{_size}_blobflow_{_solver}"] = (
            lambda s=_size, v=_solver: part_persim_blobflow(s, v))
        PARTS[f"persim_{_size}_splishsplash_{_solver}"] = (
            lambda s=_size, v=_solver: part_persim_splishsplash(s, v))


def run_part(name, timeout=3600):
    env = dict(os.environ)
    threads = 2 if name.endswith("_2threads") else 1
    env.update(NUMBA_NUM_THREADS=str(threads), OMP_NUM_THREADS=str(threads),
               OPENBLAS_NUM_THREADS="1")
    if "splishsplash" in name:
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
    return {"error": f"exit {proc.returncode}", "tail": (proc.stdout + proc.stderr)[-1500:]}


def main():
    results = {"machine": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
               "threads": 1, "spacing_m": SPACING, "kinematic_viscosity_m2_s": NU,
               "max_density_error": MAX_ERROR, "max_divergence_error": MAX_ERROR_V,
               "sim_time_s": T_END,
               "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    only = sys.argv[1:] or list(PARTS)
    for name in only:
        print(f"--- {name}", flush=True)
        results[name] = run_part(name)
        print(json.dumps(results[name], indent=1), flush=True)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    previous = json.loads(RESULTS.read_text()) if RESULTS.exists() and sys.argv[1:] else {}
    previous.update(results)
    previous["summary"] = summarise(previous)
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
    for size in SIZES:
        ours = _get(r, f"persim_{size}_blobflow_dfsph", "wall_s_per_sim_s")
        peer = _get(r, f"persim_{size}_splishsplash_dfsph", "wall_s_per_sim_s")
        wc = _get(r, f"persim_{size}_blobflow_wcsph", "wall_s_per_sim_s")
        pwc = _get(r, f"persim_{size}_splishsplash_wcsph", "wall_s_per_sim_s")
        if ours and peer:
            s[f"dfsph_speedup_vs_splishsplash_dfsph_{size}"] = peer / ours
        if ours and wc:
            s[f"dfsph_speedup_vs_blobflow_wcsph_{size}"] = wc / ours
        if wc and pwc:
            s[f"wcsph_speedup_vs_splishsplash_wcsph_{size}"] = pwc / wc
        mine = _get(r, f"persim_{size}_blobflow_dfsph", "worst_particle_density_error_after_50ms")
        theirs = _get(r, f"persim_{size}_splishsplash_dfsph",
                      "worst_particle_density_error_after_50ms")
        if mine and theirs:  # <= 1: blobflow's worst particle no worse than SPlisHSPlasH's
            s[f"dfsph_worst_particle_vs_splishsplash_{size}"] = mine / theirs
    for part in ("nsearch", "nsearch_2threads"):
        for n in ("100000", "1000000"):
            v = _get(r, part, n, "speedup_pairs_vs_ckdtree")
            if v:
                s[f"{part}_speedup_{n}"] = v
    for solver in ("dfsph", "wcsph"):
        m = _get(r, f"memory_{solver}", "peak_bytes_per_fluid_particle")
        if m:
            s[f"memory_bytes_per_particle_1M_{solver}"] = m
    return s


def table(r):
    s = r.get("summary", {})

    def fmt(v, f="{:.3g}"):
        return "n/a" if v is None else f.format(v)

    def pct(v):
        return "n/a" if v is None else f"{100 * v:.2f} %"

    rows = ["| wall s per simulated s, dam break, 1 thread | particles | blobflow DFSPH | "
            "SPlisHSPlasH DFSPH | blobflow WCSPH | SPlisHSPlasH WCSPH | DFSPH speed-up vs "
            "SPlisHSPlasH DFSPH (>= 1.5) / vs blobflow WCSPH (>= 3) |",
            "|---|---|---|---|---|---|---|"]
    for size in SIZES:
        cells = []
        for code, solver in (("blobflow", "dfsph"), ("splishsplash", "dfsph"),
                             ("blobflow", "wcsph"), ("splishsplash", "wcsph")):
            d = _get(r, f"persim_{size}_{code}_{solver}")
            cells.append("n/a" if not d or "error" in d else
                         f"{fmt(d['wall_s_per_sim_s'])} (density error mean/worst particle "
                         f"{pct(d['worst_mean_density_error'])} / "
                         f"{pct(d['worst_particle_density_error'])}; after 50 ms "
                         f"{pct(d['worst_mean_density_error_after_50ms'])} / "
                         f"{pct(d['worst_particle_density_error_after_50ms'])})")
        n = _get(r, f"persim_{size}_blobflow_dfsph", "fluid_particles")
        rows.append(f"| {size} | {n} | " + " | ".join(cells) + " | "
                    f"{fmt(s.get(f'dfsph_speedup_vs_splishsplash_dfsph_{size}'))}x / "
                    f"{fmt(s.get(f'dfsph_speedup_vs_blobflow_wcsph_{size}'))}x |")
    for part, n in [(p, n) for p in ("nsearch", "nsearch_2threads") for n in ("100000", "1000000")]:
        d = _get(r, part, n)
        threads = 2 if part.endswith("2threads") else 1
        rows.append(f"| neighbour pairs at r = 2 spacings, {n} points, {threads} thread(s) | | "
                    f"{fmt(_get(d, 'blobflow_grid_pairs_s'))} s | cKDTree "
                    f"{fmt(_get(d, 'ckdtree_build_plus_query_pairs_s'))} s | | | "
                    f"{fmt(_get(d, 'speedup_pairs_vs_ckdtree'))}x |")
    for solver in ("dfsph", "wcsph"):
        m = _get(r, f"memory_{solver}")
        rows.append(f"| peak memory per fluid particle, 1M dam break, {solver} | "
                    f"{_get(m, 'fluid_particles')} | "
                    f"{fmt(_get(m, 'peak_bytes_per_fluid_particle'), '{:.0f}')} B | | | | |")
    return "\n".join(rows)


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--part":
        sys.path.insert(0, str(HERE.parent))
        result = PARTS[sys.argv[2]]()
        print("RESULT " + json.dumps(result), flush=True)
    else:
        main()
