"""Liquid surfaces in motion: drops keep their volume, pools keep their water, frames do not
flicker.

blobflow's scene surface (``scenes/liquid_surface.py``: :func:`pipeline.surface.options.
liquid_surface_options`, i.e. anisotropic kernels, ghosts across the tank walls, feature and
windowed-sinc smoothing, volume correction, the tank intersected) side by side with
pysplashsurf's smoothed surface (``reconstruction_pipeline``: particle radius = spacing / 2,
smoothing length 2 r, cube 0.5 r, iso 0.6, 25 weighted smoothing iterations, Löschner et al.
2023) on the same particles. Cases:

* ``drops``: jittered lattice balls (jitter +-5 % and +-10 % of the spacing) of radius 2, 3, 4
  and 6 spacings; volume error against ``N s^3``, for the scene surface, the scene surface
  without its volume correction, the isotropic-kernel scene surface and pysplashsurf.
* ``pools``: pools settled by the liquid scenes' solver (DFSPH, :func:`filters.sph.scenarios.
  dam_break_liquid` with the column filling the tank: 0.064 x 0.064 m, 0.032 m deep, viscosity
  0.05, 1 s) at the dam break's spacing (4 mm, 2,048 particles) and half of it (2 mm,
  16,384); volume error of the surface against ``N s^3``, walls included, with and without the
  correction and without the ghosts (the tank only intersected); the bumpiness of the top (RMS
  of its vertices 2 s away from the walls about their mean, spacings).
* ``temporal_rest``: 10 more frames of each pool (30 fps): the RMS distance of the top
  surface's vertices (2 s from the walls) to the previous frame's surface, spacings per frame;
  beside it, how far the top layer's particles move (RMS of their vertical displacement).
* ``temporal_motion``: the frames of the ``drop`` scene at its defaults (1.5 s, 30 fps, 12 mm
  spacing, 2,500 particles) and at 6 mm (20,000 particles, a crown and drops): each frame's vertices
  moved by the particles' own displacement to the next frame (interpolated at the vertex with
  Shepard weights of the SPH kernel, support 2 s), then their distance to the next frame's surface:
  the surface motion the liquid's motion does not explain. RMS over the vertices more than one
  spacing from the tank walls (pysplashsurf does not clip at the walls), the same with distances
  capped at one spacing (a drop forming or
  merging moves the surface by more), and the fraction above half a spacing. Two more views
  of the same signed distances: ``beyond_uniform_offset``, the RMS once each piece's mean
  (a uniform offset of a closed piece: the volume it gains or loses) is removed, and
  ``flicker``, the RMS of half the sum of a vertex's forward and backward unexplained
  displacements (to the next and to the previous frame's surface, both within a spacing): a
  steady drift cancels in it, a surface that jumps out and back for one frame does not.
  Beside them, ``scene_across_5_frames``: the scene's surfaces filtered across frames k-2 ..
  k+2 (:func:`filters.surface.temporal.smooth_across_frames`, weights 1, 2, 3, 2, 1 over 9, as
  ``blobflow surface --across-frames 2`` writes them; not what the scenes write), and the same
  two with 10 sweeps of feature smoothing instead of 25 (``scene_feature_smoothing_10...``);
  and ``splashsurf_at_the_scenes_volume``: pysplashsurf's surfaces cut at the walls and held at
  ``N s^3`` by the scenes' own volume correction (the peer at the scene surface's volume
  accuracy: uncorrected, its pool loses 6 % of its water while the particles settle). Every
  surface's volume error against ``N s^3`` per frame is written beside its motion.
* ``thin_features``: jittered single and double particle layers (16 x 16 particles, in-plane
  spacing 1.0-1.8 s, layers s apart): components, cavities (closed bubbles inside) and holes
  (``(2 c - chi) / 2`` for ``c`` components of Euler characteristic ``chi``); and on every ``drop``
  frame the components, cavities and holes of both surfaces against the particle clusters (particles
  linked by chains of neighbours within the kernel support, 2 s: the pieces the liquid forms where
  particles are within the kernel support of each other).

Run alone (the machine has 2 cores)::

    env OPENBLAS_NUM_THREADS=1 python benchmarks/bench_splash.py [--quick]

``--quick`` skips the 2 mm pool and the 6 mm ``drop`` run (their simulations take most of the
run); ``--only CASE`` (``drops``, ``pools``, ``motion``, ``sheets``; repeatable) runs those cases
only and keeps the other entries of an existing ``splash.json`` (``pools`` also measures
``temporal_rest``, ``motion`` also ``drop_topology``). Writes
``benchmarks/results/splash.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
RESULTS = ROOT / "results"
if str(ROOT.parent) not in sys.path:
    sys.path.insert(0, str(ROOT.parent))

from filters.geometry import Box  # noqa: E402
from filters.surface.mesh import mesh_stats  # noqa: E402

POOL_TANK = (0.064, 0.064, 0.05)
POOL_DEPTH = 0.032
POOL_SETTLE_S = 1.0
FPS = 30.0
REST_FRAMES = 10
DROP_SPACING = 0.012  # the drop scene's default
CASES = ("drops", "pools", "motion", "sheets")


# --------------------------------------------------------------------------------------------
# Surfaces
# --------------------------------------------------------------------------------------------


def scene_surface(x, spacing, tank=None, **options):
    """The liquid scenes' surface of particles ``x`` (m) of spacing ``spacing`` in ``tank``
    (lower, upper) (geometry only: no attributes, no normals); returns (points, triangles)."""
    import pyvista as pv

    from pipeline.algorithm import run_chain
    from pipeline.surface import surface_stages
    from pipeline.surface.contour import polydata_to_mesh
    from pipeline.surface.options import liquid_surface_options

    lo, hi = tank if tank is not None else (None, None)
    opts = liquid_surface_options(spacing, lo, hi, normals=False, attributes=(), **options)
    out = run_chain(surface_stages(**opts), pv.PolyData(np.ascontiguousarray(x)))
    return polydata_to_mesh(out)


def splashsurf_surface(x, spacing):
    """pysplashsurf's smoothed surface (module docstring); (points, triangles)."""
    import pysplashsurf

    mesh, reconstruction = pysplashsurf.reconstruction_pipeline(
        np.ascontiguousarray(x, np.float32), particle_radius=0.5 * spacing, smoothing_length=2.0,
        cube_size=0.5, iso_surface_threshold=0.6, mesh_smoothing_iters=25,
        mesh_smoothing_weights=True)
    # read back what it used: its lengths are multiples of the particle radius (its docstring
    # says otherwise), so the marching-cubes cell must be 0.5 r = s / 4
    cell = reconstruction.grid.cell_size
    if abs(cell - 0.25 * spacing) > 1e-6 * spacing:
        raise RuntimeError(f"pysplashsurf used a {cell:g} m cell, not {0.25 * spacing:g} m "
                           f"(0.5 particle radii): its parameters were not read as intended")
    m = mesh.mesh
    return np.asarray(m.vertices, np.float64), np.asarray(m.triangles, np.int64)


def splashsurf_at_the_scenes_volume(x, spacing, tank, mesh):
    """pysplashsurf's surface ``mesh`` (points, triangles) held at the volume the scenes' surface
    keeps: cut at the tank's walls and every closed piece offset to enclose its particles'
    ``N s^3`` by the scenes' own stages (:class:`pipeline.surface.liquid.ClipBox`,
    :class:`pipeline.surface.liquid.VolumeCorrection`, same cell and limits): the peer at the same
    volume accuracy; (points, triangles)."""
    import pyvista as pv

    from pipeline.algorithm import update
    from pipeline.surface.contour import mesh_to_polydata, polydata_to_mesh
    from pipeline.surface.liquid import ClipBox, VolumeCorrection

    points, tris = mesh
    box = Box(*tank)
    cell = 0.25 * spacing  # the scenes' voxel and pysplashsurf's cube (0.5 particle radii)
    clip = ClipBox(box, tolerance=0.01 * cell)
    clip.SetInputDataObject(0, mesh_to_polydata(points, tris))  # pysplashsurf's float32
    correct = VolumeCorrection(radius=0.5 * spacing, container=box, cell_size=cell)
    correct.SetInputConnection(0, clip.GetOutputPort(0))
    correct.SetInputDataObject(1, pv.PolyData(np.ascontiguousarray(x, np.float64)))
    return polydata_to_mesh(update(correct, [clip, correct], what="the peer's volume"))


def holes(points, triangles):
    """Solid components, cavities (components enclosing a negative volume: bubbles) and holes
    (the genus summed over the components) of a closed mesh."""
    from filters.surface.correction import vertex_components

    p = np.asarray(points, np.float64)
    t = np.asarray(triangles, np.int64)
    st = mesh_stats(p, t)
    labels, k = vertex_components(t, len(p))
    signed = np.einsum("ij,ij->i", p[t[:, 0]], np.cross(p[t[:, 1]], p[t[:, 2]])) / 6.0
    volume = np.bincount(labels[t[:, 0]], weights=signed, minlength=k)
    cavities = int((volume < 0).sum())
    return k - cavities, cavities, (2 * st.components - st.euler) // 2


def distances(points, mesh):
    """Unsigned distance (m) of ``points`` to the triangle mesh ``(vertices, triangles)``."""
    return np.abs(signed_distances(points, mesh))


def signed_distances(points, mesh):
    """Signed distance (m) of ``points`` to the closed triangle mesh ``(vertices, triangles)``
    (positive outside)."""
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkPolyData
    from vtkmodules.vtkFiltersCore import vtkImplicitPolyDataDistance
    from vtkmodules.vtkFiltersGeneral import vtkSampleImplicitFunctionFilter

    from pipeline.surface.contour import mesh_to_polydata

    if len(points) == 0:
        return np.zeros(0)
    distance = vtkImplicitPolyDataDistance()
    distance.SetInput(mesh_to_polydata(*mesh))
    cloud = vtkPolyData()
    pts = vtkPoints()
    pts.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(points, np.float64), deep=True))
    cloud.SetPoints(pts)
    f = vtkSampleImplicitFunctionFilter()
    f.SetImplicitFunction(distance)
    f.SetInputData(cloud)
    f.ComputeGradientsOff()
    f.Update()
    return numpy_support.vtk_to_numpy(f.GetOutput().GetPointData().GetScalars()).astype(
        np.float64)


def away_from_walls(points, tank, margin):
    lo, hi = (np.asarray(v, np.float64) for v in tank)
    return np.all((points > lo + margin) & (points < hi - margin), axis=1)


# --------------------------------------------------------------------------------------------
# Particles
# --------------------------------------------------------------------------------------------


def ball(radius, spacing, jitter, seed=0):
    """Lattice points within ``radius`` spacings of a point off the lattice, jittered."""
    n = radius + 2
    g = np.stack(np.meshgrid(*[np.arange(-n, n + 1)] * 3, indexing="ij"), -1).reshape(-1, 3)
    g = g[np.linalg.norm(g - 0.1, axis=1) < radius].astype(np.float64) * spacing
    rng = np.random.default_rng(seed)
    return np.ascontiguousarray(g + rng.uniform(-jitter * spacing, jitter * spacing, g.shape))


def sheet(factor, layers, spacing, n=16, jitter=0.1, seed=0):
    """A jittered sheet of ``n x n`` particles ``factor`` spacings apart, ``layers`` thick."""
    g = np.stack(np.meshgrid(np.arange(n), np.arange(n), np.arange(layers), indexing="ij"), -1)
    g = g.reshape(-1, 3).astype(np.float64) * spacing
    g[:, :2] *= factor
    rng = np.random.default_rng(seed)
    return np.ascontiguousarray(g + rng.uniform(-jitter * spacing, jitter * spacing, g.shape))


def settled_pool(spacing, frames):
    """Particle frames (F, N, 3) of a pool settled by DFSPH for POOL_SETTLE_S, then ``frames``
    frames at FPS; and the wall time of the simulation."""
    from filters.sph.scenarios import dam_break_liquid

    length, width, height = POOL_TANK
    sim = dam_break_liquid(column_width=length, column_height=POOL_DEPTH, tank_length=length,
                           depth=width, tank_height=height, spacing=spacing, viscosity=0.05)
    t0 = time.perf_counter()
    sim.advance_to(POOL_SETTLE_S)
    out = []
    for k in range(frames + 1):
        sim.advance_to(POOL_SETTLE_S + k / FPS)
        # the solver sorts its particles into cells: put them back in the order of their ids
        out.append(np.array(sim.state.positions)[np.argsort(sim.state.extra["id"])])
    return np.array(out), time.perf_counter() - t0


def scene_frames(scene, *settings):
    """Times, positions (F, N, 3, in the order of the particles' ids) and the parameters of a
    scene run at its defaults but ``settings`` (``NAME=VALUE``), without its surface."""
    from pipeline.cli import main
    from pipeline.io.series import read_series

    with tempfile.TemporaryDirectory() as tmp:
        extra = [a for setting in settings for a in ("--set", setting)]
        code = main(["run", scene, "--out", tmp, "--quiet", "--no-render",
                     "--set", "surface=false", *extra])
        if code:
            raise RuntimeError(f"blobflow run {scene} failed ({code})")
        record = json.loads((Path(tmp) / "scene.json").read_text())
        times, frames = read_series(Path(tmp) / "particles.pvd")
        x = np.array([np.asarray(f.points, np.float64)[np.argsort(f.point_data["id"])]
                      for f in frames])
    return np.asarray(times), x, record["parameters"]


def clusters(x, link):
    """Number of particle clusters linked by chains of neighbours within ``link`` (m)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from filters.neighbors import NeighborSearch

    offsets, indices = NeighborSearch(link, "auto").build(x).query(half=True)
    rows = np.repeat(np.arange(len(x)), np.diff(offsets))
    graph = coo_matrix((np.ones(rows.size), (rows, indices)), shape=(len(x), len(x)))
    return int(connected_components(graph, directed=False)[0])


# --------------------------------------------------------------------------------------------
# Cases
# --------------------------------------------------------------------------------------------


def run_drops(report, spacing=0.02):
    out = {}
    for jitter in (0.05, 0.1):
        for radius in (2, 3, 4, 6):
            x = ball(radius, spacing, jitter)
            v0 = len(x) * spacing ** 3
            row = {"particles": int(len(x))}
            for name, fn in (
                    ("scene", lambda x=x: scene_surface(x, spacing)),
                    ("scene_without_correction",
                     lambda x=x: scene_surface(x, spacing, volume_correction=False)),
                    ("scene_isotropic", lambda x=x: scene_surface(x, spacing, anisotropic=False)),
                    ("splashsurf", lambda x=x: splashsurf_surface(x, spacing))):
                row[name] = float(mesh_stats(*fn()).volume / v0 - 1.0)
            out[f"radius_{radius}_jitter_{jitter}"] = row
            report(f"  ball r={radius} jitter {jitter}: " + "  ".join(
                f"{k} {v:+.3f}" for k, v in row.items() if k != "particles"))
    return out


def _top_bumpiness(points, tank, spacing):
    p = np.asarray(points)
    top = away_from_walls(p, tank, 2 * spacing) & (p[:, 2] > 0.5 * POOL_DEPTH)
    return float(np.std(p[top, 2]) / spacing)


def run_pools(report, spacings):
    pools, rest = {}, {}
    tank = ((0.0, 0.0, 0.0), POOL_TANK)
    for spacing in spacings:
        frames, wall = settled_pool(spacing, REST_FRAMES)
        key = f"spacing_{spacing * 1000:g}mm"
        v0 = frames.shape[1] * spacing ** 3
        x = frames[0]
        row = {"particles": int(frames.shape[1]), "settle_wall_s": wall}
        variants = {"scene": {}, "scene_without_correction": {"volume_correction": False},
                    "without_ghosts_or_correction": {"volume_correction": False,
                                                     "operation": "intersection_only"}}
        for name, extra in variants.items():
            if extra.get("operation") == "intersection_only":
                pts, tris = _without_ghosts(x, spacing, tank)
            else:
                pts, tris = scene_surface(x, spacing, tank, **extra)
            row[name] = {"volume_error": float(mesh_stats(pts, tris).volume / v0 - 1.0),
                         "bumpiness": _top_bumpiness(pts, tank, spacing)}
        pts, tris = splashsurf_surface(x, spacing)
        row["splashsurf"] = {"volume_error_unclipped": float(mesh_stats(pts, tris).volume / v0
                                                             - 1.0),
                             "bumpiness": _top_bumpiness(pts, tank, spacing)}
        pools[key] = row
        report(f"  pool {key} ({row['particles']} particles, settled in {wall:.0f} s): "
               + "  ".join(f"{k} {v['volume_error']:+.4f} (bumps {v['bumpiness']:.4f})"
                           for k, v in row.items()
                           if isinstance(v, dict) and "volume_error" in v))
        rest[key] = _temporal_rest(frames, spacing, tank, report)
    return pools, rest


def _without_ghosts(x, spacing, tank):
    """The scene surface with the tank only intersected with the field (no ghosts across its
    walls, no volume correction): the walls as the liquid scenes had them before."""
    return scene_surface(x, spacing, tank, volume_correction=False, mirror_walls=False)


def _temporal_rest(frames, spacing, tank, report):
    x0 = frames[0]
    top = (x0[:, 2] > x0[:, 2].max() - 0.5 * spacing) & away_from_walls(x0, tank, 2 * spacing)
    dz = np.diff(frames[:, top, 2], axis=0)
    out = {"particles_top_layer_rms_dz_per_frame": [float(v) for v in
                                                    np.sqrt(np.mean(dz ** 2, axis=1)) / spacing]}
    report(f"    at rest, the top layer's particles move "
           f"{np.mean(out['particles_top_layer_rms_dz_per_frame']):.5f} "
           f"spacings per frame (RMS, vertical)")
    for name, fn in (("scene", lambda x: scene_surface(x, spacing, tank)),
                     ("splashsurf", lambda x: splashsurf_surface(x, spacing))):
        meshes = [fn(x) for x in frames]
        per_frame = []
        for a, b in zip(meshes[:-1], meshes[1:], strict=False):
            p = b[0]
            top = away_from_walls(p, tank, 2 * spacing) & (p[:, 2] > 0.5 * POOL_DEPTH)
            d = distances(p[top], a)
            per_frame.append(float(np.sqrt(np.mean(d ** 2)) / spacing))
        out[name] = {"rms_per_frame": per_frame, "rms_mean": float(np.mean(per_frame)),
                     "rms_max": float(np.max(per_frame))}
        report(f"    at rest, {name}: RMS normal displacement {np.mean(per_frame):.5f} spacings "
               f"per frame (max {np.max(per_frame):.5f})")
    return out


def _displaced(points, x0, x1, spacing):
    """``points`` moved by the particles' displacement x1 - x0 (Shepard, SPH kernel)."""
    from filters.surface.attributes import interpolate_attributes

    u = interpolate_attributes(np.asarray(points, np.float64), x0, np.full(len(x0), 0.5 * spacing),
                               x1 - x0, cell_size=0.25 * spacing, kernel="sph")
    return points + u


def run_motion(report, *settings):
    times, frames, params = scene_frames("drop", *settings)
    spacing = params["spacing"]
    tank = ((0.0, 0.0, 0.0), (params["tank_length"], params["tank_width"],
                              params["tank_height"]))
    out = {"scene": "drop", "settings": list(settings), "frames": int(len(frames)),
           "particles": int(frames.shape[1]), "spacing_m": spacing}
    topology = {"particle_clusters": [clusters(x, 2.0 * spacing) for x in frames]}
    scene_meshes = [scene_surface(x, spacing, tank) for x in frames]
    fs10, peer = [], []
    for name, make in (("scene", lambda: scene_meshes),
                       ("splashsurf", lambda: peer.extend(splashsurf_surface(x, spacing)
                                                          for x in frames) or peer),
                       ("splashsurf_at_the_scenes_volume",
                        lambda: [splashsurf_at_the_scenes_volume(x, spacing, tank, m)
                                 for x, m in zip(frames, peer, strict=False)]),
                       ("scene_across_5_frames",
                        lambda: across_frames(scene_meshes, frames, spacing, tank)),
                       ("scene_feature_smoothing_10",
                        lambda: fs10.extend(scene_surface(x, spacing, tank, feature_smoothing=10)
                                            for x in frames) or fs10),
                       ("scene_feature_smoothing_10_across_5_frames",
                        lambda: across_frames(fs10, frames, spacing, tank))):
        t0 = time.perf_counter()
        meshes = make()
        if name == "scene_across_5_frames":
            # the filter alone (the scene's surfaces were made above), Numba compiled or cached
            out["across_5_frames_wall_s_per_frame"] = (time.perf_counter() - t0) / len(meshes)
        rms, capped, large, shape, flicker = [], [], [], [], []
        for k in range(len(frames) - 1):
            p, tris = meshes[k]
            keep = away_from_walls(p, tank, spacing)
            moved = _displaced(p[keep], frames[k], frames[k + 1], spacing)
            signed = signed_distances(moved, meshes[k + 1]) / spacing
            d = np.abs(signed)
            rms.append(float(np.sqrt(np.mean(d ** 2))) if d.size else 0.0)
            capped.append(float(np.sqrt(np.mean(np.minimum(d, 1.0) ** 2))) if d.size else 0.0)
            large.append(float(np.mean(d > 0.5)) if d.size else 0.0)
            shape.append(_beyond_uniform_offset(signed, tris, len(p), keep))
            if k > 0:
                back = signed_distances(_displaced(p[keep], frames[k], frames[k - 1], spacing),
                                        meshes[k - 1]) / spacing
                both = (d < 1.0) & (np.abs(back) < 1.0)
                flicker.append(float(np.sqrt(np.mean((0.5 * (signed + back)[both]) ** 2)))
                               if both.any() else 0.0)
        volume = [float(mesh_stats(*m).volume / (frames.shape[1] * spacing ** 3) - 1.0)
                  for m in meshes]
        out[name] = {"rms_per_frame": rms, "rms_mean": float(np.mean(rms)),
                     "volume_error_per_frame": volume,
                     "volume_error_last": volume[-1],
                     "volume_error_max_abs": float(np.max(np.abs(volume))),
                     "rms_median": float(np.median(rms)),
                     "rms_capped_mean": float(np.mean(capped)),
                     "fraction_above_half_spacing": float(np.mean(large)),
                     "beyond_uniform_offset_mean": float(np.mean(shape)),
                     "flicker_per_frame": flicker, "flicker_mean": float(np.mean(flicker)),
                     "flicker_median": float(np.median(flicker))}
        comps, cavs, hls = zip(*(holes(*m) for m in meshes), strict=False)
        topology[name] = {"components": list(map(int, comps)), "cavities": list(map(int, cavs)),
                          "holes": list(map(int, hls))}
        report(f"  in motion ({name}): unexplained RMS {np.mean(rms):.4f} spacings per frame "
               f"(median {np.median(rms):.4f}), capped at 1 s {np.mean(capped):.4f}, above 0.5 s "
               f"{np.mean(large):.4f}, beyond a uniform offset per piece {np.mean(shape):.4f}, "
               f"flicker {np.mean(flicker):.4f} (median {np.median(flicker):.4f}); volume "
               f"error at the end {volume[-1]:+.4f}, at most {np.max(np.abs(volume)):.4f}; "
               f"components {sum(comps)}, cavities {sum(cavs)}, holes {sum(hls)} over "
               f"{len(meshes)} frames")
    report(f"  particle clusters (link 2 s) summed over frames: "
           f"{sum(topology['particle_clusters'])}")
    return out, topology


def across_frames(meshes, frames, spacing, tank):
    """The scene's surfaces filtered across five frames, as ``blobflow surface --across-frames
    2`` writes them (:func:`filters.surface.temporal.follow_particles_across_frames`, weights
    :func:`pipeline.surface.across_frames.weights_across`; every particle is in every frame, in the
    order of its id)."""
    from filters.surface.linecast import TriangleGrid
    from filters.surface.temporal import follow_particles_across_frames
    from pipeline.surface.across_frames import weights_across

    w = weights_across(2)  # frames k-2 .. k+2: 1, 2, 3, 2, 1 over 9
    rows = np.arange(frames.shape[1])
    # every surface binned once for the frames it serves, as the pipeline does
    grids = [TriangleGrid(*m, 0.5 * spacing) for m in meshes]
    out = []
    for k, (points, tris) in enumerate(meshes):
        neighbours, weights = [], [w[2]]
        for j in (-2, -1, 1, 2):
            if 0 <= k + j < len(meshes):
                neighbours.append((rows, frames[k + j], grids[k + j]))
                weights.append(w[2 + j])
        out.append((follow_particles_across_frames(points, tris, frames[k], neighbours, weights,
                                                   0.5 * spacing, box=tank), tris))
    return out


def _beyond_uniform_offset(signed, triangles, n_vertices, keep):
    """RMS of the signed distances of the vertices ``keep`` once each closed piece's mean is
    removed (what is left is the change of shape, not of size)."""
    from filters.surface.correction import vertex_components

    labels, k = vertex_components(triangles, n_vertices)
    lab = labels[keep]
    used = lab >= 0
    if not used.any():
        return 0.0
    lab, s = lab[used], signed[used]
    mean = np.bincount(lab, weights=s, minlength=k) / np.maximum(np.bincount(lab, minlength=k), 1)
    return float(np.sqrt(np.mean((s - mean[lab]) ** 2)))


def run_sheets(report, spacing=0.02):
    out = {}
    for layers in (1, 2):
        for factor in (1.0, 1.2, 1.4, 1.6, 1.8):
            x = sheet(factor, layers, spacing)
            row = {}
            for name, fn in (("scene", lambda x=x: scene_surface(x, spacing)),
                             ("splashsurf", lambda x=x: splashsurf_surface(x, spacing))):
                c, cav, h = holes(*fn())
                row[name] = {"components": int(c), "cavities": int(cav), "holes": int(h)}
            out[f"layers_{layers}_spacing_{factor}"] = row
            report(f"  sheet {layers} layer(s), in-plane spacing {factor} s: " + "  ".join(
                f"{k}: {v['components']} comp, {v['cavities']} cavities, {v['holes']} holes"
                for k, v in row.items()))
    return out


def main(argv=None) -> int:
    import numba

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="skip the 2 mm pool and the 6 mm drop run")
    parser.add_argument("--only", action="append", choices=CASES, default=None,
                        help="run only this case (repeatable); the other entries of an existing "
                             "splash.json are kept")
    args = parser.parse_args(argv)
    cases = set(args.only or CASES)
    report = print
    path = RESULTS / "splash.json"
    previous = json.loads(path.read_text()) if args.only and path.exists() else {}
    out = {**previous, "benchmark": "splash",
           "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
           "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                       "numba_threads": numba.get_num_threads(),
                       "load_average_start": list(os.getloadavg())},
           "parameters": {"pool_tank_m": POOL_TANK, "pool_depth_m": POOL_DEPTH,
                          "pool_settle_s": POOL_SETTLE_S, "fps": FPS,
                          "rest_frames": REST_FRAMES,
                          "splashsurf": "reconstruction_pipeline, radius s/2, smoothing length "
                                        "2 r, cube 0.5 r, iso 0.6, 25 weighted smoothing "
                                        "iterations, float32"}}
    scene_surface(ball(2, 0.02, 0.05), 0.02)  # compile / load the Numba cache first
    if "drops" in cases:
        report("drops (volume error against N s^3)")
        out["drops"] = run_drops(report)
    if "pools" in cases:
        report("settled pools")
        out["pools"], out["temporal_rest"] = run_pools(report, (0.004,) if args.quick
                                                       else (0.004, 0.002))
    if "motion" in cases:
        report("drop scene frames (defaults: 12 mm spacing)")
        out["temporal_motion"], out["drop_topology"] = run_motion(report)
        if not args.quick:
            report("drop scene frames at 6 mm spacing")
            out["temporal_motion_6mm"], out["drop_topology_6mm"] = run_motion(report,
                                                                              "spacing=0.006")
    if cases & {"pools", "motion"}:
        out["quick"] = bool(args.quick)
    if args.only:
        out["cases_run"] = sorted(cases)
    if "sheets" in cases:
        report("thin sheets")
        out["thin_sheets"] = run_sheets(report)
    out["machine"]["load_average_end"] = list(os.getloadavg())
    RESULTS.mkdir(exist_ok=True)
    path.write_text(json.dumps(out, indent=2))
    report(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
