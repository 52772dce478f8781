"""Benchmark: the dam break refined, default spacing down to a quarter of it, through the impact.

The issue's requirement: ``blobflow run dam_break`` never stops on a density-error guard or an
instability at default parameters with the spacing anywhere from the default (4 mm, 31,250
particles) down to a quarter of it (1 mm, 2,000,000 particles).  For each spacing this runs the
command line (particles only: ``--set surface=false --no-render``) for ``--duration`` seconds
(0.6 s by default: the front hits the far wall at about 0.25 s, runs up it and falls back), then
reads every frame back and records, per frame, the mean compression ``mean(max(rho / rho0 - 1,
0))`` and the worst particle's, the largest speed, the tank's safety net's corrections so far
(the field ``container_corrections``: 0 while the walls hold by themselves), and the wall time
per simulated second.

A run folder that already holds a complete series of the same parameters is read, not rerun
(``--runs DIR``, default ``outputs/refinement``; its wall time is kept beside it in
``bench_refinement_timing.json``): the quarter-spacing run takes hours here.  With
``--read-partial`` a run that stopped short of the duration (killed, or resumed in pieces with
``blobflow run ... --resume``) is read as far as it got; its timing file then says how it ran.

    python benchmarks/bench_refinement.py [--divisors 1 2 4] [--duration 0.6]

Writes ``benchmarks/results/refinement.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results" / "refinement.json"
ROOT = Path(__file__).resolve().parents[1]
#: The command line, run by this interpreter (what the `blobflow` script runs).
BLOBFLOW = [sys.executable, "-m", "pipeline"]
DEFAULT_SPACING = 0.004
REST_DENSITY = 1000.0
#: Kept in each run folder: the wall time and exit code of the run that wrote it.
TIMING_FILE = "bench_refinement_timing.json"


def _written_to(folder: Path, spacing: float) -> float | None:
    """The last frame time of a dam break at ``spacing`` in ``folder`` (None: no such run)."""
    record, pvd = folder / "scene.json", folder / "particles.pvd"
    if not (record.exists() and pvd.exists()):
        return None
    params = json.loads(record.read_text())["parameters"]
    if params.get("spacing") != spacing or params.get("surface"):
        return None
    from pipeline.io.series import read_collection

    entries = read_collection(pvd)
    return entries[-1][0] if entries else None


def _complete(folder: Path, spacing: float, duration: float) -> bool:
    """Whether ``folder`` holds a finished run of the dam break at ``spacing`` to ``duration``."""
    last = _written_to(folder, spacing)
    return last is not None and abs(last - duration) < 1e-9


def analyse(folder: Path) -> list[dict]:
    """Per frame: time, particle count, the container corrections so far (the safety net),
    mean and worst compression, largest speed."""
    from vtkmodules.util import numpy_support

    from pipeline.io.series import read_collection, read_frame

    rows = []
    for t, name in read_collection(folder / "particles.pvd"):
        data = read_frame(folder / name)
        pd = data.GetPointData()
        rho = numpy_support.vtk_to_numpy(pd.GetArray("density"))
        v = numpy_support.vtk_to_numpy(pd.GetArray("velocity"))
        compression = np.maximum(rho / REST_DENSITY - 1.0, 0.0)
        fixed = data.GetFieldData().GetArray("container_corrections")
        rows.append({"time": t, "particles": int(rho.size),
                     "container_corrections": (int(numpy_support.vtk_to_numpy(fixed)[0])
                                               if fixed is not None else None),
                     "mean_compression": float(compression.mean()),
                     "worst_compression": float(compression.max()),
                     "max_speed": float(np.sqrt((v * v).sum(axis=1)).max()),
                     "finite": bool(np.isfinite(v).all() and np.isfinite(rho).all())})
    return rows


def run(folder: Path, spacing: float, duration: float) -> dict:
    cmd = BLOBFLOW + ["run", "dam_break", "--set", f"spacing={spacing}", "--set",
                         "surface=false", "--duration", str(duration), "--no-render", "--quiet",
                         "--out", str(folder)]
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - start
    return {"exit_code": proc.returncode, "wall_s": round(wall, 1),
            "message": (proc.stderr.strip().splitlines() or [""])[-1]}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--divisors", type=int, nargs="+", default=[1, 2, 4],
                        help="spacings as the default divided by these (default 1 2 4)")
    parser.add_argument("--duration", type=float, default=0.6, help="simulated s (default 0.6)")
    parser.add_argument("--runs", default=str(ROOT / "outputs" / "refinement"),
                        help="folder of the runs (kept; complete ones are read, not rerun)")
    parser.add_argument("--read-partial", action="store_true",
                        help="read a run that stopped short of --duration as far as it got "
                             "instead of rerunning it (its timing file says how it stopped)")
    args = parser.parse_args(argv)
    if min(args.divisors) < 1:
        parser.error(f"--divisors must be whole numbers >= 1 (got {args.divisors})")
    if not args.duration > 0:
        parser.error(f"--duration must be > 0 s (got {args.duration})")
    cases = []
    for d in args.divisors:
        spacing = round(DEFAULT_SPACING / d, 9)
        folder = Path(args.runs) / f"spacing_{spacing * 1000:g}mm"
        timing = folder / TIMING_FILE
        if _complete(folder, spacing, args.duration):
            outcome = {"exit_code": 0, "wall_s": None, "message": "read from an earlier run"}
            if timing.exists():  # the earlier run's own measurement
                outcome.update(json.loads(timing.read_text()), message="read from an earlier run")
        elif args.read_partial and (last := _written_to(folder, spacing)) is not None:
            outcome = {"exit_code": None, "wall_s": None,
                       "message": f"partial run read to t = {last:g} s"}
            if timing.exists():
                outcome.update(json.loads(timing.read_text()))
        else:
            outcome = run(folder, spacing, args.duration)
            folder.mkdir(parents=True, exist_ok=True)
            timing.write_text(json.dumps(outcome) + "\n")
        frames = analyse(folder) if (folder / "particles.pvd").exists() else []
        case = {"spacing_m": spacing, "divisor": d, **outcome,
                "particles": frames[0]["particles"] if frames else None,
                "frames": frames,
                "mean_compression_max": max((f["mean_compression"] for f in frames), default=None),
                "worst_compression_max": max((f["worst_compression"] for f in frames),
                                             default=None)}
        if outcome["wall_s"] is not None and frames:
            case["wall_s_per_simulated_s"] = round(outcome["wall_s"] / frames[-1]["time"], 1)
        cases.append(case)
        print(f"spacing {spacing * 1000:g} mm: exit {case['exit_code']}, "
              f"{len(frames)} frames to t = {frames[-1]['time'] if frames else 0} s, mean "
              f"compression <= {case['mean_compression_max']}, worst particle <= "
              f"{case['worst_compression_max']}", flush=True)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps({
        "benchmark": "refinement", "scene": "dam_break (defaults, surface=false)",
        "duration_s": args.duration,
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                    "python": platform.python_version()},
        "cases": cases}, indent=1) + "\n")
    return 0 if all(c["exit_code"] in (0, None) for c in cases) else 1


if __name__ == "__main__":
    sys.exit(main())
