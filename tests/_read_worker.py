"""Reads VTK XML files with blobflow's reader in a process of its own (the file-check tests).

``python _read_worker.py REFERENCE FILE...``: prints one line per file, ``same``, ``error
MESSAGE`` or ``different``, flushing after each, so that a file that aborts the process is the
one after the last line printed.  ``REFERENCE`` is the frame every file must equal when it reads.
"""

import sys

import numpy as np
from vtkmodules.util import numpy_support

from pipeline.io.series import SeriesError, read_frame


def _arrays(data):
    out = {}
    if hasattr(data, "GetPoints") and data.GetPoints() is not None:
        out["points"] = numpy_support.vtk_to_numpy(data.GetPoints().GetData())
    for label, attributes in (("point", data.GetPointData()), ("cell", data.GetCellData()),
                              ("field", data.GetFieldData())):
        for i in range(attributes.GetNumberOfArrays()):
            array = attributes.GetArray(i)
            if array is not None:
                out[f"{label}:{array.GetName()}"] = numpy_support.vtk_to_numpy(array)
    for kind in ("Verts", "Lines", "Strips", "Polys"):
        cells = getattr(data, f"Get{kind}", None)
        if cells is not None and cells() is not None and cells().GetNumberOfCells():
            out[kind] = numpy_support.vtk_to_numpy(cells().GetConnectivityArray())
    if data.IsA("vtkUnstructuredGrid") and data.GetCells() is not None:
        out["cells"] = numpy_support.vtk_to_numpy(data.GetCells().GetConnectivityArray())
    return out


def _same(a, b) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(np.asarray(a[k]), np.asarray(b[k]))
                                        for k in a)


def main(argv):
    reference = _arrays(read_frame(argv[0]))
    for path in argv[1:]:
        try:
            data = read_frame(path)
        except SeriesError as exc:
            line = str(exc)
            assert "\n" not in line and path in line, line
            print("error", line, flush=True)
            continue
        print("same" if _same(_arrays(data), reference) else "different", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
