"""Benchmark: the main job (`blobflow run dam_break`, the Quickstart's first command) end to end.

Runs the command line exactly as a user does, in a fresh process, twice:

* ``cold``: with an empty Numba cache (a new ``NUMBA_CACHE_DIR``, so Numba compiles every
  kernel, as on a fresh clone; the project's own ``__pycache__`` is left alone);
* ``warm``: again with that cache filled by the cold run.

For each it records the wall time of the whole command (simulation, surface, writes, turntable
GIF and MP4), the CPU time of the process and its children, the time at which the progress
bar of the frames reached each phase (from the command's own output: ``frames``, ``turntable``,
``time-lapse``), and checks the outputs (46 particle and surface frames, the GIF and the MP4).
The targets: <= 150 s cold and <= 110 s warm on 2 cores (3 minutes cold before).  Run it alone
on the machine::

    python benchmarks/bench_main_job.py [--repeat N]

Writes ``benchmarks/results/main_job.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results" / "main_job.json"
ROOT = Path(__file__).resolve().parents[1]
#: The command line, run by this interpreter (what the `blobflow` script runs).
BLOBFLOW = [sys.executable, "-m", "pipeline"]


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_once(out: Path, cache: Path) -> dict:
    """One ``blobflow run dam_break`` into ``out`` with Numba's cache in ``cache``."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    if out.exists():
        shutil.rmtree(out)
    cpu0 = _children_cpu()
    start = time.perf_counter()
    proc = subprocess.Popen(BLOBFLOW + ["run", "dam_break", "--out", str(out)], cwd=ROOT,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    phases = {}
    buffer = b""
    while True:
        chunk = proc.stdout.read1(4096)  # what is there, without waiting for 4096 bytes
        if not chunk:
            break
        buffer += chunk
        now = time.perf_counter() - start
        text = buffer.decode(errors="replace")
        for phase, pattern in (("frames", rf"{re.escape(out.name)}:\s+\d"),
                               ("turntable", r"turntable:"), ("time_lapse", r"time-lapse:")):
            if phase not in phases and re.search(pattern, text):
                phases[phase] = round(now, 1)
    proc.wait()
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"blobflow run dam_break exited with {proc.returncode}:\n"
                           + buffer.decode(errors="replace")[-2000:])
    frames = {name: len(list((out / name).glob(f"{name}_*.vtp")))
              for name in ("particles", "surface")}
    renders = {name: (out / name).exists() and (out / name).stat().st_size > 0
               for name in ("turntable.gif", "movie.mp4")}
    if frames != {"particles": 46, "surface": 46} or not all(renders.values()):
        raise RuntimeError(f"incomplete outputs: {frames}, {renders}")
    return {"wall_s": round(wall, 1), "cpu_s": round(_children_cpu() - cpu0, 1),
            "phase_start_s": phases, "frames": frames, "renders": renders}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=1, help="cold + warm pairs (default 1)")
    parser.add_argument("--keep", type=Path, metavar="DIR",
                        help="copy the last run's folder (series, renders) to DIR (replaced), "
                             "e.g. for bench_across_frames.py --run DIR")
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error(f"--repeat must be >= 1 (got {args.repeat})")
    runs = []
    with tempfile.TemporaryDirectory(prefix="blobflow-main-job-") as tmp:
        for k in range(args.repeat):
            cache = Path(tmp) / f"numba-cache-{k}"
            out = Path(tmp) / "dam_break"
            for label in ("cold", "warm"):
                result = run_once(out, cache)
                result["cache"] = label
                runs.append(result)
                print(f"{label}: {result['wall_s']} s wall, {result['cpu_s']} s CPU, "
                      f"phases {result['phase_start_s']}", flush=True)
        if args.keep is not None:
            if args.keep.exists():
                shutil.rmtree(args.keep)
            shutil.copytree(Path(tmp) / "dam_break", args.keep)
    cold = [r["wall_s"] for r in runs if r["cache"] == "cold"]
    warm = [r["wall_s"] for r in runs if r["cache"] == "warm"]
    record = {
        "benchmark": "main_job",
        "command": "blobflow run dam_break",
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                    "usable_cpus": len(os.sched_getaffinity(0)),
                    "python": platform.python_version(),
                    "load_average_before": os.getloadavg()},
        "target": "cold <= 150 s, warm <= 110 s on 2 cores (cold <= 180 s before)",
        "runs": runs,
        "cold_wall_s": {"min": min(cold), "max": max(cold)},
        "warm_wall_s": {"min": min(warm), "max": max(warm)},
    }
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(record, indent=1) + "\n")
    print(f"cold {min(cold)}-{max(cold)} s, warm {min(warm)}-{max(warm)} s -> {RESULTS}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
