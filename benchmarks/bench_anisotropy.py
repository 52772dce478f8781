"""Flat liquid surfaces: anisotropic kernels (Yu & Turk 2013) vs. isotropic kernels and splashsurf.

One run, side by side on identical particles (spacing s = 0.02 m, particle radius 0.01 m,
cell 0.005 m, SPH kernel of support 4 r, iso 0.6 -- the settings of ``bench_surface.py``; the
anisotropic field uses its default iso 0.55, see ``filters.splat_anisotropic.ANISOTROPIC_ISO``):

* ``pool_lattice``: a resting pool, a 40 x 40 x 10 lattice jittered by +-10 % of s (seed 0);
  the true free surface is the plane half a spacing above the top layer.
* ``pool_sph``: a pool settled by :class:`filters.sph.SPHLiquid` (20 x 20 x 8 particles in a
  closed tank, 1.5 s with viscosity 0.2), when that runs in reasonable time; its true plane is
  the liquid's volume over the tank's floor area (``N s^3 / A`` above the floor).
* ``cube``: a 16^3 lattice cube (jitter +-5 %): sharpness, i.e. how far the reconstructed edges
  and faces deviate from the true cube (the lattice's cells, half a spacing beyond the outer
  particles).
* ``cost``: the 100k jittered block of ``bench_surface.py`` (50 x 50 x 40): time of a whole
  reconstruction (splat + contour; for the anisotropic one also the anisotropy), best of 3,
  alternating.

Methods: ``isotropic`` (``filters.splat.splat_sparse`` + ``contour_sparse``), ``isotropic+smooth``
(the same + ``pipeline.surface.Smooth`` defaults), ``anisotropic``
(``filters.splat_anisotropic.splat_sparse_anisotropic`` + ``contour_sparse``; defaults),
``anisotropic_3s`` (the same with a neighbourhood of 3 spacings instead of 2.5),
``splashsurf_raw`` (``pysplashsurf.reconstruct_surface``, smoothing length 2 r, cube 0.5 r, iso
0.6, float32) and ``splashsurf_smoothed`` (``pysplashsurf.reconstruction_pipeline`` with its
weighted Laplacian smoothing, 25 iterations, Löschner et al. 2023).

Flatness: the vertices of the top face at least 3 s inside the pool's rim; ``rms_plane`` is their
RMS deviation from the true plane, ``rms_flat`` from their own mean (bumpiness), ``offset`` the
mean's height over the true plane, all in spacings.

Run under the shared lock::

    flock /tmp/blobflow-bench.lock env OPENBLAS_NUM_THREADS=1 \\
        /tmp/venv/bin/python benchmarks/bench_anisotropy.py
"""

from __future__ import annotations

import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT.parent))

from filters.splat import splat_sparse  # noqa: E402
from filters.splat_anisotropic import splat_sparse_anisotropic  # noqa: E402
from filters.anisotropy import anisotropic_kernels  # noqa: E402
from filters.surface_mesh import mesh_stats  # noqa: E402

S = 0.02
R = 0.01
CELL = 0.005
ISO = 0.6


def lattice(shape, jitter, seed=0):
    g = np.stack(np.meshgrid(*[np.arange(n) for n in shape], indexing="ij"), -1)
    g = g.reshape(-1, 3).astype(np.float64) * S
    rng = np.random.default_rng(seed)
    return np.ascontiguousarray(g + rng.uniform(-jitter * S, jitter * S, g.shape))


# --------------------------------------------------------------------------------------------
# Methods
# --------------------------------------------------------------------------------------------


def _contour(grid):
    from pipeline.surface import contour_sparse

    return contour_sparse(grid)


def _smooth(points, tris):
    from pipeline.surface import Smooth, mesh_to_polydata, polydata_to_mesh

    s = Smooth()
    s.SetInputDataObject(mesh_to_polydata(points, tris))
    s.Update()
    return polydata_to_mesh(s.GetOutputDataObject(0))


def isotropic(x):
    return _contour(splat_sparse(x, R, CELL, iso=ISO))


def isotropic_smooth(x):
    return _smooth(*isotropic(x))


def anisotropic(x):
    return _contour(splat_sparse_anisotropic(x, R, CELL))


def anisotropic_wide(x):
    return _contour(splat_sparse_anisotropic(x, R, CELL, neighbor_factor=3.0))


def splashsurf_raw(x):
    import pysplashsurf

    rec = pysplashsurf.reconstruct_surface(x.astype(np.float32), particle_radius=R,
                                           smoothing_length=2.0, cube_size=0.5,
                                           iso_surface_threshold=ISO)
    return np.asarray(rec.mesh.vertices, np.float64), np.asarray(rec.mesh.triangles, np.int64)


def splashsurf_smoothed(x):
    import pysplashsurf

    mesh, _ = pysplashsurf.reconstruction_pipeline(
        x.astype(np.float32), particle_radius=R, smoothing_length=2.0, cube_size=0.5,
        iso_surface_threshold=ISO, mesh_smoothing_iters=25, mesh_smoothing_weights=True)
    m = mesh.mesh
    return np.asarray(m.vertices, np.float64), np.asarray(m.triangles, np.int64)


METHODS = {
    "isotropic": isotropic,
    "isotropic+smooth": isotropic_smooth,
    "anisotropic": anisotropic,
    "anisotropic_3s": anisotropic_wide,
    "splashsurf_raw": splashsurf_raw,
    "splashsurf_smoothed": splashsurf_smoothed,
}


# --------------------------------------------------------------------------------------------
# Metrics
# --------------------------------------------------------------------------------------------


def flatness(points, lo_xy, hi_xy, z_true, z_min):
    p = np.asarray(points, np.float64)
    m = ((p[:, 0] > lo_xy[0]) & (p[:, 0] < hi_xy[0]) & (p[:, 1] > lo_xy[1])
         & (p[:, 1] < hi_xy[1]) & (p[:, 2] > z_min))
    z = p[m, 2]
    return {"vertices": int(m.sum()),
            "rms_plane": float(np.sqrt(np.mean((z - z_true) ** 2)) / S),
            "rms_flat": float(np.std(z) / S),
            "offset": float((z.mean() - z_true) / S),
            "max_abs_dev": float(np.abs(z - z.mean()).max() / S)}


def cube_sharpness(points, lo, hi):
    """Deviation of a mesh from the box [lo, hi] (spacings): faces (vertices >= 3 s from any
    edge) and edges (vertices within 3 s of an edge, >= 3 s from its ends)."""
    p = np.asarray(points, np.float64)
    # signed distance to the box (negative inside)
    q = np.abs(p - 0.5 * (lo + hi)) - 0.5 * (hi - lo)
    out = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    inside = np.minimum(q.max(axis=1), 0.0)
    sd = (out + inside) / S
    near = q > -3 * S  # per axis: within 3 s of that pair of faces
    nnear = near.sum(axis=1)
    face = nnear == 1
    edge = nnear == 2
    # edge gap: distance from the true edge to the closest vertex, per 1-cell slab along it
    gaps = []
    for axis in range(3):
        sel = edge & ~near[:, axis]
        if not sel.any():
            continue
        other = [a for a in range(3) if a != axis]
        corner = np.where(p[sel][:, other] > 0.5 * (lo + hi)[other], hi[other], lo[other])
        d = np.linalg.norm(p[sel][:, other] - corner, axis=1)
        sl = np.floor(p[sel][:, axis] / CELL).astype(np.int64)
        key = sl * 4 + (corner[:, 0] == hi[other[0]]) * 2 + (corner[:, 1] == hi[other[1]])
        order = np.lexsort((d, key))
        first = np.r_[True, key[order][1:] != key[order][:-1]]
        gaps.append(d[order][first])
    gaps = np.concatenate(gaps) / S if gaps else np.zeros(1)
    return {"face_rms": float(np.sqrt(np.mean(sd[face] ** 2))),
            "edge_rms": float(np.sqrt(np.mean(sd[edge] ** 2))),
            "edge_max": float(np.abs(sd[edge]).max()),
            "edge_gap_mean": float(gaps.mean()),
            "face_vertices": int(face.sum()), "edge_vertices": int(edge.sum())}


# --------------------------------------------------------------------------------------------
# Cases
# --------------------------------------------------------------------------------------------


def sph_pool(seconds=1.5):
    """A pool settled by SPHLiquid in a closed tank; returns (positions, z_true, lo, hi, info)."""
    from filters.boundary import box_boundary
    from filters.sph import SPHLiquid

    nx, ny, nz = 20, 20, 8
    lower = np.zeros(3)
    upper = np.array([nx * S, ny * S, 0.3])
    g = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"), -1)
    x0 = (g.reshape(-1, 3) + 0.5) * S
    boundary = box_boundary(lower, upper, S)
    sim = SPHLiquid(x0, spacing=S, boundary=boundary, viscosity=0.2)
    t0 = time.perf_counter()
    sim.advance_to(seconds)
    wall = time.perf_counter() - t0
    x = np.ascontiguousarray(sim.state.positions, dtype=np.float64)
    v = np.linalg.norm(sim.state.velocities, axis=1)
    z_true = len(x) * S**3 / (nx * S * ny * S)
    info = {"particles": int(len(x)), "sim_seconds": seconds, "wall_s": wall,
            "max_speed_m_s": float(v.max()), "tank": [nx * S, ny * S],
            "z_true_m": z_true, "z_top_particle_m": float(x[:, 2].max())}
    return x, z_true, info


def best_time(fn, x, repeats=3):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn(x)
        times.append(time.perf_counter() - t0)
    return min(times), times


def main():
    out = {"benchmark": "anisotropy", "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
           "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                       "load_average": list(os.getloadavg())},
           "parameters": {"spacing_m": S, "particle_radius_m": R, "cell_size_m": CELL,
                          "iso": ISO, "kernel": "sph, support 4 r",
                          "anisotropy": "neighbourhood 2.5 s, k_r 4, N_eps 15, lambda 0.9, "
                                        "layer band 1.6 r, max axis 1.6 h, iso 0.55",
                          "splashsurf": "smoothing length 2 r, cube 0.5 r, float32; smoothed: "
                                        "reconstruction_pipeline mesh_smoothing_iters=25, "
                                        "weights on"},
           "flatness": {}, "sharpness": {}, "cost": {}}
    # warm up Numba
    w = lattice((6, 6, 6), 0.1)
    for name, fn in METHODS.items():
        fn(w)
    meshes = {}
    # --- lattice pool
    x = lattice((40, 40, 10), 0.1)
    z_true = 9 * S + 0.5 * S
    lo_xy = np.array([3 * S, 3 * S])
    hi_xy = np.array([36 * S, 36 * S])
    res = {}
    for name, fn in METHODS.items():
        pts, tris = fn(x)
        if name in ("isotropic", "anisotropic"):
            meshes[name] = (pts, tris)
        res[name] = flatness(pts, lo_xy, hi_xy, z_true, z_true - 1.0 * S)
        print("pool_lattice", name, res[name], flush=True)
    out["flatness"]["pool_lattice"] = {"particles": int(len(x)), "methods": res}
    # --- SPH pool
    try:
        xs, zt, info = sph_pool()
        print("sph pool", info, flush=True)
        res = {}
        lo_xy = np.array([3 * S, 3 * S])
        hi_xy = np.array([17 * S, 17 * S])
        for name, fn in METHODS.items():
            pts, tris = fn(xs)
            res[name] = flatness(pts, lo_xy, hi_xy, zt, zt - 1.0 * S)
            print("pool_sph", name, res[name], flush=True)
        out["flatness"]["pool_sph"] = dict(info, methods=res)
    except Exception as exc:  # report, do not hide
        out["flatness"]["pool_sph"] = {"error": f"{type(exc).__name__}: {exc}"}
        print("pool_sph failed:", exc, flush=True)
    # --- cube sharpness
    xc = lattice((16, 16, 16), 0.05, seed=1)
    lo = np.full(3, -0.5 * S)
    hi = np.full(3, 15.5 * S)
    res = {}
    for name, fn in METHODS.items():
        pts, tris = fn(xc)
        st = mesh_stats(pts, tris)
        res[name] = dict(cube_sharpness(pts, lo, hi), volume_error=float(st.volume / (16 * S) ** 3 - 1))
        print("cube", name, res[name], flush=True)
    out["sharpness"]["cube_16"] = {"particles": int(len(xc)), "methods": res}
    # --- cost (100k block, alternating, best of 3)
    xb = lattice((50, 50, 40), 0.1)
    iso_times, ani_times, k_times, wide_times = [], [], [], []
    for _ in range(3):
        iso_times.append(best_time(isotropic, xb, 1)[0])
        ani_times.append(best_time(anisotropic, xb, 1)[0])
        wide_times.append(best_time(anisotropic_wide, xb, 1)[0])
        k_times.append(best_time(lambda y: anisotropic_kernels(y, R, return_volumes=True), xb, 1)[0])
    pool_iso = best_time(isotropic, x, 3)[0]
    pool_ani = best_time(anisotropic, x, 3)[0]
    out["cost"] = {
        "block_100k": {"particles": int(len(xb)), "isotropic_s": min(iso_times),
                       "anisotropic_s": min(ani_times), "anisotropy_only_s": min(k_times),
                       "isotropic_times_s": iso_times, "anisotropic_times_s": ani_times,
                       "ratio": min(ani_times) / min(iso_times),
                       "anisotropic_3s_s": min(wide_times),
                       "ratio_3s": min(wide_times) / min(iso_times)},
        "pool_lattice": {"particles": int(len(x)), "isotropic_s": pool_iso,
                         "anisotropic_s": pool_ani, "ratio": pool_ani / pool_iso},
    }
    print("cost", out["cost"], flush=True)
    results = ROOT / "results"
    results.mkdir(exist_ok=True)
    (results / "anisotropy.json").write_text(json.dumps(out, indent=2))
    render(meshes, results / "anisotropy_flatness.png")
    print("wrote", results / "anisotropy.json", flush=True)


def render(meshes, path):
    """The top of the lattice pool, isotropic and anisotropic, side by side (offscreen)."""
    import pyvista as pv

    pv.OFF_SCREEN = True
    plotter = pv.Plotter(off_screen=True, shape=(1, 2), window_size=(1800, 800))
    for col, name in enumerate(("isotropic", "anisotropic")):
        pts, tris = meshes[name]
        faces = np.hstack([np.full((len(tris), 1), 3), np.asarray(tris)]).astype(np.int64)
        mesh = pv.PolyData(np.asarray(pts, np.float64), faces.ravel())
        mesh = mesh.clip_box([0.1, 0.7, 0.1, 0.7, 0.1, 0.3], invert=False)
        plotter.subplot(0, col)
        plotter.add_text(f"{name} kernels", font_size=14)
        plotter.add_mesh(mesh, color="lightsteelblue", specular=0.6, specular_power=30,
                         smooth_shading=False)
        plotter.camera_position = [(0.05, -0.25, 0.45), (0.4, 0.4, 0.17), (0, 0, 1)]
        plotter.add_light(pv.Light(position=(1.5, 0.4, 0.25), focal_point=(0.4, 0.4, 0.18),
                                   intensity=0.8))
    plotter.screenshot(str(path))
    plotter.close()


if __name__ == "__main__":
    main()
