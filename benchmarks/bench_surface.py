"""Surface reconstruction from particles: blobflow vs. pysplashsurf (and VTK's own SPH path).

One run, side by side, on identical particles:

* ``block_100k``: a jittered lattice block of 50 x 50 x 40 = 100,000 particles,
* ``block_1m``: a jittered lattice block of 100^3 = 1,000,000 particles,
* ``sphere_100k``: the 100,000 jittered lattice points nearest to a centre (a ball),
* ``splash_1m``: about 1M particles (984,070) spread over a cube whose volume is 10x the
  liquid's: half in a pool on its floor, half in balls of radius 5 spacings strewn above it.
  Shows that memory follows the surface: ``grid_MiB`` (the sparse grid) against
  ``dense_box_MiB`` (a dense float32 grid over the same box, 2.5 GiB),

with lattice spacing 0.02 m, jitter uniform in +-10 % of the spacing, seed 0.

Tools, each in its own subprocess (peak resident memory per tool):

* ``pysplashsurf`` (Löschner et al. 2023) ``reconstruct_surface``: particle radius 0.01 m,
  smoothing length 2.0 and cube size 0.5 (multiples of the radius), iso 0.6, float32 input;
  the cell size of the grid it builds is read back from its result (``grid_cell_size_m``,
  which must be 0.005 m) and the triangle counts are compared.
* ``blobflow``: ``filters.surface.splat.splat_sparse`` (SPH kernel, support 4 r = 2 x smoothing
  length, iso 0.6, cell 0.005 m) + ``pipeline.surface.contour_sparse`` (flying edges per brick,
  stitched); smoothing (``Smooth`` defaults) is timed separately and not part of the ratio,
  because ``reconstruct_surface`` does no post-processing.
* ``vtk_sph`` (100k block only): vtkSPHInterpolator (cubic spline, same support, particle
  volume s^3) onto a vtkImageData with the same cell size + vtkFlyingEdges3D.

The machine is shared, so runs alternate between the tools, one fresh process per run
(``--repeats`` rounds for the 100k cases, 2 for the others). Reported per tool and case: the best
wall time (all listed), the largest peak RSS of its processes (VmHWM) and the largest increase over
the RSS after imports, Numba warm-up and data generation, triangles, closed / manifold, and the
volume error against the particles' volume ``N s^3``. The absolute peak includes the
interpreter and libraries: about 230 MiB for blobflow (Numba's LLVM, VTK), 50 MiB for
pysplashsurf.

``--flatness`` runs the anisotropic-kernel benchmark instead (resting pools: RMS distance of
the top surface from the true plane; a cube's edges; cost against the isotropic path), see
``bench_anisotropy.py``.

Run under the shared lock::

    flock /tmp/blobflow-bench.lock env OPENBLAS_NUM_THREADS=1 \\
        /tmp/venv/bin/python benchmarks/bench_surface.py
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SPACING = 0.02
RADIUS = 0.01
CELL = 0.005
ISO = 0.6
CASES = {
    "block_100k": ("block", (50, 50, 40)),
    "block_1m": ("block", (100, 100, 100)),
    "sphere_100k": ("sphere", 100_000),
    "splash_1m": ("splash", 1_000_000),
}
SPLASH_BOX_FACTOR = 10.0  # the splash's bounding box / the liquid's volume


def make_particles(case: str) -> np.ndarray:
    """The particles of a case, (N, 3) float64 (m): jittered lattice, fixed seed."""
    kind, size = CASES[case]
    rng = np.random.default_rng(0)
    if kind == "block":
        g = np.stack(np.meshgrid(*[np.arange(n) for n in size], indexing="ij"), -1)
        g = g.reshape(-1, 3).astype(np.float64)
    elif kind == "sphere":
        r = int(np.ceil((3 * size / (4 * np.pi)) ** (1 / 3))) + 2
        g = np.stack(np.meshgrid(*[np.arange(-r, r + 1)] * 3, indexing="ij"), -1)
        g = g.reshape(-1, 3).astype(np.float64)
        d = np.linalg.norm(g, axis=1)
        g = g[np.argsort(d, kind="stable")[:size]]
    else:
        g = _splash_lattice(size, rng)
    x = g * SPACING + rng.uniform(-0.1 * SPACING, 0.1 * SPACING, g.shape)
    return np.ascontiguousarray(x)


def _splash_lattice(size: int, rng) -> np.ndarray:
    """Lattice points (spacing units) of a splash: a pool holding half the particles on the
    floor of a cube whose volume is ``SPLASH_BOX_FACTOR`` times the liquid's, the other half
    as balls of radius 5 spacings strewn over the cube above the pool (overlaps removed)."""
    side = int(round((SPLASH_BOX_FACTOR * size) ** (1 / 3)))
    layers = max(1, (size // 2) // (side * side))
    pool = np.stack(np.meshgrid(np.arange(side), np.arange(side), np.arange(layers),
                                indexing="ij"), -1).reshape(-1, 3)
    r = 5
    ball = np.stack(np.meshgrid(*[np.arange(-r, r + 1)] * 3, indexing="ij"), -1).reshape(-1, 3)
    ball = ball[(ball**2).sum(1) <= r * r]
    count = (size - pool.shape[0]) // ball.shape[0] + 1
    centres = rng.integers([r, r, layers + r + 2], [side - r, side - r, side - r],
                           size=(count, 3))
    drops = (centres[:, None, :] + ball[None, :, :]).reshape(-1, 3)
    # overlapping balls merge (about 1.6 % fewer particles than asked for)
    return np.unique(np.concatenate([pool, drops]), axis=0).astype(np.float64)


def _rss_mib() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def _peak_mib() -> float:
    """Peak RSS of this process image (VmHWM). Not ru_maxrss: on Linux that survives exec and
    so includes the parent's RSS at fork time."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def worker(tool: str, case: str, repeats: int, mesh_path: str) -> dict:
    """Run one tool on one case in this process, save its mesh, return its measurements.

    The pysplashsurf worker imports nothing of blobflow (no Numba threads in its process)."""
    x = make_particles(case)
    n = x.shape[0]
    extra = {}
    if tool == "pysplashsurf":
        import pysplashsurf

        xf = x.astype(np.float32)
        del x

        def run():
            rec = pysplashsurf.reconstruct_surface(
                xf, particle_radius=RADIUS, smoothing_length=2.0, cube_size=0.5,
                iso_surface_threshold=ISO)
            # its settings read back: the marching-cubes grid it built (cube_size is a multiple
            # of the particle radius, so the cell must come back as CELL)
            extra["grid_cell_size_m"] = float(rec.grid.cell_size)
            extra["grid_cells_per_dim"] = [int(v) for v in rec.grid.ncells_per_dim]
            return np.asarray(rec.mesh.vertices), np.asarray(rec.mesh.triangles)

        warm = lambda: None  # noqa: E731
    elif tool == "blobflow":
        from filters.surface.splat import splat_sparse
        from pipeline.surface.contour import contour_sparse

        def run():
            t0 = time.perf_counter()
            grid = splat_sparse(x, RADIUS, CELL, kernel="sph", iso=ISO)
            t1 = time.perf_counter()
            out = contour_sparse(grid)
            t2 = time.perf_counter()
            extra.setdefault("splat_s", []).append(t1 - t0)
            extra.setdefault("contour_s", []).append(t2 - t1)
            extra["grid_MiB"] = grid.nbytes / 2**20
            # what a dense grid over the particles' supports would take (float32)
            span = x.max(axis=0) - x.min(axis=0) + 2 * 4 * RADIUS
            extra["dense_box_MiB"] = float(np.prod(np.ceil(span / CELL) + 1)) * 4 / 2**20
            return out

        def warm():  # compile / load the Numba cache outside the timings
            g = splat_sparse(x[:500], RADIUS, CELL)
            contour_sparse(g)
    elif tool == "vtk_sph":
        from vtkmodules.util import numpy_support
        from vtkmodules.vtkCommonCore import vtkPoints
        from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPolyData, vtkStaticPointLocator
        from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D
        from vtkmodules.vtkFiltersPoints import vtkSPHCubicKernel, vtkSPHInterpolator

        def run():
            poly = vtkPolyData()
            pts = vtkPoints()
            pts.SetData(numpy_support.numpy_to_vtk(x, deep=True))
            poly.SetPoints(pts)
            for name, value in (("one", 1.0), ("mass", SPACING**3), ("density", 1.0)):
                arr = numpy_support.numpy_to_vtk(np.full(n, value), deep=True)
                arr.SetName(name)
                poly.GetPointData().AddArray(arr)
            support = 4 * RADIUS
            lo = x.min(axis=0) - support - CELL
            dims = np.ceil((x.max(axis=0) - lo + support + CELL) / CELL).astype(int) + 1
            image = vtkImageData()
            image.SetDimensions(*[int(d) for d in dims])
            image.SetOrigin(*lo)
            image.SetSpacing(CELL, CELL, CELL)
            locator = vtkStaticPointLocator()
            locator.SetDataSet(poly)
            locator.BuildLocator()
            kernel = vtkSPHCubicKernel()
            kernel.SetSpatialStep(support / 2)  # smoothing length; cubic support = 2 x
            interp = vtkSPHInterpolator()
            interp.SetInputData(image)
            interp.SetSourceData(poly)
            interp.SetLocator(locator)
            interp.SetKernel(kernel)
            interp.SetMassArrayName("mass")
            interp.SetDensityArrayName("density")
            interp.ShepardNormalizationOff()
            interp.PassPointArraysOff()
            interp.Update()
            out = interp.GetOutput()
            out.GetPointData().SetActiveScalars("one")
            fe = vtkFlyingEdges3D()
            fe.SetInputData(out)
            fe.SetValue(0, ISO)
            fe.ComputeNormalsOff()
            fe.ComputeGradientsOff()
            fe.ComputeScalarsOff()
            fe.Update()
            mesh = fe.GetOutput()
            v = numpy_support.vtk_to_numpy(mesh.GetPoints().GetData()).copy()
            t = numpy_support.vtk_to_numpy(mesh.GetPolys().GetConnectivityArray()).reshape(-1, 3)
            return v, t.copy()

        warm = lambda: None  # noqa: E731
    else:
        raise ValueError(f"unknown tool {tool!r}")

    warm()
    baseline = _rss_mib()
    times = []
    result = None
    for _ in range(repeats):
        result = None
        t0 = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - t0)
    verts, tris = result
    if mesh_path.endswith(".npz"):
        mesh_path = mesh_path[:-4]
    np.savez(mesh_path, vertices=np.asarray(verts, np.float32),
             triangles=np.asarray(tris, np.int64))
    out = {
        "tool": tool, "case": case, "particles": int(n),
        "time_s": min(times), "times_s": times,
        "peak_rss_MiB": _peak_mib(), "baseline_rss_MiB": baseline,
        "peak_increase_MiB": _peak_mib() - baseline,
    }
    if tool == "pysplashsurf":
        out["grid_cell_size_m"] = extra["grid_cell_size_m"]
        out["grid_cells_per_dim"] = extra["grid_cells_per_dim"]
        if not math.isclose(extra["grid_cell_size_m"], CELL, rel_tol=1e-6):
            raise RuntimeError(f"pysplashsurf built a grid of cell {extra['grid_cell_size_m']} m, "
                               f"not {CELL} m: its settings were not taken as meant")
    if tool == "blobflow":
        out["splat_s"] = min(extra["splat_s"])
        out["contour_s"] = min(extra["contour_s"])
        out["grid_MiB"] = extra["grid_MiB"]
        out["dense_box_MiB"] = extra["dense_box_MiB"]
    return out


def measure_mesh(row: dict, mesh_path: str) -> None:
    """Mesh measures (and, for blobflow, the smoothing stage) in the parent process."""
    from filters.surface.mesh import mesh_stats
    from pipeline.surface import Smooth
    from pipeline.surface.contour import mesh_to_polydata, polydata_to_mesh

    data = np.load(mesh_path)
    verts, tris = data["vertices"].astype(np.float64), data["triangles"]
    n = row["particles"]
    st = mesh_stats(verts, tris)
    row.update({"triangles": st.triangles, "vertices": st.points, "closed": st.closed,
                "manifold": st.manifold, "euler": st.euler, "components": st.components,
                "volume": abs(st.volume), "area": st.area,
                "volume_error": abs(st.volume) / (n * SPACING**3) - 1.0})
    if row["tool"] == "blobflow":
        smooth = Smooth()
        smooth.SetInputDataObject(mesh_to_polydata(verts, tris))
        t0 = time.perf_counter()
        smooth.Update()
        row["smooth_s"] = time.perf_counter() - t0
        s2 = mesh_stats(*polydata_to_mesh(smooth.GetOutputDataObject(0)))
        row["smoothed_volume_error"] = abs(s2.volume) / (n * SPACING**3) - 1.0
        row["smoothed_closed_manifold"] = bool(s2.closed and s2.manifold)


def _run_worker(tool: str, case: str, env: dict) -> dict:
    """One timed run of ``tool`` on ``case`` in a fresh process."""
    fd, mesh_path = tempfile.mkstemp(prefix=f"bench_surface_{tool}_{case}_", suffix=".npz")
    os.close(fd)
    proc = subprocess.run([sys.executable, __file__, "--worker", tool, case, mesh_path,
                           "--repeats", "1"], capture_output=True, text=True, env=env,
                          timeout=900)
    if proc.returncode != 0:
        return {"tool": tool, "case": case, "error": proc.stderr[-2000:]}
    row = json.loads(proc.stdout.strip().splitlines()[-1])
    row["mesh_path"] = mesh_path
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worker", nargs=3, metavar=("TOOL", "CASE", "MESH_NPZ"))
    parser.add_argument("--repeats", type=int, default=5,
                        help="runs per tool for the 100k cases (alternating; 2 for the others)")
    parser.add_argument("--cases", default=",".join(CASES))
    parser.add_argument("--output", default=str(Path(__file__).parent / "results" / "surface.json"))
    parser.add_argument("--flatness", action="store_true",
                        help="instead: flatness, sharpness and cost of anisotropic kernels against "
                             "isotropic ones and pysplashsurf (bench_anisotropy.run_flatness; "
                             "writes results/anisotropy.json and anisotropy_flatness.png)")
    args = parser.parse_args(argv)
    if args.flatness:
        from bench_anisotropy import run_flatness  # this script's folder is on sys.path

        run_flatness(print)
        return 0
    if args.worker:
        print(json.dumps(worker(args.worker[0], args.worker[1], args.repeats, args.worker[2])))
        return 0
    rows = []
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    for case in args.cases.split(","):
        tools = ["pysplashsurf", "blobflow"]
        rounds = args.repeats if case.endswith("100k") else 2
        runs = {tool: [] for tool in tools}
        # alternate the tools, one fresh process per run, so that both see the same
        # (shared, fluctuating) machine load; keep the best time and the largest peak
        for _ in range(rounds):
            for tool in tools:
                runs[tool].append(_run_worker(tool, case, env))
        if case == "block_100k":
            runs["vtk_sph"] = [_run_worker("vtk_sph", case, env)]
        for tool, results in runs.items():
            failed = [r for r in results if "error" in r]
            if failed:
                rows.append(failed[0])
                print(f"{case:12s} {tool:13s} FAILED\n{failed[0]['error']}", flush=True)
                continue
            best = min(results, key=lambda r: r["time_s"])
            row = dict(best)
            row["times_s"] = [r["time_s"] for r in results]
            row["peak_rss_MiB"] = max(r["peak_rss_MiB"] for r in results)
            row["peak_increase_MiB"] = max(r["peak_increase_MiB"] for r in results)
            row["runs"] = len(results)
            measure_mesh(row, best["mesh_path"])
            row.pop("mesh_path", None)
            for r in results:
                if os.path.exists(r["mesh_path"]):
                    os.remove(r["mesh_path"])
            rows.append(row)
            print(f"{case:12s} {tool:13s} {row['time_s']:8.3f} s  peak {row['peak_rss_MiB']:7.1f}"
                  f" MiB (+{row['peak_increase_MiB']:6.1f})  tris {row['triangles']:9d}  "
                  f"closed {row['closed']!s:5s} manifold {row['manifold']!s:5s}  "
                  f"vol.err {100 * row['volume_error']:+.3f} %", flush=True)
    ratios = {}
    for case in args.cases.split(","):
        by = {r["tool"]: r for r in rows if r.get("case") == case and "error" not in r}
        if "pysplashsurf" in by and "blobflow" in by:
            p, b = by["pysplashsurf"], by["blobflow"]
            ratios[case] = {
                "time_ratio": b["time_s"] / p["time_s"],
                "peak_rss_ratio": b["peak_rss_MiB"] / p["peak_rss_MiB"],
                "peak_increase_ratio": b["peak_increase_MiB"] / max(p["peak_increase_MiB"], 1e-9),
            }
            print(f"{case:12s} blobflow / pysplashsurf: time {ratios[case]['time_ratio']:.2f}x, "
                  f"peak RSS {ratios[case]['peak_rss_ratio']:.2f}x, "
                  f"peak increase {ratios[case]['peak_increase_ratio']:.2f}x")
    result = {
        "benchmark": "surface",
        "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                    "load_average": os.getloadavg()},
        "parameters": {"spacing_m": SPACING, "jitter": "+-10% uniform", "seed": 0,
                       "particle_radius_m": RADIUS, "smoothing_length_r": 2.0,
                       "cube_size_r": 0.5, "cell_size_m": CELL, "iso": ISO,
                       "blobflow_kernel": "sph, support 4 r"},
        "rows": rows,
        "ratios_blobflow_over_pysplashsurf": ratios,
    }
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    Path(args.output).write_text(json.dumps(result, indent=2))
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
