"""Flat liquid surfaces: anisotropic kernels (Yu & Turk 2013) vs. isotropic kernels and splashsurf.

The flatness / sharpness / cost benchmark, one run, side by side on identical particles
(spacing s = 0.02 m, particle radius 0.01 m, cell 0.005 m, SPH kernel of support 4 r, iso 0.6 --
the settings of ``bench_surface.py``; the anisotropic field raises the amplitudes of stretched
kernels instead of lowering its iso, see ``filters.surface.volumes.stretched_gain``).
``bench_surface.py --flatness`` calls :func:`run_flatness`; this file also runs alone.

Cases:

* ``pool_lattice``: a resting pool, a 40 x 40 x 10 lattice jittered by +-10 % of s (seed 0).
* ``pool_sph``: a pool settled by :class:`filters.sph.SPHLiquid` (20 x 20 x 8 particles in a
  closed tank, 1.5 s with viscosity 0.2).
* ``pool_sph_40``: the same with 40 x 40 x 10 particles, the lattice pool's size (about a
  minute to settle): the smoothing stages reach less of its measured region from the rim.
* ``cube_16``: a 16^3 lattice cube (jitter +-5 %, seed 1): sharpness, i.e. how far the
  reconstructed faces and edges deviate from the true cube (the lattice's cells, half a spacing
  beyond the outer particles), and the volume error.
* ``cost``: the 100k jittered block of ``bench_surface.py`` (50 x 50 x 40) and the lattice pool:
  wall time of a whole reconstruction (splat + contour; for the anisotropic one the anisotropy
  is included), best of 5, isotropic and anisotropic alternating in the same process, same
  particles, cell size and sparse grid; also with the ``Smooth`` stage for both.

The true plane of both pools is defined the same way: **half a (nominal) spacing above the mean
height of the top particle layer** (the particles of the pool's inner region within half a
spacing of the highest one). For the lattice that is the plane half a spacing above the top
layer, where the lattice's cells end; for the SPH pool it follows the settled particles rather
than the initial volume (the weakly compressible solver leaves the column 0.2 spacings lower
than ``N s^3 / A``, and its layers closer than s near the top).

Methods: ``isotropic`` (``filters.surface.splat.splat_sparse`` + ``contour_sparse``),
``isotropic+smooth`` (the same + ``pipeline.surface.Smooth`` defaults: windowed sinc, 100
iterations, pass band 0.001), ``anisotropic`` (``filters.surface.splat.splat_sparse_anisotropic``
defaults + ``contour_sparse``), ``anisotropic+smooth`` (the same + ``Smooth`` defaults),
``isotropic+feature`` / ``anisotropic+feature`` (+ 25 sweeps of feature-weighted Laplacian
smoothing, :func:`filters.surface.smoothing.smooth_surface`, the ``MarchingCubes`` option),
``splashsurf_raw`` (``pysplashsurf.reconstruct_surface``, smoothing length 2 r, cube 0.5 r, iso
0.6, float32) and ``splashsurf_smoothed`` (``pysplashsurf.reconstruction_pipeline`` with its
weighted Laplacian mesh smoothing, 25 iterations, Löschner et al. 2023). Per pool also
``scene_pipeline``: the surface ``dam_break`` and ``drop`` write (:func:`scene_surface`),
isotropic and anisotropic. ``ball_volume``: the volume error of every method on jittered lattice
balls of radius 2, 3, 4 and 6 spacings (what smoothing costs drops).

Flatness: the vertices of the top face at least 3 s inside the pool's rim; ``rms_plane`` is their
RMS deviation from the true plane, ``rms_flat`` from their own mean (bumpiness), ``offset`` the
mean's height over the true plane, ``max_abs_dev`` the largest deviation from the mean, all in
spacings.

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
RESULTS = ROOT / "results"
if str(ROOT.parent) not in sys.path:
    sys.path.insert(0, str(ROOT.parent))

from filters.surface.anisotropy import DEFAULTS as ANISO_DEFAULTS  # noqa: E402
from filters.surface.anisotropy import anisotropic_kernels  # noqa: E402
from filters.surface.ellipsoids import ANISOTROPIC_ISO  # noqa: E402
from filters.surface.mesh import mesh_stats  # noqa: E402
from filters.surface.splat import splat_sparse, splat_sparse_anisotropic  # noqa: E402
from filters.surface.volumes import STRETCHED_GAIN  # noqa: E402

S = 0.02
R = 0.01
CELL = 0.005
ISO = 0.6
TARGET_RMS = 0.05
TARGET_COST = 1.5


def lattice(shape, jitter, seed=0):
    """A jittered lattice of spacing ``S`` ((N, 3) float64, m), corner at the origin."""
    g = np.stack(np.meshgrid(*[np.arange(n) for n in shape], indexing="ij"), -1)
    g = g.reshape(-1, 3).astype(np.float64) * S
    rng = np.random.default_rng(seed)
    return np.ascontiguousarray(g + rng.uniform(-jitter * S, jitter * S, g.shape))


def ball(radius, jitter=0.05, seed=0):
    """Lattice points within ``radius`` spacings of a point off the lattice, jittered."""
    n = radius + 2
    g = np.stack(np.meshgrid(*[np.arange(-n, n + 1)] * 3, indexing="ij"), -1).reshape(-1, 3) * S
    g = g[np.linalg.norm(g - 0.1 * S, axis=1) < radius * S]
    rng = np.random.default_rng(seed)
    return np.ascontiguousarray(g + rng.uniform(-jitter * S, jitter * S, g.shape))


# --------------------------------------------------------------------------------------------
# Methods
# --------------------------------------------------------------------------------------------


def _contour(grid):
    from pipeline.surface.contour import contour_sparse

    return contour_sparse(grid)


def _smooth(points, tris):
    from pipeline.surface import Smooth
    from pipeline.surface.contour import mesh_to_polydata, polydata_to_mesh

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


def anisotropic_smooth(x):
    return _smooth(*anisotropic(x))


def _feature(x, points, tris):
    from filters.surface.smoothing import smooth_surface

    return smooth_surface(points, tris, x, R), tris


def isotropic_feature(x):
    return _feature(x, *isotropic(x))


def anisotropic_feature(x):
    return _feature(x, *anisotropic(x))


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
    "anisotropic+smooth": anisotropic_smooth,
    "isotropic+feature": isotropic_feature,
    "anisotropic+feature": anisotropic_feature,
    "splashsurf_raw": splashsurf_raw,
    "splashsurf_smoothed": splashsurf_smoothed,
}
SPLASHSURF = ("splashsurf_raw", "splashsurf_smoothed")


# --------------------------------------------------------------------------------------------
# Metrics
# --------------------------------------------------------------------------------------------


def true_plane(x, lo_xy, hi_xy):
    """Height (m) of the true free surface of a resting pool: half a nominal spacing above the
    mean height of the top particle layer (the particles inside ``lo_xy .. hi_xy`` within half a
    spacing of the highest of them); also returns that layer's particle count."""
    x = np.asarray(x, np.float64)
    m = ((x[:, 0] > lo_xy[0]) & (x[:, 0] < hi_xy[0]) & (x[:, 1] > lo_xy[1])
         & (x[:, 1] < hi_xy[1]))
    z = x[m, 2]
    top = z > z.max() - 0.5 * S
    return float(z[top].mean() + 0.5 * S), int(top.sum())


def flatness(points, lo_xy, hi_xy, z_true):
    """RMS deviations (spacings) of a mesh's top-face vertices inside ``lo_xy .. hi_xy``."""
    p = np.asarray(points, np.float64)
    m = ((p[:, 0] > lo_xy[0]) & (p[:, 0] < hi_xy[0]) & (p[:, 1] > lo_xy[1])
         & (p[:, 1] < hi_xy[1]) & (p[:, 2] > z_true - 1.0 * S))
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


def sph_pool(seconds=1.5, shape=(20, 20, 8)):
    """A pool of ``shape`` particles settled by SPHLiquid in a closed tank that it fills
    horizontally; returns (positions, info)."""
    from filters.sph import SPHLiquid
    from filters.sph.boundary import box_boundary

    nx, ny, nz = shape
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
    info = {"particles": int(len(x)), "sim_seconds": seconds, "wall_s": wall,
            "max_speed_m_s": float(v.max()), "tank_m": [nx * S, ny * S],
            "z_initial_volume_m": len(x) * S**3 / (nx * S * ny * S)}
    return x, info


def scene_surface(x, tank_lo, tank_hi, anisotropic):
    """The surface the liquid scenes build (:func:`pipeline.surface.options.
    liquid_surface_options`: ghosts across the tank's walls and the surface cut at them,
    feature smoothing, ``Smooth(30, 0.01)``, the volume correction), without normals and
    attributes."""
    import pyvista as pv

    from pipeline.algorithm import run_chain
    from pipeline.surface import surface_stages
    from pipeline.surface.contour import polydata_to_mesh
    from pipeline.surface.options import liquid_surface_options

    options = liquid_surface_options(2 * R, tank_lo, tank_hi, anisotropic=anisotropic,
                                     normals=False, attributes=())
    return polydata_to_mesh(run_chain(surface_stages(**options),
                                      pv.PolyData(np.ascontiguousarray(x))))


def _pool(x, lo_xy, hi_xy, tank, report, keep=None):
    z_true, n_top = true_plane(x, lo_xy, hi_xy)
    res = {}
    for name, fn in METHODS.items():
        pts, tris = fn(x)
        if keep is not None:
            keep[name] = (pts, tris)
        res[name] = flatness(pts, lo_xy, hi_xy, z_true)
        report(f"  {name:20s} rms_plane {res[name]['rms_plane']:.4f}  rms_flat "
               f"{res[name]['rms_flat']:.4f}  offset {res[name]['offset']:+.4f}")
    scene = {}
    for name in ("isotropic", "anisotropic"):
        pts, _ = scene_surface(x, tank[0], tank[1], name == "anisotropic")
        scene[name] = flatness(pts, lo_xy, hi_xy, z_true)
        report(f"  scene pipeline {name:12s} rms_plane {scene[name]['rms_plane']:.4f}  "
               f"rms_flat {scene[name]['rms_flat']:.4f}  offset {scene[name]['offset']:+.4f}")
    return {"particles": int(len(x)), "z_true_m": z_true, "top_layer_particles": n_top,
            "methods": res, "scene_pipeline": scene}


def _best_alternating(fns, x, repeats):
    times = {name: [] for name in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            fn(x)
            times[name].append(time.perf_counter() - t0)
    return {name: min(t) for name, t in times.items()}, times


def _verdict(out):
    """The targets of the flatness benchmark, from the results."""
    flat = {}
    for case in ("pool_lattice", "pool_sph", "pool_sph_40"):
        methods = out["flatness"].get(case, {}).get("methods")
        if not methods:
            continue
        best_splash = min(methods[m]["rms_plane"] for m in SPLASHSURF)
        flat[case] = {
            name: {"rms_plane": methods[name]["rms_plane"],
                   "meets_0.05": methods[name]["rms_plane"] <= TARGET_RMS,
                   "beats_every_splashsurf": methods[name]["rms_plane"] < best_splash,
                   "ratio_to_best_splashsurf": methods[name]["rms_plane"] / best_splash,
                   "ratio_to_isotropic_same_smoothing": methods[name]["rms_plane"]
                   / methods["isotropic" + name[len("anisotropic"):]]["rms_plane"]}
            for name in ("anisotropic", "anisotropic+smooth", "anisotropic+feature")}
    cost = out["cost"]["block_100k"]
    return {"flatness": flat,
            "cost_ratio_100k": cost["ratio"], "cost_meets_1.5": cost["ratio"] <= TARGET_COST}


def run_flatness(report=print, *, write: bool = True, include_sph: bool = True,
                 repeats: int = 5) -> dict:
    """Run the whole benchmark; returns the results and (``write``) writes
    ``benchmarks/results/anisotropy.json`` and ``anisotropy_flatness.png``.

    Parameters
    ----------
    report : callable
        Called with one line of text per measurement (``print`` by default).
    write : bool
        Write the JSON and the side-by-side PNG.
    include_sph : bool
        Also settle and measure the SPH pool (about 15-25 s).
    repeats : int
        Timed runs per method for the cost (alternating; the best is kept), >= 1.
    """
    import numba

    out = {"benchmark": "anisotropy", "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
           "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                       "numba_threads": numba.get_num_threads(),
                       "load_average_start": list(os.getloadavg())},
           "parameters": {"spacing_m": S, "particle_radius_m": R, "cell_size_m": CELL,
                          "iso": ISO, "anisotropic_iso": ANISOTROPIC_ISO["sph"],
                          "stretched_gain": STRETCHED_GAIN,
                          "kernel": "sph, support 4 r",
                          "anisotropy": dict(ANISO_DEFAULTS),
                          "smooth": "pipeline.surface.Smooth defaults (100, pass band 0.001)",
                          "feature": "filters.surface.smoothing.smooth_surface defaults (25 "
                                     "sweeps, reach 8 r, low 0.5, high 1)",
                          "splashsurf": "smoothing length 2 r, cube 0.5 r, float32; smoothed: "
                                        "reconstruction_pipeline mesh_smoothing_iters=25, "
                                        "weights on",
                          "true_plane": "half a nominal spacing above the mean height of the "
                                        "top particle layer"},
           "flatness": {}, "sharpness": {}, "cost": {}}
    # warm up Numba and the libraries outside the measurements
    w = lattice((6, 6, 6), 0.1)
    for fn in METHODS.values():
        fn(w)
    meshes = {}
    # --- lattice pool
    x = lattice((40, 40, 10), 0.1)
    report("pool_lattice (40 x 40 x 10, jitter 10 %)")
    out["flatness"]["pool_lattice"] = _pool(x, (3 * S, 3 * S), (36 * S, 36 * S),
                                            ((-0.5 * S,) * 3, (39.5 * S, 39.5 * S, 0.3)),
                                            report, meshes)
    # --- SPH pools: the small one, and one of the lattice pool's size (about a minute to settle)
    if include_sph:
        for case, shape in (("pool_sph", (20, 20, 8)), ("pool_sph_40", (40, 40, 10))):
            try:
                xs, info = sph_pool(shape=shape)
                report(f"{case} ({info['particles']} particles settled {info['sim_seconds']} s, "
                       f"{info['wall_s']:.1f} s wall, max speed {info['max_speed_m_s']:.3f} m/s)")
                nx, ny, _ = shape
                res = _pool(xs, (3 * S, 3 * S), ((nx - 3) * S, (ny - 3) * S),
                            ((0.0, 0.0, 0.0), (nx * S, ny * S, 0.3)), report)
                out["flatness"][case] = dict(info, **res)
            except Exception as exc:  # report, do not hide
                out["flatness"][case] = {"error": f"{type(exc).__name__}: {exc}"}
                report(f"{case} failed: {exc}")
    # --- cube sharpness
    xc = lattice((16, 16, 16), 0.05, seed=1)
    lo = np.full(3, -0.5 * S)
    hi = np.full(3, 15.5 * S)
    res = {}
    report("cube_16 (16^3, jitter 5 %)")
    for name, fn in METHODS.items():
        pts, tris = fn(xc)
        st = mesh_stats(pts, tris)
        res[name] = dict(cube_sharpness(pts, lo, hi),
                         volume_error=float(st.volume / (16 * S) ** 3 - 1))
        report(f"  {name:20s} face_rms {res[name]['face_rms']:.4f}  edge_rms "
               f"{res[name]['edge_rms']:.4f}  volume {res[name]['volume_error']:+.4f}")
    out["sharpness"]["cube_16"] = {"particles": int(len(xc)), "methods": res}
    # --- volume of lattice balls: what each method (and its smoothing) does to drops
    out["ball_volume"] = {}
    report("ball volumes (lattice balls, jitter 5 %): relative error")
    for radius in (2, 3, 4, 6):
        xb_ = ball(radius)
        v0 = len(xb_) * S**3
        res = {name: float(mesh_stats(*fn(xb_)).volume / v0 - 1) for name, fn in METHODS.items()}
        out["ball_volume"][f"radius_{radius}"] = {"particles": int(len(xb_)), "methods": res}
        report(f"  radius {radius} spacings: " + "  ".join(f"{k} {v:+.3f}" for k, v in res.items()))
    # --- cost: same particles, cell size and sparse grid, alternating
    xb = lattice((50, 50, 40), 0.1)
    fns = {"isotropic": isotropic, "anisotropic": anisotropic,
           "anisotropy_only": lambda y: anisotropic_kernels(y, R, return_volumes=True)}
    best, times = _best_alternating(fns, xb, repeats)
    best_s, times_s = _best_alternating({"isotropic+smooth": isotropic_smooth,
                                         "anisotropic+smooth": anisotropic_smooth,
                                         "isotropic+feature": isotropic_feature,
                                         "anisotropic+feature": anisotropic_feature}, xb,
                                        max(1, repeats // 2))
    pool_best, _ = _best_alternating({"isotropic": isotropic, "anisotropic": anisotropic}, x,
                                     repeats)
    out["cost"] = {
        "block_100k": {"particles": int(len(xb)),
                       "isotropic_s": best["isotropic"], "anisotropic_s": best["anisotropic"],
                       "anisotropy_only_s": best["anisotropy_only"],
                       "ratio": best["anisotropic"] / best["isotropic"],
                       "isotropic_smooth_s": best_s["isotropic+smooth"],
                       "anisotropic_smooth_s": best_s["anisotropic+smooth"],
                       "ratio_with_smooth": best_s["anisotropic+smooth"]
                       / best_s["isotropic+smooth"],
                       "isotropic_feature_s": best_s["isotropic+feature"],
                       "anisotropic_feature_s": best_s["anisotropic+feature"],
                       "ratio_with_feature": best_s["anisotropic+feature"]
                       / best_s["isotropic+feature"],
                       "times_s": dict(times, **times_s)},
        "pool_lattice": {"particles": int(len(x)), "isotropic_s": pool_best["isotropic"],
                         "anisotropic_s": pool_best["anisotropic"],
                         "ratio": pool_best["anisotropic"] / pool_best["isotropic"]},
    }
    c = out["cost"]["block_100k"]
    report(f"cost 100k: isotropic {c['isotropic_s']:.3f} s, anisotropic "
           f"{c['anisotropic_s']:.3f} s (anisotropy {c['anisotropy_only_s']:.3f} s): ratio "
           f"{c['ratio']:.2f}; with Smooth {c['ratio_with_smooth']:.2f}; feature smoothing "
           f"{c['isotropic_feature_s'] - c['isotropic_s']:.3f} s vs windowed sinc "
           f"{c['isotropic_smooth_s'] - c['isotropic_s']:.3f} s")
    out["machine"]["load_average_end"] = list(os.getloadavg())
    out["targets"] = _verdict(out)
    if write:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "anisotropy.json").write_text(json.dumps(out, indent=2))
        render(meshes, out["flatness"]["pool_lattice"], RESULTS / "anisotropy_flatness.png")
        report(f"wrote {RESULTS / 'anisotropy.json'} and anisotropy_flatness.png")
    return out


def render(meshes, pool, path):
    """The top of the lattice pool with four methods side by side (offscreen)."""
    import pyvista as pv

    import pipeline.render.renderer  # noqa: F401 - chooses EGL / OSMesa without trying an X server

    pv.OFF_SCREEN = True
    names = ("isotropic", "anisotropic", "anisotropic+feature", "splashsurf_smoothed")
    plotter = pv.Plotter(off_screen=True, shape=(1, len(names)), window_size=(2400, 700))
    for col, name in enumerate(names):
        pts, tris = meshes[name]
        faces = np.hstack([np.full((len(tris), 1), 3), np.asarray(tris)]).astype(np.int64)
        mesh = pv.PolyData(np.asarray(pts, np.float64), faces.ravel())
        mesh = mesh.clip_box([0.1, 0.7, 0.1, 0.7, 0.1, 0.3], invert=False)
        plotter.subplot(0, col)
        rms = pool["methods"][name]["rms_plane"]
        plotter.add_text(f"{name}\nRMS from plane {rms:.3f} s", font_size=11)
        plotter.add_mesh(mesh, color="lightsteelblue", specular=0.6, specular_power=30,
                         smooth_shading=False)
        plotter.camera_position = [(0.05, -0.25, 0.45), (0.4, 0.4, 0.17), (0, 0, 1)]
        plotter.add_light(pv.Light(position=(1.5, 0.4, 0.25), focal_point=(0.4, 0.4, 0.18),
                                   intensity=0.8))
    plotter.screenshot(str(path))
    plotter.close()


def main(argv=None) -> int:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-sph", action="store_true", help="skip the SPH-settled pool")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    run_flatness(print, include_sph=not args.no_sph, repeats=max(1, args.repeats))
    return 0


if __name__ == "__main__":
    sys.exit(main())
