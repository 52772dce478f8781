"""Benchmark: a floating box side by side with Genesis (genesis-world), draft and cost.

One box 0.1 x 0.1 x 0.05 m of 500 kg/m^3 released 5 mm above a pool 0.3 x 0.2 m and 12 cm deep
(1 cm particles, 7,200 of them) in a closed tank; after 1.5 s simulated: the box's draft over
its Archimedes draft (half its height), measured from the mean top of the water columns away
from the box plus half a spacing, and the wall seconds per simulated second.  blobflow: DFSPH,
the box a :class:`filters.rigid.RigidBodies` body coupled by :class:`filters.coupling.Coupled`,
one thread.  Genesis: its SPH solver and a rigid box (``gs.materials.Rigid(rho=500)``) on its
CPU backend, run by the Python that has it installed (``--genesis-python``; Genesis and its
torch need a virtual environment of their own, 8.5 GB here), its settings read back from the
built scene.

    python benchmarks/bench_floating_genesis.py --genesis-python /path/to/venv/bin/python

Writes ``benchmarks/results/floating_genesis.json``.
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

import numba
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from filters.coupling import Coupled, coupled_boundary  # noqa: E402
from filters.elastic.contact import Colliders  # noqa: E402
from filters.geometry import Box  # noqa: E402
from filters.rigid import RigidBodies, RigidBody  # noqa: E402
from filters.rigid.meshes import box_mesh  # noqa: E402
from filters.sph import SPHLiquid  # noqa: E402
from filters.sph.boundary import box_boundary  # noqa: E402
from filters.sph.settle import hydrostatic_pressure  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results" / "floating_genesis.json"
S, TANK, DEPTH, BOX, RHO_BOX, T = 0.01, (0.3, 0.2, 0.3), 0.12, (0.1, 0.1, 0.05), 500.0, 1.5
CENTER = (0.15, 0.1, DEPTH + BOX[2] / 2 + 0.005)


def level_and_draft(x, center):
    """Mean top of the water columns away from the box (+ s/2) and the box's draft over
    Archimedes'."""
    far = np.max(np.abs(x[:, :2] - center[:2]), axis=1) > BOX[0] / 2 + 2 * S
    key = np.floor(x[far, :2] / S).astype(np.int64)
    key = key[:, 0] * 1_000_000 + key[:, 1]
    z = x[far, 2]
    order = np.lexsort((z, key))
    last = np.r_[key[order][1:] != key[order][:-1], True]
    level = float(z[order][last].mean()) + S / 2
    return level, (level - (center[2] - BOX[2] / 2)) / (BOX[2] * RHO_BOX / 1000.0)


def blobflow() -> dict:
    numba.set_num_threads(1)
    v, f = box_mesh(BOX, CENTER)
    bodies = RigidBodies([RigidBody(v, f, density=RHO_BOX)],
                         colliders=Colliders().add(~Box((0, 0, 0), TANK)))
    axes = [(np.arange(int(round(n / S))) + 0.5) * S for n in (TANK[0], TANK[1], DEPTH)]
    x = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    walls = box_boundary((0, 0, 0), TANK, S)
    liquid = SPHLiquid(x, spacing=S, boundary=coupled_boundary(walls, bodies, S),
                       solver="dfsph", initial_pressure=hydrostatic_pressure(x, S),
                       kinematic_viscosity=1e-4, max_dt=0.005, container=((0, 0, 0), TANK))
    sim = Coupled(liquid, bodies)
    sim.advance_to(0.01)  # compiled
    t0 = time.perf_counter()
    sim.advance_to(T)
    wall = time.perf_counter() - t0
    c = bodies.state.positions[0]
    level, ratio = level_and_draft(liquid.state.positions, c)
    m = liquid.model
    return {"particles": int(x.shape[0]), "wall_s": round(wall, 2),
            "wall_s_per_simulated_s": round(wall / (T - 0.01), 2), "box_z_m": float(c[2]),
            "level_m": level, "draft_over_archimedes": round(ratio, 4), "threads": 1,
            "settings": {"solver": m.solver, "spacing": m.spacing,
                         "max_density_error": m.max_density_error, "cfl": m.cfl,
                         "max_dt": m.max_dt, "steps": sim.steps_taken}}


GENESIS = r'''
import json, sys, time
import numpy as np
import genesis as gs
S, TANK, DEPTH, BOX, RHO, T, C = json.loads(sys.argv[1])
gs.init(backend=gs.cpu, logging_level="warning")
dt, sub = 4e-3, 10
scene = gs.Scene(sim_options=gs.options.SimOptions(dt=dt, substeps=sub),
                 sph_options=gs.options.SPHOptions(lower_bound=(0, 0, 0), upper_bound=TANK,
                                                   particle_size=S), show_viewer=False)
water = scene.add_entity(material=gs.materials.SPH.Liquid(),
                         morph=gs.morphs.Box(lower=(0, 0, 0), upper=(TANK[0], TANK[1], DEPTH)))
box = scene.add_entity(material=gs.materials.Rigid(rho=RHO), morph=gs.morphs.Box(pos=C, size=BOX))
scene.build()
sph = scene.sim.sph_solver
settings = {"dt": scene.sim.dt, "substeps": scene.sim.substeps}
for k in ("particle_size", "pressure_solver"):
    for name in (k, "_" + k):
        if hasattr(sph, name):
            settings[k] = str(getattr(sph, name))
            break
scene.step()
t0 = time.perf_counter()
for i in range(int(round(T / dt)) - 1):
    scene.step()
wall = time.perf_counter() - t0
x = water.get_particles_pos().cpu().numpy().reshape(-1, 3)
print(json.dumps({"wall_s": wall, "simulated_s": T - dt, "x": x.tolist(),
                  "box": box.get_pos().cpu().numpy().ravel().tolist(), "settings": settings}))
'''


def genesis(python: str) -> dict:
    args = json.dumps([S, TANK, DEPTH, BOX, RHO_BOX, T, CENTER])
    out = subprocess.run([python, "-c", GENESIS, args], capture_output=True, text=True,
                         timeout=3600)
    if out.returncode != 0:
        return {"error": out.stderr[-2000:]}
    r = json.loads(out.stdout.strip().splitlines()[-1])
    x = np.asarray(r.pop("x"))
    c = np.asarray(r["box"])
    level, ratio = level_and_draft(x, c)
    return {"particles": int(x.shape[0]), "wall_s": round(r["wall_s"], 2),
            "wall_s_per_simulated_s": round(r["wall_s"] / r["simulated_s"], 2),
            "box_z_m": float(c[2]), "level_m": level, "draft_over_archimedes": round(ratio, 4),
            "settings": r["settings"], "threads": "its CPU backend's default"}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--genesis-python", required=True,
                        help="the Python of a virtual environment with genesis-world and torch")
    args = parser.parse_args(argv)
    result = {"benchmark": "floating_genesis", "tank_m": TANK, "depth_m": DEPTH, "box_m": BOX,
              "box_density": RHO_BOX, "simulated_s": T, "spacing_m": S,
              "blobflow": blobflow(), "genesis": genesis(args.genesis_python),
              "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                          "load_average": os.getloadavg()}}
    print(json.dumps(result, indent=1))
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
