"""The liquid's volume over the dam break: where ``sum(m / rho)`` drifts and where it does not.

The ``dam_break`` scene (DFSPH, its defaults: 31,250 particles) runs for 1.5 s; every 0.1 s the
frame's densities (as written, by summation at the frame's positions) give

* ``sum(m / rho)`` over all particles, against the rest volume ``N m / rho0``;
* the same over the **interior** particles, those whose kernel support holds at least as many
  fluid and boundary particles as a particle deep inside the resting lattice: there the
  summation density measures compression or expansion, not a missing neighbourhood;
* the fraction of the particles that are not interior (the free surface, drops, sheets);
* the mean compression ``mean max(rho / rho0 - 1, 0)`` that the density solve bounds.

A particle at the free surface lacks neighbours, so its summed density is below ``rho0`` and its
``m / rho`` above its rest volume whatever the solver does; ``sum(m / rho)`` over all particles
therefore follows the area of the free surface.

Run::

    python benchmarks/bench_volume.py [--spacing 0.004] [--duration 1.5]

Writes ``benchmarks/results/volume.json``.
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
from scipy.spatial import cKDTree

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from scenes.dam_break import build  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results" / "volume.json"


def full_count(spacing: float, support: float) -> int:
    """Particles (itself included) within ``support`` of a particle of the lattice of
    ``spacing``: the count of a complete neighbourhood."""
    reach = int(np.ceil(support / spacing)) + 1
    g = np.arange(-reach, reach + 1) * spacing
    lattice = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    return int((np.linalg.norm(lattice, axis=1) < support).sum())


def measure(positions, density, boundary_tree, support, mass, rho0, full) -> dict:
    """The volume figures of one frame (see the module docstring)."""
    tree = cKDTree(positions)
    count = (tree.query_ball_point(positions, support, return_length=True)
             + boundary_tree.query_ball_point(positions, support, return_length=True))
    interior = count >= full
    rest = mass / rho0
    n = positions.shape[0]
    return {"volume_error": float((mass / density).sum() / (n * rest) - 1.0),
            "interior_volume_error": float((mass / density[interior]).sum()
                                           / (interior.sum() * rest) - 1.0),
            "interior_particles": int(interior.sum()),
            "surface_fraction": float(1.0 - interior.mean()),
            "mean_compression": float(np.maximum(density / rho0 - 1.0, 0.0).mean())}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--spacing", type=float, default=0.004, help="particle spacing (m)")
    parser.add_argument("--duration", type=float, default=1.5, help="simulated time (s)")
    args = parser.parse_args(argv)
    if not (0.001 <= args.spacing <= 0.05):
        parser.error("--spacing must be in [0.001, 0.05] m")
    if not (0.0 < args.duration <= 10.0):
        parser.error("--duration must be in (0, 10] s")
    sim = build(spacing=args.spacing, surface=False).source.simulation
    model = sim.model
    rho0 = model.rest_density
    full = full_count(model.spacing, model.support)
    boundary = cKDTree(model.boundary_points)
    frames = []
    t0 = time.perf_counter()
    for t in np.arange(0.0, args.duration + 1e-9, 0.1):
        sim.advance_to(float(t))
        frame = sim.frame()
        row = {"t": round(float(t), 6), **measure(frame.points, frame.point_data["density"],
                                                  boundary, model.support, model.mass, rho0,
                                                  full)}
        frames.append(row)
        print(f"t = {t:.2f} s: sum(m/rho) {100 * row['volume_error']:+.3f} %, interior "
              f"{100 * row['interior_volume_error']:+.3f} % ({row['interior_particles']} "
              f"particles), not interior {100 * row['surface_fraction']:.1f} %, mean "
              f"compression {100 * row['mean_compression']:.3f} %", flush=True)
    interior = [f["interior_volume_error"] for f in frames]
    summary = {
        "volume_error_start_end": [frames[0]["volume_error"], frames[-1]["volume_error"]],
        "volume_error_range": [min(f["volume_error"] for f in frames),
                               max(f["volume_error"] for f in frames)],
        "interior_volume_error_range": [min(interior), max(interior)],
        "interior_drift_start_to_end": interior[-1] - interior[0],
        "correlation_volume_error_surface_fraction": float(np.corrcoef(
            [f["volume_error"] for f in frames], [f["surface_fraction"] for f in frames])[0, 1]),
    }
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps({
        "benchmark": "volume", "scene": "dam_break", "spacing_m": model.spacing,
        "particles": int(sim.state.n_points), "full_neighbourhood": full,
        "wall_s": round(time.perf_counter() - t0, 1),
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
        "summary": summary, "frames": frames}, indent=1) + "\n")
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
