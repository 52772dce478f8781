"""XDMF (with HDF5 heavy data) exports of fixed-topology series, as ParaView's readers expect.

One temporal collection of uniform grids, one grid per frame, every frame (t = 0 included) with
its own ``<Time>``, its own point positions and point arrays, and the one topology written once
in the HDF5 file and referenced by every frame. Cells of one kind get that kind's topology
(``Triangle``, ``Quadrilateral``, ``Tetrahedron``, ...); lines of equal length are
``Polyline`` with ``NodesPerElement`` (a strand of hair stays one cell); anything else is a
``Mixed`` topology, whose poly-vertices and poly-lines carry their node count. Times are
written as the shortest decimal that reads back to the frame's time, as in the PVD files.

Layout of ``NAME.xdmf`` beside ``NAME.h5``::

    /topology            (C,) int64    the cells (Mixed) or (C, k) int64 (one kind)
    /frames/000000/points       (N, 3) float64
    /frames/000000/ARRAY        (N,) or (N, c)  every point array of the frame
    ...

Reference: the XDMF model and format, https://www.xdmf.org/index.php/XDMF_Model_and_Format.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING
from xml.sax.saxutils import quoteattr

import numpy as np
from vtkmodules.util import numpy_support

from .outfiles import atomic_path

if TYPE_CHECKING:
    import pyvista as pv

__all__ = ["export_xdmf", "xdmf_topology"]

#: XDMF topology names (uniform) and Mixed type ids of the VTK cell types we export.
_UNIFORM = {1: ("Polyvertex", 1), 3: ("Polyline", 2), 5: ("Triangle", 3), 9: ("Quadrilateral", 4),
            10: ("Tetrahedron", 4), 12: ("Hexahedron", 8), 13: ("Wedge", 6), 14: ("Pyramid", 5)}
_MIXED_ID = {1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 7: 3, 9: 5, 10: 6, 12: 9, 13: 8, 14: 7}
_VTK_POLY_VERTEX, _VTK_LINE, _VTK_POLY_LINE, _VTK_POLYGON = 2, 3, 4, 7


def _cells(mesh):
    """VTK cell types (C,) and CSR connectivity ``(offsets (C + 1,), indices)`` of ``mesh``."""
    import pyvista as pv

    if isinstance(mesh, pv.PolyData):
        types, offsets, indices = [], [np.zeros(1, np.int64)], []
        base = 0
        for cells, single, many in ((mesh.GetVerts(), 1, _VTK_POLY_VERTEX),
                                    (mesh.GetLines(), _VTK_LINE, _VTK_POLY_LINE),
                                    (mesh.GetPolys(), None, _VTK_POLYGON)):
            off = numpy_support.vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64)
            idx = numpy_support.vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int64)
            if len(off) < 2:
                continue
            sizes = np.diff(off)
            if single is None:  # polygons: triangles, quads, other polygons
                kind = np.where(sizes == 3, 5, np.where(sizes == 4, 9, many))
            else:
                kind = np.where(sizes == (1 if single == 1 else 2), single, many)
            types.append(kind)
            offsets.append(off[1:] + base)
            indices.append(idx)
            base += len(idx)
        if mesh.GetNumberOfStrips():
            raise ValueError("triangle strips cannot be exported to XDMF; triangulate first")
        if not types:
            return np.zeros(0, np.uint8), np.zeros(1, np.int64), np.zeros(0, np.int64)
        return (np.concatenate(types).astype(np.uint8), np.concatenate(offsets),
                np.concatenate(indices))
    types = np.asarray(mesh.celltypes, dtype=np.uint8)
    off = np.asarray(mesh.offset, dtype=np.int64)
    return types, off, np.asarray(mesh.cell_connectivity, dtype=np.int64)


def xdmf_topology(mesh: pv.DataSet) -> tuple[dict[str, str], np.ndarray]:
    """The XDMF topology of a PyVista dataset's cells.

    Parameters
    ----------
    mesh : pyvista.PolyData or pyvista.UnstructuredGrid

    Returns
    -------
    attributes : dict of str to str
        The ``<Topology>`` element's attributes (``TopologyType``, ``NumberOfElements`` and,
        where XDMF needs it, ``NodesPerElement``).
    data : ndarray of int64
        (C, k) node indices (one cell kind) or the flat ``Mixed`` array (type id, [node
        count,] nodes, for each cell).

    Raises
    ------
    ValueError
        For a cell type XDMF has no name for in this exporter.
    """
    types, offsets, indices = _cells(mesh)
    n = len(types)
    sizes = np.diff(offsets)
    unknown = sorted(set(np.unique(types).tolist()) - set(_MIXED_ID))
    if unknown:
        raise ValueError(f"VTK cell type {unknown[0]} has no XDMF equivalent in this exporter")
    if n == 0:
        return {"TopologyType": "Polyvertex", "NumberOfElements": "0",
                "NodesPerElement": "1"}, np.zeros((0, 1), np.int64)
    line_like = np.isin(types, (_VTK_LINE, _VTK_POLY_LINE))
    vertex_like = np.isin(types, (1, _VTK_POLY_VERTEX))
    for group, (name, _) in ((line_like, _UNIFORM[3]), (vertex_like, _UNIFORM[1])):
        if group.all() and np.all(sizes == sizes[0]):  # lines or vertices of one length
            return ({"TopologyType": name, "NumberOfElements": str(n),
                     "NodesPerElement": str(int(sizes[0]))}, indices.reshape(n, int(sizes[0])))
    if np.all(types == types[0]) and int(types[0]) in _UNIFORM and int(types[0]) not in (1, 3):
        name, k = _UNIFORM[int(types[0])]
        return {"TopologyType": name, "NumberOfElements": str(n)}, indices.reshape(n, k)
    # Mixed: type id, node count for poly-vertices / poly-lines / polygons, then the nodes
    lookup = np.zeros(max(_MIXED_ID) + 1, np.int64)
    for vtk_type, xdmf_id in _MIXED_ID.items():
        lookup[vtk_type] = xdmf_id
    ids = lookup[types]
    counted = np.isin(ids, (1, 2, 3))
    head = 1 + counted.astype(np.int64)
    out = np.empty(int(head.sum() + sizes.sum()), np.int64)
    starts = np.concatenate([[0], np.cumsum(head + sizes)[:-1]])
    out[starts] = ids
    out[starts[counted] + 1] = sizes[counted]
    node_pos = np.repeat(starts + head, sizes) + (np.arange(len(indices))
                                                  - np.repeat(offsets[:-1], sizes))
    out[node_pos] = indices
    return {"TopologyType": "Mixed", "NumberOfElements": str(n)}, out


def _number_type(values: np.ndarray) -> tuple[str, int]:
    if np.issubdtype(values.dtype, np.floating):
        return "Float", values.dtype.itemsize
    if np.issubdtype(values.dtype, np.unsignedinteger):
        return "UInt", values.dtype.itemsize
    if np.issubdtype(values.dtype, np.integer):
        return "Int", values.dtype.itemsize
    raise ValueError(f"cannot export an array of dtype {values.dtype} to XDMF")


def _data_item(values: np.ndarray, h5_name: str, path: str) -> str:
    number, precision = _number_type(values)
    dims = " ".join(str(d) for d in values.shape)
    return (f'<DataItem Dimensions="{dims}" NumberType="{number}" Precision="{precision}" '
            f'Format="HDF">{h5_name}:{path}</DataItem>')


def _attribute(name: str, values: np.ndarray, h5_name: str, path: str) -> str:
    if values.ndim == 1:
        kind = "Scalar"
    elif values.ndim == 2 and values.shape[1] == 3:
        kind = "Vector"
    elif values.ndim == 2 and values.shape[1] == 9:
        kind = "Tensor"
    else:
        kind = "Matrix"
    return (f'<Attribute Name={quoteattr(name)} AttributeType="{kind}" Center="Node">'
            f'{_data_item(values, h5_name, path)}</Attribute>')


def export_xdmf(series_path: str | Path, xdmf_path: str | Path | None = None) -> Path:
    """Export a fixed-topology series as XDMF + HDF5 that ParaView opens as one animated mesh.

    Every frame is a grid of the temporal collection with its time, its points and its point
    arrays (with their own names); the cells are written once. Use it for cloth, jello and hair,
    whose cells never change (surfaces, whose topology changes every frame, stay PVD series).

    Parameters
    ----------
    series_path : str or Path
        A ``.pvd`` or ``.series`` collection of VTP/VTU frames.
    xdmf_path : str or Path, optional
        Output file; the collection's name with ``.xdmf`` when omitted. The heavy data go to
        the same name with ``.h5``. Both are written to temporary files and renamed into place.

    Returns
    -------
    Path
        The ``.xdmf`` file.

    Raises
    ------
    ValueError
        If the series has no frame, its point count or cells change between frames, or it
        holds cells XDMF cannot name.
    """
    import h5py

    from .series import read_series

    series_path = Path(series_path)
    xdmf_path = Path(xdmf_path) if xdmf_path else series_path.with_suffix(".xdmf")
    times, meshes = read_series(series_path)
    if not meshes:
        raise ValueError(f"{series_path} has no frames to export")
    first = meshes[0]
    topology, cells = xdmf_topology(first)
    for t, mesh in zip(times, meshes, strict=False):
        if mesh.n_points != first.n_points or not np.array_equal(xdmf_topology(mesh)[1], cells):
            raise ValueError(f"{series_path.name} changes topology at t = {t}; XDMF export "
                             f"needs a fixed mesh")
    h5_path = xdmf_path.with_suffix(".h5")
    h5_name = h5_path.name
    grids = []
    # temporary names unique to this process, removed if the export fails (pipeline.io.outfiles)
    with atomic_path(h5_path) as h5_tmp, h5py.File(h5_tmp, "w") as h5:
        h5.create_dataset("topology", data=cells)
        topo_xml = (f'<Topology {" ".join(f"{k}={quoteattr(v)}" for k, v in topology.items())}>'
                    f'{_data_item(cells, h5_name, "/topology")}</Topology>')
        for index, (t, mesh) in enumerate(zip(times, meshes, strict=False)):
            group = f"/frames/{index:06d}"
            points = np.asarray(mesh.points, dtype=np.float64)
            h5.create_dataset(f"{group}/points", data=points)
            parts = [f'<Grid Name="{xdmf_path.stem}_{index:06d}" GridType="Uniform">',
                     f'<Time Value="{float(t)!r}"/>', topo_xml,
                     f'<Geometry GeometryType="XYZ">'
                     f'{_data_item(points, h5_name, group + "/points")}</Geometry>']
            for name in mesh.point_data.keys():
                values = np.asarray(mesh.point_data[name])
                if values.dtype == np.bool_:
                    values = values.astype(np.uint8)
                if values.ndim > 2 or values.dtype.kind not in "fiu":
                    continue  # strings and higher-rank arrays have no XDMF attribute
                path = f"{group}/{name.replace('/', '_')}"
                h5.create_dataset(path, data=values)
                parts.append(_attribute(name, values, h5_name, path))
            parts.append("</Grid>")
            grids.append("".join(parts))
    text = ('<?xml version="1.0" ?>\n<Xdmf Version="3.0">\n<Domain>\n'
            f'<Grid Name={quoteattr(xdmf_path.stem)} GridType="Collection" '
            'CollectionType="Temporal">\n' + "\n".join(grids) + "\n</Grid>\n</Domain>\n</Xdmf>\n")
    with atomic_path(xdmf_path) as xml_tmp:
        xml_tmp.write_text(text, encoding="utf-8")
    return xdmf_path
