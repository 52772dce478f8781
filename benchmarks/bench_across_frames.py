"""Benchmark: the across-frames surface filter on the main job's frames, now and before.

The frames are those of the main job (``blobflow run dam_break`` at its defaults: 46 frames,
31,250 particles, surfaces of 124k-171k vertices), written once by this script (``--run DIR``
reuses a run's folder: ``particles.pvd`` and ``surface.pvd``). Every frame's surface is
filtered with the two frames on each side (``blobflow surface --across-frames 2``: weights 1,
2, 3, 2, 1 over 9, the particles matched by id, the vertices on the tank's walls held), three
ways, side by side in one run:

* ``filter``: :func:`filters.surface.temporal.follow_particles_across_frames` on the frames in
  memory, each neighbour's surface given as ``(vertices, triangles)`` (binned per call), plus
  the output's normals (:func:`filters.surface.temporal.vertex_normals`) as the pipeline
  writes them;
* ``filter_grids_reused``: the same with every surface binned once
  (:class:`filters.surface.linecast.TriangleGrid`) and reused by the frames it serves, as
  the pipeline does; a frame's time includes the binning of one surface;
* ``baseline``: the filter of a git revision (``--baseline``, default: where this branch left
  ``main``), loaded from that revision's ``filters/surface/temporal.py``, on the same frames in
  the same rounds; its results are compared with today's bit for bit (vertices and normals,
  every frame);
* ``pipeline``: :func:`pipeline.surface.across_frames.smooth_series_across_frames`'s filtering pass
  on the run's files (reads, filter, writes; the first pass's single-frame surfaces are the
  run's own), seconds a frame, beside the same pass of the baseline revision
  (``pipeline/across_frames.py`` on its filter), whose files must be identical.

Frames are timed round-robin (each repeat visits every frame with every method), medians
reported; the issue's target is <= 0.3 s a frame. Run it under the lock for heavy jobs::

    flock /tmp/blobflow-heavy.lock env OPENBLAS_NUM_THREADS=1 \\
        python benchmarks/bench_across_frames.py [--run DIR] [--repeats N]

Writes ``benchmarks/results/across_frames.json``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results" / "across_frames.json"
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

K = 2  # frames on each side, as ``--across-frames 2``


def main_job_frames(out: Path) -> None:
    """``blobflow run dam_break --no-render`` into ``out`` (the main job's frames)."""
    cmd = [sys.executable, "-m", "pipeline", "run", "dam_break", "--no-render", "--quiet",
           "--out", str(out)]
    subprocess.run(cmd, cwd=ROOT, check=True)


def load_frames(run: Path):
    """Particles (F, N, 3) in id order, surfaces [(points, triangles)], tank (lower, upper),
    particle radius (m) of a run's folder."""
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkCommonDataModel import vtkPointSet, vtkPolyData

    from pipeline.io.series import read_collection, read_frame
    from pipeline.surface.contour import polydata_to_mesh

    record = json.loads((run / "scene.json").read_text())
    prm = record["parameters"]
    width = prm["depth"] if "depth" in prm else prm["tank_width"]  # dam_break / drop
    tank = (np.zeros(3), np.array([prm["tank_length"], width, prm["tank_height"]]))
    particles, surfaces = [], []
    for (_, rp), (_, rs) in zip(read_collection(run / "particles.pvd"),
                                read_collection(run / "surface.pvd"), strict=True):
        data = read_frame(str(run / rp))
        ids = numpy_support.vtk_to_numpy(data.GetPointData().GetArray("id")).astype(np.int64)
        x = numpy_support.vtk_to_numpy(vtkPointSet.SafeDownCast(data).GetPoints().GetData())
        particles.append(np.asarray(x, np.float64)[np.argsort(ids)])
        surfaces.append(polydata_to_mesh(vtkPolyData.SafeDownCast(read_frame(str(run / rs)))))
    return np.array(particles), surfaces, tank, 0.5 * prm["spacing"]


def _git(*args) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, check=True, capture_output=True,
                          text=True).stdout


def _module_of(revision: str, path: str, name: str, folder: Path, package: str, replace=()):
    """``path`` as of ``revision``, importable as ``name`` beside today's packages (its
    relative imports made absolute into ``package``, then ``replace`` applied)."""
    source = _git("show", f"{revision}:{path}")
    parent = package.rpartition(".")[0]
    source = re.sub(r"^(\s*)from \.\.(\w)", rf"\1from {parent}.\2", source, flags=re.M)
    source = re.sub(r"^(\s*)from \.(\w)", rf"\1from {package}.\2", source, flags=re.M)
    for old, new in replace:
        source = source.replace(old, new)
    file = folder / f"{name}.py"
    file.write_text(source)
    spec = importlib.util.spec_from_file_location(name, file)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def baseline_modules(revision: str, folder: Path):
    """The across-frames filter (``filters/surface/temporal.py``) and pass
    (``pipeline/surface/across_frames.py``, on that filter) as of ``revision``, running on today's
    helpers (binning, attributes, series)."""
    temporal = _module_of(revision, "filters/surface/temporal.py", "temporal_baseline", folder,
                          "filters.surface")
    # pipeline/surface/across_frames.py since pipeline/ was organised by purpose; the flat
    # pipeline/across_frames.py before (its old imports resolve through pipeline's aliases)
    listed = _git("ls-tree", "-r", "--name-only", revision, "pipeline").split()
    path, package = (("pipeline/surface/across_frames.py", "pipeline.surface")
                     if "pipeline/surface/across_frames.py" in listed
                     else ("pipeline/across_frames.py", "pipeline"))
    passes = _module_of(revision, path, "across_frames_baseline", folder, package,
                        replace=[("from filters.surface.temporal import",
                                  "from temporal_baseline import")])
    return temporal, passes


def neighbours_of(k, particles, surfaces, grids=None):
    """The (rows, positions, surface...) entries and weights of frame ``k``'s neighbours."""
    from pipeline.surface.across_frames import weights_across

    w = weights_across(K)
    rows = np.arange(particles.shape[1])
    entries, weights = [], [w[K]]
    for j in range(-K, K + 1):
        if j == 0 or not 0 <= k + j < len(surfaces):
            continue
        surface = (grids[k + j],) if grids is not None else surfaces[k + j]
        entries.append((rows, particles[k + j], *surface))
        weights.append(w[K + j])
    return entries, weights


def pipeline_pass(run: Path, particles, radius, tank, work: Path, across_frames=None) -> float:
    """Seconds a frame of the pipeline's filtering pass on the run's files (``across_frames``:
    the module that makes it, today's by default); the series in ``work/smoothed.pvd``."""
    from filters.geometry import Box
    from pipeline.io.series import read_collection

    if across_frames is None:
        from pipeline.surface import across_frames

    def single(source, target, **kwargs):  # the first pass: the run's own surfaces
        folder = Path(target).parent / Path(target).stem
        folder.mkdir(parents=True, exist_ok=True)
        for i, (_, rel) in enumerate(read_collection(run / "surface.pvd")):
            shutil.copy(run / rel, folder / f"{Path(target).stem}_{i:06d}.vtp")

    out = work / "smoothed.pvd"
    if out.parent.exists():
        shutil.rmtree(out.parent)
    out.parent.mkdir(parents=True)
    options = {"radius": radius, "implicit": Box(*tank)}
    t0 = time.perf_counter()
    across_frames.smooth_series_across_frames(run / "particles.pvd", out, K, options,
                                              single=single, progress=False)
    return (time.perf_counter() - t0) / len(particles)


def main(argv=None) -> dict:
    import numba

    from filters.surface.linecast import TriangleGrid
    from filters.surface.temporal import follow_particles_across_frames, vertex_normals

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", type=Path, help="a run's folder (default: run the main job)")
    parser.add_argument("--baseline", default=None,
                        help="git revision of the old filter (default: git merge-base HEAD main)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--output", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    if args.baseline is None:
        args.baseline = _git("merge-base", "HEAD", "main").strip()

    load_start = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        run = args.run
        if run is None:
            run = tmp / "main_job"
            main_job_frames(run)
        particles, surfaces, tank, radius = load_frames(run)
        frames = len(surfaces)
        old, old_pass = baseline_modules(args.baseline, tmp)

        def today(k):
            entries, weights = neighbours_of(k, particles, surfaces)
            out = follow_particles_across_frames(*surfaces[k], particles[k], entries, weights,
                                                 radius, box=tank)
            return out, vertex_normals(out, surfaces[k][1])

        grids = {}

        def reused(k):
            # the surfaces this frame needs that no earlier frame binned: one a frame in order
            for j in range(-K, K + 1):
                if 0 <= k + j < frames and k + j not in grids:
                    grids[k + j] = TriangleGrid(*surfaces[k + j], radius)
            grids.pop(k - K - 1, None)
            entries, weights = neighbours_of(k, particles, surfaces, grids)
            out = follow_particles_across_frames(*surfaces[k], particles[k], entries, weights,
                                                 radius, box=tank)
            return out, vertex_normals(out, surfaces[k][1])

        def before(k):
            entries, weights = neighbours_of(k, particles, surfaces)
            out = old.follow_particles_across_frames(*surfaces[k], particles[k], entries,
                                                     weights, radius, box=tank)
            return out, old.vertex_normals(out, surfaces[k][1])

        methods = {"filter": today, "filter_grids_reused": reused, "baseline": before}
        for fn in methods.values():  # compile or load every kernel
            fn(0)
        grids.clear()
        times = {name: np.zeros((args.repeats, frames)) for name in methods}
        identical = {"filter": True, "filter_grids_reused": True}
        for r in range(args.repeats):
            for k in range(frames):
                results = {}
                for name, fn in methods.items():
                    t0 = time.perf_counter()
                    results[name] = fn(k)
                    times[name][r, k] = time.perf_counter() - t0
                for name in identical:
                    identical[name] &= all(np.array_equal(a, b) for a, b in
                                           zip(results[name], results["baseline"], strict=True))
            grids.clear()
        pipeline_s, pipeline_old_s = [], []
        for _ in range(args.repeats):
            pipeline_s.append(pipeline_pass(run, particles, radius, tank, tmp / "new"))
            pipeline_old_s.append(pipeline_pass(run, particles, radius, tank, tmp / "old",
                                                old_pass))
        files = sorted((tmp / "new" / "smoothed").glob("*.vtp"))
        old_files = sorted((tmp / "old" / "smoothed").glob("*.vtp"))
        files_identical = len(files) == len(old_files) == frames and all(
            a.read_bytes() == b.read_bytes() for a, b in zip(files, old_files, strict=True))
    per_frame = {name: np.median(t, axis=0) for name, t in times.items()}
    median = {name: float(np.median(v)) for name, v in per_frame.items()}
    result = {
        "benchmark": "across_frames",
        "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                    "numba_threads": numba.get_num_threads(),
                    "load_average_start": list(load_start),
                    "load_average_end": list(os.getloadavg())},
        "frames": frames, "particles": int(particles.shape[1]),
        "vertices_min_max": [min(len(s[0]) for s in surfaces),
                             max(len(s[0]) for s in surfaces)],
        "triangles_max": max(len(s[1]) for s in surfaces),
        "frames_each_side": K, "repeats": args.repeats, "baseline_revision": args.baseline,
        "median_s_per_frame": median,
        "max_of_frame_medians_s": {name: float(v.max()) for name, v in per_frame.items()},
        "mean_s_per_frame": {name: float(v.mean()) for name, v in per_frame.items()},
        "per_frame_median_s": {name: v.round(4).tolist() for name, v in per_frame.items()},
        "vertices_per_frame": [len(s[0]) for s in surfaces],
        "pipeline_pass_s_per_frame": {"median": float(np.median(pipeline_s)),
                                      "all": pipeline_s},
        "pipeline_pass_baseline_s_per_frame": {"median": float(np.median(pipeline_old_s)),
                                               "all": pipeline_old_s},
        "pipeline_pass_speedup": float(np.median(pipeline_old_s) / np.median(pipeline_s)),
        "pipeline_files_identical_to_baseline": bool(files_identical),
        "speedup_vs_baseline": {name: median["baseline"] / median[name]
                                for name in ("filter", "filter_grids_reused")},
        "bitwise_identical_to_baseline": identical,
        "target_s_per_frame": 0.3,
        "target_met": {"filter_grids_reused": median["filter_grids_reused"] <= 0.3,
                       "pipeline_pass": float(np.median(pipeline_s)) <= 0.3},
    }
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(result, indent=2) + "\n")
    for name, v in median.items():
        print(f"{name:22s} {v:7.3f} s a frame (median over {frames} frames)")
    print(f"pipeline pass (reads, filter, writes): {np.median(pipeline_s):.3f} s a frame, "
          f"baseline {np.median(pipeline_old_s):.3f}; files identical: {files_identical}")
    print(f"speed-up vs {args.baseline}: {result['speedup_vs_baseline']}")
    print(f"bitwise identical to {args.baseline}: {identical}")
    print(f"wrote {args.output}")
    return result


if __name__ == "__main__":
    main()
