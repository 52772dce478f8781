"""Series as one USD stage (Pixar's Universal Scene Description) for Blender, Houdini and others.

Each series becomes one prim under ``/blobflow`` (its name), with one time sample per frame:

- particles (vertices or no cells) -> ``UsdGeom.Points``: ``points``, ``widths`` (twice the
  particle radius), ``velocities`` (from the ``velocity`` array), ``ids`` (from ``id``, so a
  particle keeps its identity while the count changes);
- surfaces (polygons) -> ``UsdGeom.Mesh``: ``points``, ``faceVertexCounts`` and
  ``faceVertexIndices`` sampled at every frame when the topology changes from frame to frame
  (one value when it does not: cloth, jello), ``normals`` (from ``Normals``) and
  ``velocities``;
- strands (lines) -> ``UsdGeom.BasisCurves`` (linear): ``points``, ``curveVertexCounts``,
  ``widths``;
- volumes (unstructured grids) -> their boundary surface as a ``UsdGeom.Mesh``;
- rigid bodies (the ``bodies`` of a scene with bodies in the water) -> one ``UsdGeom.Xform``
  per body with sampled ``translate`` and ``orient`` ops over its mesh as given
  (:mod:`pipeline.io.usd_bodies`).

The stage is z-up in metres (``upAxis = "Z"``, ``metersPerUnit = 1``), ``timeCodesPerSecond``
and ``framesPerSecond`` are the series' frame rate, and a frame at time ``t`` (s) is time code
``t * fps``. Every sampled prim also gets its ``extent``. Needs ``usd-core``
(``pip install "blobflow[usd]"``).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from filters.validation import check_range

from .outfiles import atomic_path
from .usd_bodies import has_rigid_bodies, write_bodies

if TYPE_CHECKING:
    from collections.abc import Sequence

    from numpy.typing import ArrayLike

__all__ = ["export_usd", "UsdUnavailableError", "time_codes", "curves_of_lines"]


class UsdUnavailableError(ImportError):
    """``usd-core`` (the ``pxr`` package) is not installed."""


def _pxr():
    try:
        from pxr import Sdf, Usd, UsdGeom, Vt
    except ImportError:
        raise UsdUnavailableError(
            "USD export needs Pixar's usd-core: pip install \"blobflow[usd]\" (or usd-core)"
        ) from None
    return Sdf, Usd, UsdGeom, Vt


def time_codes(times: ArrayLike, fps: float) -> np.ndarray:
    """USD time codes of frame times: ``t * fps``, snapped to the nearest integer within 1e-6.

    Parameters
    ----------
    times : (F,) array_like
        Frame times (s); the series rounds them to 9 decimals, so ``t * fps`` misses whole
        frames by up to ~1e-8.
    fps : float
        Frames per second, > 0.
    """
    with np.errstate(over="ignore", invalid="ignore"):  # checked by the caller: finite codes
        codes = np.asarray(times, dtype=np.float64) * float(fps)
        whole = np.round(codes)
        return np.where(np.abs(codes - whole) <= 1e-6, whole, codes)


def _frame_rate(times, series_path: Path) -> float:
    """The frame rate of a series: its run record's ``fps``, else 1 / the median time step."""
    record = series_path.parent / "scene.json"
    if record.is_file():
        try:
            fps = float(json.loads(record.read_text(encoding="utf-8")).get("fps"))
            if math.isfinite(fps) and 0 < fps <= _MAX_FPS:
                return fps
        except (OSError, ValueError, TypeError, AttributeError, RecursionError):
            pass
    if len(times) > 1:
        step = float(np.median(np.diff(times)))
        fps = 1.0 / step if step > 0 else math.inf
        if math.isfinite(fps) and 0 < fps <= _MAX_FPS:
            return fps
        raise ValueError(f"{series_path}: its frame times are {step:g} s apart, more than "
                         f"{_MAX_FPS:g} frames a second; give --fps")
    return 24.0


def _record_radius(series_path: Path) -> float | None:
    """Half the particle spacing of the run that wrote a series (its ``scene.json``), if any."""
    record = series_path.parent / "scene.json"
    try:
        spacing = float(json.loads(record.read_text(encoding="utf-8"))["parameters"]["spacing"])
    except (OSError, ValueError, TypeError, KeyError, RecursionError):
        return None
    return 0.5 * spacing if math.isfinite(spacing) and spacing > 0 else None


def _kind(mesh) -> str:
    """``points``, ``mesh`` or ``curves``: how a frame is written."""
    import pyvista as pv

    if isinstance(mesh, pv.PolyData):
        if mesh.GetNumberOfPolys() or mesh.GetNumberOfStrips():
            return "mesh"
        if mesh.GetNumberOfLines():
            return "curves"
        return "points"
    return "volume"


def _surface(mesh):
    """A frame as a PolyData that USD can hold: volumes by their boundary, strips as triangles."""
    import pyvista as pv

    if not isinstance(mesh, pv.PolyData):
        mesh = mesh.extract_surface()
    if mesh.n_strips:
        mesh = mesh.triangulate()
    return mesh


def _csr(cells):
    from vtkmodules.util import numpy_support

    offsets = numpy_support.vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64)
    indices = numpy_support.vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int32)
    return np.diff(offsets).astype(np.int32), indices


def curves_of_lines(counts: np.ndarray, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """VTK line cells as USD curves: one vertex count per curve, and the point of each vertex.

    A ``UsdGeom.BasisCurves`` has no index array: curve ``c``'s vertices are the next
    ``counts[c]`` points. Line cells that continue one another (a cell starting at the point
    the one before it ends at: hair written as 2-point ``segments``) are joined into one curve,
    so that a strand of ``S`` segments is one curve of ``S + 1`` vertices; any other cell is a
    curve of its own.

    Parameters
    ----------
    counts : (C,) int array
        Points of every line cell (VTK's offsets, differenced).
    indices : (sum(counts),) int array
        The cells' point indices, cell after cell (VTK's connectivity).

    Returns
    -------
    curve_counts : (K,) int32 array
        Vertices of every curve (``curveVertexCounts``).
    order : (curve_counts.sum(),) int32 array
        The point of every curve vertex: write ``points[order]`` (and every point array so).
    """
    counts = np.asarray(counts, np.int64)
    indices = np.asarray(indices, np.int64)
    if not len(counts):
        return np.zeros(0, np.int32), np.zeros(0, np.int32)
    starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
    first, last = indices[starts], indices[starts + counts - 1]
    joined = np.zeros(len(counts), bool)
    joined[1:] = first[1:] == last[:-1]
    keep = np.ones(len(indices), bool)
    keep[starts[joined]] = False  # the shared point is the previous cell's last vertex
    curve = np.cumsum(~joined) - 1
    curve_counts = np.bincount(curve, weights=counts - joined).astype(np.int32)
    return curve_counts, indices[keep].astype(np.int32)


def _extent(points: np.ndarray, pad: float = 0.0) -> np.ndarray:
    if not len(points):
        return np.zeros((2, 3), np.float32)
    return np.array([points.min(axis=0) - pad, points.max(axis=0) + pad], np.float32)


def _vec3(Vt, values) -> object:
    return Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(values, dtype=np.float32).reshape(-1, 3))


def _write_series(stage, path: Path, name: str, times, meshes, codes, radius, UsdGeom, Vt):
    kinds = {_kind(m) for m in meshes if m.n_points} or {"points"}
    kind = "mesh" if kinds & {"mesh", "volume"} else ("curves" if "curves" in kinds else "points")
    prim_path = f"/blobflow/{name}"
    if kind == "points":
        prim = UsdGeom.Points.Define(stage, prim_path)
    elif kind == "curves":
        prim = UsdGeom.BasisCurves.Define(stage, prim_path)
        prim.CreateTypeAttr(UsdGeom.Tokens.linear)
    else:
        prim = UsdGeom.Mesh.Define(stage, prim_path)
        prim.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    frames = [_surface(m) if kind == "mesh" else m for m in meshes]
    topology = []  # (counts, indices) per frame: one default value when it never changes
    if kind in ("mesh", "curves"):
        for mesh in frames:
            counts, indices = _csr(mesh.GetPolys() if kind == "mesh" else mesh.GetLines())
            topology.append((counts, indices) if kind == "mesh"
                            else curves_of_lines(counts, indices))
    fixed = bool(topology) and all(np.array_equal(c, topology[0][0])
                                   and np.array_equal(i, topology[0][1]) for c, i in topology)
    if kind == "mesh":
        topology_attrs = (prim.CreateFaceVertexCountsAttr(), prim.CreateFaceVertexIndicesAttr())
    elif kind == "curves":
        topology_attrs = (prim.CreateCurveVertexCountsAttr(), None)
    if fixed:
        topology_attrs[0].Set(Vt.IntArray.FromNumpy(topology[0][0]))
        if topology_attrs[1] is not None:
            topology_attrs[1].Set(Vt.IntArray.FromNumpy(topology[0][1]))
    points_attr = prim.CreatePointsAttr()
    extent_attr = prim.CreateExtentAttr()
    velocity_attr = widths_attr = ids_attr = normals_attr = None
    for k, (code, mesh) in enumerate(zip(codes, frames, strict=False)):
        points = np.asarray(mesh.points, dtype=np.float64).reshape(-1, 3)
        data = {name: np.asarray(mesh.point_data[name]) for name in mesh.point_data.keys()}
        if kind == "curves":  # the curves' vertices, curve after curve (see curves_of_lines)
            order = topology[k][1]
            points = points[order]
            data = {name: values[order] for name, values in data.items()}
        points_attr.Set(_vec3(Vt, points), code)
        pad = 0.0
        if "velocity" in data.keys():
            velocity_attr = velocity_attr or prim.CreateVelocitiesAttr()
            velocity_attr.Set(_vec3(Vt, data["velocity"]), code)
        if kind in ("points", "curves"):
            if "radius" in data.keys():
                widths = 2.0 * np.asarray(data["radius"], np.float32).reshape(-1)
            else:
                widths = np.full(len(points), 2.0 * radius, np.float32)
            widths_attr = widths_attr or prim.CreateWidthsAttr()
            prim.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
            widths_attr.Set(Vt.FloatArray.FromNumpy(widths), code)
            pad = float(widths.max()) / 2 if len(widths) else 0.0
        if kind == "points" and "id" in data.keys():
            ids_attr = ids_attr or prim.CreateIdsAttr()
            ids_attr.Set(Vt.Int64Array.FromNumpy(np.asarray(data["id"], np.int64).reshape(-1)),
                         code)
        if topology and not fixed:
            topology_attrs[0].Set(Vt.IntArray.FromNumpy(topology[k][0]), code)
            if topology_attrs[1] is not None:
                topology_attrs[1].Set(Vt.IntArray.FromNumpy(topology[k][1]), code)
        if kind == "mesh" and "Normals" in data.keys():
            normals_attr = normals_attr or prim.CreateNormalsAttr()
            prim.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
            normals_attr.Set(_vec3(Vt, data["Normals"]), code)
        extent_attr.Set(Vt.Vec3fArray.FromNumpy(_extent(points, pad)), code)
    return kind


def export_usd(series: str | Path | Sequence[str | Path], usd_path: str | Path, *,
               fps: float | None = None, radius: float | None = None) -> Path:
    """Write one or more series as one USD stage, one time sample per frame.

    Parameters
    ----------
    series : str, Path, or sequence of them
        ``.pvd`` or ``.series`` collections (their frames all share one time axis); each becomes
        the prim ``/blobflow/NAME`` (``NAME`` the collection's name).
    usd_path : str or Path
        Output stage: ``.usd`` / ``.usdc`` (binary crate) or ``.usda`` (text).
    fps : float, optional
        Time codes per second, in (0, 1e6]; default the producing run's ``fps`` (its
        ``scene.json``), else one over the median time step of the first series.
    radius : float, optional
        Particle and strand radius (m, > 0) for the ``widths`` where a series has no ``radius``
        array, finite; default half the run's ``spacing``, else 0.005 m.

    Returns
    -------
    Path
        ``usd_path``, written to a temporary file and renamed into place.

    Raises
    ------
    UsdUnavailableError
        If ``usd-core`` is not installed.
    ValueError
        For a bad ``usd_path`` suffix, ``fps`` or ``radius``, names used twice, NaN or infinite
        values in a frame, or frame times that do not give distinct finite time codes, before
        anything is written.
    FileNotFoundError, pipeline.io.series.SeriesError
        For a missing or malformed series.
    """
    from .series import read_series

    Sdf, Usd, UsdGeom, Vt = _pxr()
    paths = [Path(series)] if isinstance(series, (str, os.PathLike)) else [Path(p) for p in series]
    if not paths:
        raise ValueError("series must name at least one .pvd or .series file")
    usd_path = Path(usd_path)
    if usd_path.suffix not in (".usd", ".usda", ".usdc"):
        raise ValueError(f"usd_path must end in .usd, .usda or .usdc, got {str(usd_path)!r}")
    if fps is not None:
        fps = check_range("fps", fps, 0.0, _MAX_FPS, low_inclusive=False)
    if radius is not None:
        radius = check_range("radius", radius, 0.0, math.inf, low_inclusive=False,
                             high_inclusive=False)
    names = [p.name.split(".")[0] for p in paths]
    if len(set(names)) != len(names):
        raise ValueError(f"series names must differ (each is a prim), got {names}")
    bad = [n for n in names if not Sdf.Path.IsValidIdentifier(n)]
    if bad:
        raise ValueError(f"series name {bad[0]!r} is not a valid USD prim name")
    loaded = [read_series(p) for p in paths]
    for path, (_, meshes) in zip(paths, loaded, strict=False):
        _check_finite_frames(path, meshes)
    fps = fps or _frame_rate(loaded[0][0], paths[0])
    radius = radius or _record_radius(paths[0]) or 0.005
    all_codes = [time_codes(times, fps) for times, _ in loaded]
    for path, codes in zip(paths, all_codes, strict=False):
        _check_codes(path, codes, fps)

    with atomic_path(usd_path) as tmp:  # a unique name, removed if anything fails
        _write_stage(tmp, names, paths, loaded, all_codes, fps, radius, Usd, UsdGeom, Vt)
    return usd_path


#: Largest frame rate (time codes per second) accepted: a movie's frames far apart enough
#: that ``t * fps`` stays exact in double precision for any sensible duration.
_MAX_FPS = 1e6


def _check_finite_frames(path: Path, meshes) -> None:
    """Refuse NaN or infinite points and point arrays (USD would store them)."""
    for index, mesh in enumerate(meshes):
        arrays = [("points", np.asarray(mesh.points))] + [
            (f"point array {name!r}", np.asarray(mesh.point_data[name]))
            for name in mesh.point_data.keys()]
        for what, values in arrays:
            if np.issubdtype(values.dtype, np.floating) and not np.isfinite(values).all():
                raise ValueError(f"{path}: frame {index} has NaN or infinite {what}; USD "
                                 f"cannot hold them")


def _check_codes(path: Path, codes: np.ndarray, fps: float) -> None:
    """The time codes of a series must be finite and increasing (each frame its own sample)."""
    if not np.all(np.isfinite(codes)):
        raise ValueError(f"{path}: its frame times at {fps:g} fps give time codes beyond what "
                         f"a double holds")
    if len(codes) > 1 and not np.all(np.diff(codes) > 0):
        k = int(np.flatnonzero(~(np.diff(codes) > 0))[0])
        raise ValueError(f"{path}: frames {k} and {k + 1} fall on the same time code "
                         f"({codes[k]:.17g}) at {fps:g} fps: their times are too far from 0 for "
                         f"double precision to tell them apart")


def _write_stage(tmp, names, paths, loaded, all_codes, fps, radius, Usd, UsdGeom, Vt) -> None:
    stage = Usd.Stage.CreateNew(str(tmp))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, UsdGeom.LinearUnits.meters)
    stage.SetTimeCodesPerSecond(fps)
    stage.SetFramesPerSecond(fps)
    codes = np.concatenate(all_codes) if all_codes else np.zeros(0)
    if len(codes):
        stage.SetStartTimeCode(float(codes.min()))
        stage.SetEndTimeCode(float(codes.max()))
    root = UsdGeom.Xform.Define(stage, "/blobflow")
    stage.SetDefaultPrim(root.GetPrim())
    for name, path, (times, meshes), series_codes in zip(names, paths, loaded, all_codes,
                                                          strict=False):
        if has_rigid_bodies(meshes):
            write_bodies(stage, name, meshes, [float(c) for c in series_codes])
            continue
        _write_series(stage, path, name, times, meshes, [float(c) for c in series_codes],
                      radius, UsdGeom, Vt)
    stage.GetRootLayer().Save()
