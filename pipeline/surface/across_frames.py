"""Surfaces of a particle series smoothed across frames (``blobflow surface --across-frames K``).

Two passes of :func:`pipeline.tasks.map_frames`, so that both run on a Dask cluster and
resume: the surface of every frame alone (a hidden series beside the output, removed once the
output is complete), then every frame's surface filtered with those of the ``K`` frames on
each side (:func:`filters.surface.temporal.smooth_across_frames`, triangular weights ``K + 1 -
|j|``): each vertex is moved with the particles (matched by their ``id``) to the other frames,
and along its normal toward the weighted mean of their surfaces (the offsets smoothed over
the mesh; the vertices on the tank's walls stay). A frame's result depends on
the particles of frames ``k - K .. k + K`` only, so a resumed or distributed run writes the
same frames as a serial one. Measured in ``benchmarks/results/splash_motion_notes.md``: on
the ``drop`` scene, five frames bring the surface's flicker to pysplashsurf's and the motion
the particles do not explain from 1.26x pysplashsurf's to 1.08x.
"""

from __future__ import annotations

import os
import threading
from collections import OrderedDict
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkPointSet, vtkPolyData

from filters.geometry import Box
from filters.surface.linecast import TriangleGrid
from filters.surface.temporal import follow_particles_across_frames, vertex_normals
from filters.validation import check_int

from ..io.outfiles import frames_folder, remove_series
from ..io.series import read_collection, read_frame, write_frame
from ..tasks import FramesResult, frame_done, map_frames
from .contour import polydata_to_mesh

if TYPE_CHECKING:
    from collections.abc import Callable
    from typing import Any

__all__ = ["smooth_series_across_frames", "across_frames_frame", "weights_across"]

def weights_across(frames: int) -> np.ndarray:
    """Triangular weights ``K + 1 - |j|`` of frames ``k - K .. k + K`` (sum 1)."""
    frames = check_int("frames", frames, 0, 10)
    w = frames + 1.0 - np.abs(np.arange(-frames, frames + 1, dtype=np.float64))
    return w / w.sum()


def _particles_by_id(path):
    data = read_frame(path)
    ids = data.GetPointData().GetArray("id")
    if ids is None:
        raise ValueError(f"{path}: smoothing across frames needs the particles' 'id' point "
                         f"array (to follow each particle from frame to frame)")
    ids = numpy_support.vtk_to_numpy(ids).astype(np.int64)
    x = numpy_support.vtk_to_numpy(vtkPointSet.SafeDownCast(data).GetPoints().GetData())
    return ids, np.asarray(x, np.float64)


def _mesh(path):
    data = vtkPolyData.SafeDownCast(read_frame(path))
    if data is None:
        raise TypeError(f"{path}: a surface frame must be polygonal data (vtkPolyData)")
    return (data, *polydata_to_mesh(data))


#: What recent tasks read (a serial pass reads every frame for ``2 K + 1`` tasks in a row):
#: (kind, path, inode, mtime, size, extra) -> value (frames are written by an atomic rename:
#: a rewritten file is a new inode), the oldest dropped beyond a window's worth.
_RECENT: OrderedDict = OrderedDict()
_RECENT_LOCK = threading.Lock()


def _recent(kind, path, make, keep, *extra):
    """``make(path, *extra)``, or what it returned for the same unchanged file lately (the
    ``keep`` latest kept)."""
    stat = os.stat(path)
    key = (kind, str(path), stat.st_ino, stat.st_mtime_ns, stat.st_size, *extra)
    with _RECENT_LOCK:
        if key in _RECENT:
            _RECENT.move_to_end(key)
            return _RECENT[key]
    value = make(path, *extra)
    with _RECENT_LOCK:
        _RECENT[key] = value
        while len(_RECENT) > keep:
            _RECENT.popitem(last=False)
    return value


def _surface(path, reach):
    """A surface frame's (polydata, vertices, triangles, grid of its triangles for ``reach``)."""
    data, points, tris = _mesh(path)
    return data, points, tris, TriangleGrid(points, tris, reach) if len(tris) else None


def across_frames_frame(in_file: str, out_file: str, time: float, options: dict) -> None:
    """Task: frame ``k``'s single-frame surface filtered with its neighbours'.

    ``in_file`` is frame ``k``'s particle file; ``options``: ``particles`` and ``surfaces``
    (the particle and single-frame surface file of every frame, in order), ``frames`` (``K``),
    ``radius`` and ``cell_size`` (m), ``box`` (the tank's inner corners, or None).
    """
    particles, surfaces = options["particles"], options["surfaces"]
    k = particles.index(in_file)
    K = options["frames"]
    radius = options["radius"]
    keep = 2 * (2 * K + 2)  # the particles and surfaces of a window and the next frame
    data, points, tris, _ = _recent("surface", surfaces[k], _surface, keep, radius)
    out = vtkPolyData()
    out.DeepCopy(data)
    if len(points):
        ids, x = _recent("particles", particles[k], _particles_by_id, keep)
        w = weights_across(K)
        weights, neighbours = [w[K]], []
        for j in range(-K, K + 1):
            if j == 0 or not 0 <= k + j < len(surfaces):
                continue
            other_ids, y = _recent("particles", particles[k + j], _particles_by_id, keep)
            # the particles of frame k that frame k + j has too, matched by id (frames list
            # their particles in one order, by id: mostly the same ids in the same rows)
            if np.array_equal(other_ids, ids):
                o = np.arange(len(ids))
                both = np.ones(len(ids), bool)
            else:
                sorter = np.argsort(other_ids)
                o = sorter[np.minimum(np.searchsorted(other_ids, ids, sorter=sorter),
                                      len(other_ids) - 1)]
                both = other_ids[o] == ids
            if not both.any():
                continue  # no particle in common: nothing tells where the surface went
            # the surface binned once for the 2 K frames it serves (same results either way)
            _, vertices, triangles, grid = _recent("surface", surfaces[k + j], _surface, keep,
                                                   radius)
            surface = (vertices, triangles) if grid is None else (grid,)
            neighbours.append((np.flatnonzero(both), y[o[both]], *surface))
            weights.append(w[K + j])
        smoothed = follow_particles_across_frames(points, tris, x, neighbours, weights, radius,
                                                  cell_size=options["cell_size"],
                                                  box=options["box"])
        dtype = numpy_support.vtk_to_numpy(data.GetPoints().GetData()).dtype
        pts = vtkPoints()
        pts.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(smoothed.astype(dtype)),
                                               deep=True))
        out.SetPoints(pts)
        old = out.GetPointData().GetNormals()
        if old is not None:
            normals = numpy_support.numpy_to_vtk(np.ascontiguousarray(
                vertex_normals(smoothed, tris).astype(np.float32)), deep=True)
            normals.SetName(old.GetName())
            out.GetPointData().SetNormals(normals)
    write_frame(out, out_file)


def smooth_series_across_frames(particles_path: str | Path, output_path: str | Path, frames: int,
                                surface_options: dict, *, single: Callable[..., Any],
                                client: Any = None, resume: bool = False,
                                progress: bool = True) -> FramesResult:
    """Write the surfaces of a particle series smoothed across ``2 frames + 1`` frames.

    Parameters
    ----------
    particles_path : str or Path
        The particle series (``.pvd`` or ``.series``); its frames need an ``id`` point array.
    output_path : str or Path
        The ``.pvd`` to write.
    frames : int
        ``K``, frames on each side, in [1, 10].
    surface_options : dict
        Options of :func:`pipeline.surface.surface_stages` (``radius`` at least).
    single : callable
        ``single(particles_path, path, client=, resume=, progress=)``: writes the single-frame
        surfaces as the series ``path`` (:func:`pipeline.surface.frames.surface_series`).
    client, resume, progress
        As in :func:`pipeline.tasks.map_frames`.

    Returns
    -------
    pipeline.tasks.FramesResult
        Of the second pass.
    """

    frames = check_int("frames", frames, 1, 10)
    particles_path = Path(particles_path)
    output_path = Path(output_path)
    entries = read_collection(particles_path)
    name = output_path.stem
    hidden = frames_folder(output_path.parent, f"_{name}_single")  # a link is refused
    single_path = hidden / f"{name}.pvd"
    complete = resume and all(frame_done(output_path.parent / f"{name}/{name}_{i:06d}.vtp")
                              for i in range(len(entries)))
    if not complete:
        hidden.mkdir(parents=True, exist_ok=True)
        single(particles_path, single_path, client=client, resume=resume, progress=progress)
    particles = [str(particles_path.parent / rel) for _, rel in entries]
    surfaces = [str(single_path.parent / f"{name}/{name}_{i:06d}.vtp")
                for i in range(len(entries))]
    radius = float(surface_options.get("radius", 0.01))
    implicit = surface_options.get("implicit")
    box = None
    if isinstance(implicit, Box) and surface_options.get("operation",
                                                         "intersection") == "intersection":
        box = (np.asarray(implicit.lower, np.float64), np.asarray(implicit.upper, np.float64))
    options = {"particles": particles, "surfaces": surfaces, "frames": frames,
               "radius": radius, "box": box,
               "cell_size": float(surface_options.get("cell_size") or radius / 2)}
    result = map_frames(particles_path, output_path, across_frames_frame, options, client=client,
                        resume=resume, progress=progress)
    # the single-frame surfaces are only the first pass's: gone once every frame is written
    # (what blobflow wrote there, by the one rule of pipeline.io.outfiles: other files stay)
    if hidden.is_dir():
        remove_series(hidden, name)
        try:
            hidden.rmdir()
        except OSError:
            pass
    return result
