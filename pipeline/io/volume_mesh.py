"""Reading a user's volume mesh (Gmsh ``.msh``, Medit ``.mesh``, Abaqus ``.inp``, VTU, ...)
through meshio, for a finite-element solid simulated as it is
(:meth:`filters.elastic.fem_simulation.FEMSimulation.from_tets`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = ["read_volume_mesh", "VOLUME_CELL_TYPES"]

#: meshio's names of volume cells; of these only linear tetrahedra (``tetra``) are simulated.
VOLUME_CELL_TYPES = ("tetra", "tetra10", "hexahedron", "hexahedron20", "hexahedron27",
                     "wedge", "wedge15", "pyramid", "pyramid13", "polyhedron")

#: Extensions of formats that hold volume meshes only: a reader's failure is then reported as
#: it is, instead of trying the file as a surface.
VOLUME_ONLY_SUFFIXES = (".msh", ".mesh", ".meshb", ".inp", ".med", ".xdmf", ".xmf", ".h5m")


def read_volume_mesh(path: str | Path,
                     name: str = "mesh") -> tuple[NDArray[np.float64], NDArray[np.int64]] | None:
    """The linear tetrahedra of a volume mesh file, or None when it holds no volume cells.

    Parameters
    ----------
    path : str or Path
        Any file meshio reads (Gmsh, Medit, Abaqus, VTU, VTK, XDMF, ...).
    name : str
        The parameter the path came from, for messages.

    Returns
    -------
    (points (N, 3) float64, tets (T, 4) int64) or None
        ``None`` when meshio cannot read the file or it holds only surface, line or point
        cells (a surface for the lattice path), unless its format holds volume meshes only.
        Lower-dimensional cells beside the tetrahedra (boundary triangles, physical groups)
        are ignored.

    Raises
    ------
    ValueError
        Naming ``name``: a missing file, a volume-only format meshio cannot read, or volume
        cells that are not all linear tetrahedra (quadratic tetrahedra, hexahedra, wedges,
        pyramids: say which, and how many).
    """
    import meshio

    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{name}: no such file {str(path)!r}")
    try:
        mesh = meshio.read(p)
    except Exception as exc:  # noqa: BLE001 - meshio raises many kinds for unreadable files
        if p.suffix.lower() in VOLUME_ONLY_SUFFIXES:
            raise ValueError(f"{name}: {str(path)!r} is not a volume mesh meshio can read "
                             f"({type(exc).__name__}: {exc})") from None
        return None
    counts = {}
    for block in mesh.cells:
        if block.type in VOLUME_CELL_TYPES:
            counts[block.type] = counts.get(block.type, 0) + len(block.data)
    if not counts:
        return None
    other = {k: v for k, v in counts.items() if k != "tetra"}
    if other:
        found = ", ".join(f"{v} {k}" for k, v in sorted(other.items()))
        raise ValueError(f"{name}: {str(path)!r} holds {found} cells: only linear tetrahedra "
                         "('tetra') are simulated as they are; convert the mesh to linear "
                         "tetrahedra, or give its surface to cut on the lattice")
    tets = np.concatenate([np.asarray(b.data, dtype=np.int64) for b in mesh.cells
                           if b.type == "tetra"])
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"{name}: {str(path)!r} has points of shape {points.shape}")
    if points.shape[1] == 2:
        raise ValueError(f"{name}: {str(path)!r} has 2D points: a volume mesh needs 3D ones")
    return np.ascontiguousarray(points), tets
