"""Benchmark: the pressure frames carry, in a settled column of water, against hydrostatics.

A column 0.1 x 0.1 x 0.2 m (DFSPH, the library's defaults, a closed tank 0.3 m high) starts
with its hydrostatic pressure, settles (:func:`filters.sph.settle.settle`, 1 s of simulated time
with the velocities damped by 5 % per step), and is then written as the pipeline writes frames:
``advance_to`` each frame time at 30 fps, then ``frame()``, for one second.  In every frame the
pressure gradient is fitted by least squares over the particles at least a support radius from
the side walls, the floor and the surface and compared with ``rho0 g``; the criterion of the
issue: within 3 % on average over the frames and 10 % in each.

    python benchmarks/bench_hydrostatic_column.py [--spacings 0.01 0.005]

Writes ``benchmarks/results/hydrostatic_column.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from filters.sph import SPHLiquid  # noqa: E402
from filters.sph.boundary import box_boundary  # noqa: E402
from filters.sph.settle import hydrostatic_pressure, settle  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results" / "hydrostatic_column.json"
WIDTH, HEIGHT, RHO0, G = 0.1, 0.2, 1000.0, 9.81


def gradient(points, pressure, h):
    """``-dp/dz / (rho0 g)`` over the particles a support radius inside the column."""
    z = points[:, 2]
    inner = (np.abs(points[:, :2] - 0.5 * WIDTH) < 0.5 * WIDTH - h).all(axis=1)
    band = inner & (z > h) & (z < z.max() - h)
    A = np.stack([z[band], np.ones(band.sum())], axis=1)
    return -np.linalg.lstsq(A, pressure[band], rcond=None)[0][0] / (RHO0 * G)


def run(spacing: float, frames: int = 30) -> dict:
    axes = [(np.arange(round(n / spacing)) + 0.5) * spacing for n in (WIDTH, WIDTH, HEIGHT)]
    x = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    walls = box_boundary((0, 0, 0), (WIDTH, WIDTH, 0.3), spacing)
    sim = SPHLiquid(x, spacing=spacing, boundary=walls, solver="dfsph",
                    initial_pressure=hydrostatic_pressure(x, spacing))
    t0 = time.perf_counter()
    settle(sim, max_time=1.0, damping=0.05)
    settled = time.perf_counter() - t0
    ratios, speeds = [], []
    for k in range(1, frames + 1):
        sim.advance_to(k / 30)
        f = sim.frame()
        ratios.append(gradient(f.points, f.point_data["pressure"], sim.model.support))
        speeds.append(float(np.sqrt((f.point_data["velocity"] ** 2).sum(axis=1)).max()))
    r = np.array(ratios)
    return {"spacing_m": spacing, "particles": int(x.shape[0]), "settle_wall_s": round(settled, 1),
            "frames": frames, "gradient_over_rho0_g": r.tolist(), "mean": float(r.mean()),
            "worst_frame_error": float(np.abs(r - 1.0).max()),
            "within_3_percent_mean": bool(abs(r.mean() - 1.0) <= 0.03),
            "within_10_percent_each": bool(np.abs(r - 1.0).max() <= 0.10),
            "max_speed_m_s": max(speeds), "container_corrections": int(sim.contained)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--spacings", type=float, nargs="+", default=[0.01, 0.005])
    args = parser.parse_args(argv)
    cases = []
    for s in args.spacings:
        case = run(s)
        cases.append(case)
        print(f"spacing {s * 1000:g} mm: mean {case['mean']:.4f}, worst frame "
              f"{100 * case['worst_frame_error']:.1f} %, max speed {case['max_speed_m_s']:.3f} m/s",
              flush=True)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps({
        "benchmark": "hydrostatic_column", "column_m": [WIDTH, WIDTH, HEIGHT],
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
        "cases": cases}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
