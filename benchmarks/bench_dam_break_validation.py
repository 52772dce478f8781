"""Validation: the dam break's surge front and residual column against Martin & Moyce (1952).

The column of the ``dam_break`` scene (``a = 0.1 m`` wide, ``2 a`` high, in a tank ``4 a`` long;
DFSPH with the scene's settings) collapses; every 0.05 in ``T = t sqrt(2 g / a)`` up to
``T = 3`` the leading edge of the surge and the height of the liquid at the column's wall are
measured (:mod:`filters.sph.martin_moyce`) and compared with Martin & Moyce's Table 2 (front,
``0.8 <= T <= 3``) and Table 6 (residual height, ``T <= 3``) for ``n^2 = 2``:

* three resolutions: ``a / 10``, ``a / 25`` (the scene's 4 mm) and ``a / 50``;
* two set-ups: **full depth** (the tank ``a`` deep, as the scene) and **quasi-2D** (four
  particles deep between free-slip side walls, as the experiment's two-dimensional flow);
* three wall frictions (the scene's ``wall_friction``): ``all`` (the scene's default: every
  face no-slip with the liquid's kinematic viscosity, 4e-4 m^2/s), ``floor`` (the floor
  no-slip, the walls free-slip) and ``none`` (every face free-slip; the liquid keeps its
  viscosity).  Quasi-2D side walls are free-slip whatever the friction.

Run (heavy: the ``a / 50`` full-depth column has 250,000 particles)::

    python benchmarks/bench_dam_break_validation.py [--divisors 10 25 50] [--setups full quasi2d]
        [--friction all floor none] [--merge OTHER.json ...] [--no-run]

Writes ``benchmarks/results/dam_break_validation.json`` (per case: signed and mean absolute
errors at every table point, particles, steps, wall time, container corrections).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from filters.sph.martin_moyce import (  # noqa: E402
    FRONT_T,
    FRONT_Z,
    column_height,
    compare,
    release_delay,
    surge_front,
)
from filters.sph.scenarios import dam_break_liquid  # noqa: E402
from scenes.dam_break import WALL_FRICTION  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results" / "dam_break_validation.json"
A = 0.1  # m, the dam_break scene's column width
G = 9.81
T_END = 3.0
#: The dam_break scene's liquid settings (scenes/dam_break.py defaults).
SCENE = dict(kinematic_viscosity=4e-4, solver="dfsph", max_density_error=0.001,
             max_iterations=100, cfl=0.4, max_dt=0.005)


def run_case(divisor: int, setup: str, friction: str) -> dict:
    spacing = round(A / divisor, 9)
    depth = A if setup == "full" else 4 * spacing
    slip = WALL_FRICTION[friction]
    if setup == "quasi2d" and "y" not in slip:
        slip = slip + ("y",)
    sim = dam_break_liquid(column_width=A, column_height=2 * A, tank_length=4 * A, depth=depth,
                           tank_height=3 * A, spacing=spacing, free_slip=slip, **SCENE)
    scale = math.sqrt(2.0 * G / A)
    times, fronts, heights = [0.0], [surge_front(sim.state.positions, spacing, depth)], [
        column_height(sim.state.positions, spacing, depth)]
    t0 = time.perf_counter()
    for T in np.arange(0.05, T_END + 1e-9, 0.05):
        t = round(T / scale, 9)
        sim.advance_to(t)  # as the pipeline writes frames
        times.append(t)
        fronts.append(surge_front(sim.state.positions, spacing, depth))
        heights.append(column_height(sim.state.positions, spacing, depth))
    wall = time.perf_counter() - t0
    result = compare(times, fronts, heights, A, G, (0.8, T_END))
    _add_front_diagnostics(result, times, fronts)
    result.update(divisor=divisor, spacing_m=spacing, setup=setup, friction=friction,
                  particles=int(sim.state.n_points), steps=int(sim.steps_taken),
                  wall_s=round(wall, 1),
                  container_corrections=int(sim.contained),
                  front_Z=(np.asarray(fronts) / A).tolist(),
                  height_H=(np.asarray(heights) / (2 * A)).tolist(),
                  T=(np.asarray(times) * scale).tolist())
    return result


def _add_front_diagnostics(case: dict, times, fronts) -> None:
    """What the front's error is made of: the release delay that best explains it (see
    :func:`filters.sph.martin_moyce.release_delay`) and the front's late speed, ``dZ / dT``
    from ``T`` = 1.98 to 2.98 over Table 2's (a front that left early but runs at the
    experiment's speed has a ratio of 1)."""
    delay, err = release_delay(times, fronts, A, G, (0.8, T_END))
    T = np.asarray(times) * math.sqrt(2.0 * G / A)
    late = [6, 12]  # Table 2's points at T = 1.98 and 2.98
    z = np.interp(FRONT_T[late], T, np.asarray(fronts) / A)
    ratio = float((z[1] - z[0]) / (FRONT_Z[12] - FRONT_Z[6]))
    case.update(release_delay_T=delay, front_mean_abs_after_delay=err,
                front_late_speed_ratio=ratio)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--divisors", type=int, nargs="+", default=[10, 25, 50],
                        help="resolutions a / d (default 10 25 50)")
    parser.add_argument("--setups", nargs="+", default=["full", "quasi2d"],
                        choices=["full", "quasi2d"])
    parser.add_argument("--friction", nargs="+", default=list(WALL_FRICTION),
                        choices=list(WALL_FRICTION))
    parser.add_argument("--merge", metavar="JSON", nargs="+", default=[],
                        help="take the cases of these results files (runs made elsewhere)")
    parser.add_argument("--no-run", action="store_true",
                        help="run nothing: rewrite the results (merged, figures recomputed)")
    args = parser.parse_args(argv)
    if min(args.divisors) < 4:
        parser.error("--divisors must be >= 4")
    old = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    for path in args.merge:
        old.setdefault("cases", []).extend(json.loads(Path(path).read_text())["cases"])
    cases = {}
    for c in old.get("cases", []):  # results from before wall_friction named them: on / off
        if isinstance(c["friction"], bool):
            c["friction"] = "all" if c["friction"] else "none"
            c["key"] = f"{c['setup']}_a{c['divisor']}_friction_{c['friction']}"
        if "front_late_speed_ratio" not in c:  # from the stored samples, no rerun
            scale = math.sqrt(2.0 * G / A)
            _add_front_diagnostics(c, np.asarray(c["T"]) / scale, np.asarray(c["front_Z"]) * A)
        cases[c["key"]] = c
    for setup in args.setups if not args.no_run else []:
        for friction in args.friction:
            for d in args.divisors:
                key = f"{setup}_a{d}_friction_{friction}"
                print(f"--- {key}", flush=True)
                case = run_case(d, setup, friction)
                case["key"] = key
                cases[key] = case
                print(f"front mean |error| {100 * case['front_mean_abs']:.1f} % (signed "
                      f"{100 * case['front_mean']:+.1f} %), height "
                      f"{100 * case['height_mean_abs']:.1f}"
                      f" % ({100 * case['height_mean']:+.1f} %); {case['particles']} particles, "
                      f"{case['steps']} steps, {case['wall_s']} s, front "
                      f"{100 * case['front_mean_abs_after_delay']:.1f} % after a release delay "
                      f"of {case['release_delay_T']:.2f} in T, late speed "
                      f"{case['front_late_speed_ratio']:.3f} of the experiment's, "
                      f"{case['container_corrections']} container corrections", flush=True)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps({
        "benchmark": "dam_break_validation", "reference": "Martin & Moyce (1952), n^2 = 2",
        "column_width_m": A, "T_end": T_END,
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
        "cases": sorted(cases.values(), key=lambda c: c["key"])}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
