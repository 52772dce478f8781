"""Rigid bodies in a USD stage as transformed meshes (used by :func:`pipeline.usd.export_usd`).

A series of bodies' meshes (:class:`pipeline.bodies.BodyMeshes`: point array ``body``, field
arrays ``body_orientation`` and ``body_translation``, one row per rigid body) becomes, under
``/blobflow/NAME``, one ``UsdGeom.Xform`` per rigid body (``body0``, ``body1``, ...) whose
``translate`` and ``orient`` ops are sampled at every frame and whose child ``mesh`` holds the
body's mesh as given, once: what an animator expects of a rigid body (Blender and Houdini read
it as an object moved by its transform, not a mesh re-written every frame).  The vertices of the
other bodies (elastic ones, after the rigid ones) become the deforming mesh ``deforming``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Sequence

    import pyvista as pv
    from pxr import Usd

__all__ = ["has_rigid_bodies", "write_bodies"]


def _rows(mesh, name, width):
    if name not in mesh.field_data.keys():
        return None
    return np.asarray(mesh.field_data[name], dtype=np.float64).reshape(-1, width)


def has_rigid_bodies(meshes: Sequence[pv.DataSet]) -> bool:
    """Whether a series' frames carry rigid bodies' transforms and a ``body`` point array."""
    if not meshes:
        return False
    first = meshes[0]
    q = _rows(first, "body_orientation", 4)
    return (q is not None and len(q) > 0 and "body_translation" in first.field_data.keys()
            and "body" in first.point_data.keys() and first.n_cells > 0)


def _triangles(mesh):
    from vtkmodules.util import numpy_support

    polys = mesh.GetPolys()
    offsets = numpy_support.vtk_to_numpy(polys.GetOffsetsArray()).astype(np.int64)
    conn = numpy_support.vtk_to_numpy(polys.GetConnectivityArray()).astype(np.int64)
    counts = np.diff(offsets)
    return counts, conn, offsets


def _rotations(q):
    w, x, y, z = q.T
    r = np.empty((q.shape[0], 3, 3))
    r[:, 0] = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], 1)
    r[:, 1] = np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], 1)
    r[:, 2] = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], 1)
    return r


def _sub_mesh(counts, conn, offsets, keep_points):
    """Faces whose vertices are all in ``keep_points`` (bool), renumbered."""
    owner = np.repeat(np.arange(counts.size), counts)
    bad = np.zeros(counts.size, dtype=bool)
    np.logical_or.at(bad, owner, ~keep_points[conn])
    faces = ~bad
    new = np.cumsum(keep_points) - 1
    sel = np.repeat(faces, counts)
    return counts[faces].astype(np.int32), new[conn[sel]].astype(np.int32)


def write_bodies(stage: Usd.Stage, name: str, meshes: Sequence[pv.DataSet],
                 codes: Sequence[float]) -> None:
    """Write a series of bodies' meshes under ``/blobflow/NAME`` (see the module notes).

    Parameters
    ----------
    stage : pxr.Usd.Stage
    name : str
        Prim name of the series.
    meshes : sequence of pyvista.PolyData
        Its frames (:func:`has_rigid_bodies`).
    codes : sequence of float
        Their time codes.
    """
    from pxr import Gf, UsdGeom, Vt

    UsdGeom.Xform.Define(stage, f"/blobflow/{name}")
    first = meshes[0]
    body = np.asarray(first.point_data["body"], dtype=np.int64)
    q0 = _rows(first, "body_orientation", 4)
    t0 = _rows(first, "body_translation", 3)
    r0 = _rotations(q0)
    counts, conn, offsets = _triangles(first)
    x0 = np.asarray(first.points, dtype=np.float64)
    rigid = q0.shape[0]
    ops = []
    for k in range(rigid):
        mine = body == k
        fc, fi = _sub_mesh(counts, conn, offsets, mine)
        given = (x0[mine] - t0[k]) @ r0[k]  # X = R^T (x - t), the mesh as given
        xform = UsdGeom.Xform.Define(stage, f"/blobflow/{name}/body{k}")
        ops.append((xform.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble),
                    xform.AddOrientOp(UsdGeom.XformOp.PrecisionDouble)))
        prim = UsdGeom.Mesh.Define(stage, f"/blobflow/{name}/body{k}/mesh")
        prim.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        prim.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(given, np.float32)))
        prim.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(fc))
        prim.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(fi))
        prim.CreateExtentAttr(Vt.Vec3fArray.FromNumpy(
            np.array([given.min(axis=0), given.max(axis=0)], np.float32)))
    soft = body >= rigid
    deforming = None
    if soft.any():
        fc, fi = _sub_mesh(counts, conn, offsets, soft)
        deforming = UsdGeom.Mesh.Define(stage, f"/blobflow/{name}/deforming")
        deforming.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        deforming.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(fc))
        deforming.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(fi))
        points_attr = deforming.CreatePointsAttr()
        extent_attr = deforming.CreateExtentAttr()
    for code, mesh in zip(codes, meshes, strict=True):
        q = _rows(mesh, "body_orientation", 4)
        t = _rows(mesh, "body_translation", 3)
        for k, (translate, orient) in enumerate(ops):
            translate.Set(Gf.Vec3d(*t[k].tolist()), code)
            orient.Set(Gf.Quatd(float(q[k, 0]), Gf.Vec3d(*q[k, 1:].tolist())), code)
        if deforming is not None:
            x = np.asarray(mesh.points, dtype=np.float64)[soft]
            points_attr.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(x, np.float32)), code)
            extent_attr.Set(Vt.Vec3fArray.FromNumpy(
                np.array([x.min(axis=0), x.max(axis=0)], np.float32)), code)
