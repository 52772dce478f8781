"""What ``import pipeline`` and ``import filters`` cost: wall time and peak memory of a fresh
interpreter, and which heavy packages the import loads.

Each measurement is a new ``python -c`` process (nothing cached in the interpreter; the
operating system's file cache warm after the first repeat) that times the import with
``time.perf_counter`` and reads its own peak resident memory (``resource.getrusage``,
``ru_maxrss``). The peak includes the interpreter itself, measured alone as ``python`` (no
import). The same runs are made on a baseline tree (by default the ``main`` checkout, whose
packages import eagerly) side by side, interleaved repeat by repeat, so that the machine's load
falls on both alike.

Usage::

    flock /tmp/blobflow-heavy.lock python benchmarks/bench_import.py [--repeats 7]
        [--baseline /work/main] [--out benchmarks/results/import.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: What is imported: the packages, and the first use of a name (loads VTK and the surface).
CASES = {
    "python": "",
    "import filters": "import filters",
    "import pipeline": "import pipeline",
    "import pipeline; pipeline.Flow": "import pipeline; pipeline.Flow",
}
#: Packages whose presence in ``sys.modules`` after the import is recorded.
HEAVY = ("numpy", "numba", "vtkmodules", "pyvista", "scipy", "meshio", "tqdm")

_PROBE = """
import json, resource, sys, time
start = time.perf_counter()
{code}
seconds = time.perf_counter() - start
print(json.dumps({{"seconds": seconds,
                   "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                   "loaded": [m for m in {heavy!r} if m in sys.modules]}}))
"""


def measure(tree: Path, code: str) -> dict:
    """One fresh interpreter importing with ``tree`` first on the path."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    result = subprocess.run([sys.executable, "-c", _PROBE.format(code=code, heavy=HEAVY)],
                            cwd=tree, env=env, capture_output=True, text=True, check=True)
    return json.loads(result.stdout.strip().splitlines()[-1])


def summary(runs: list[dict]) -> dict:
    return {"median_seconds": statistics.median(r["seconds"] for r in runs),
            "max_seconds": max(r["seconds"] for r in runs),
            "median_peak_rss_mb": statistics.median(r["peak_rss_mb"] for r in runs),
            "max_peak_rss_mb": max(r["peak_rss_mb"] for r in runs),
            "loaded": runs[-1]["loaded"], "repeats": len(runs)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--baseline", type=Path, default=Path("/work/main"),
                        help="a checkout to compare with (its own packages on the path)")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks/results/import.json")
    args = parser.parse_args(argv)
    trees = {"this tree": ROOT}
    if args.baseline and args.baseline.resolve() != ROOT and args.baseline.is_dir():
        trees["baseline"] = args.baseline.resolve()
    runs = {t: {c: [] for c in CASES} for t in trees}
    for _ in range(args.repeats):
        for case, code in CASES.items():
            for tree, path in trees.items():  # interleaved: the same load on both
                runs[tree][case].append(measure(path, code))
    results = {tree: {case: summary(r) for case, r in cases.items()}
               for tree, cases in runs.items()}
    commits = {t: subprocess.run(["git", "rev-parse", "HEAD"], cwd=p, capture_output=True,
                                 text=True).stdout.strip() for t, p in trees.items()}
    record = {"python": platform.python_version(), "machine": platform.machine(),
              "trees": {t: str(p) for t, p in trees.items()}, "commits": commits,
              "results": results}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
    for tree, cases in results.items():
        for case, s in cases.items():
            print(f"{tree:>9}  {case:<32} {s['median_seconds']:7.3f} s "
                  f"{s['median_peak_rss_mb']:7.1f} MB  {', '.join(s['loaded']) or '-'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
