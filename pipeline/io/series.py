"""Time series on disk: PVD collections (and ParaView ``.series`` files) of VTK XML datasets.

Layout of a series named ``particles`` in ``outputs/run/``::

    outputs/run/particles.pvd            the collection ParaView opens (one animated dataset)
    outputs/run/particles.vtp.series     the same list in ParaView's JSON file-series format
    outputs/run/particles/particles_000000.vtp, particles_000001.vtp, ...

Fixed-topology series (cloth, jello, hair) can also be exported as XDMF + HDF5
(:func:`export_xdmf`, :mod:`pipeline.io.xdmf`).

Every frame is written to a temporary file and renamed into place, and both collection files are
rewritten (atomically) after every frame, so a run interrupted at any point leaves a valid, shorter
series.  XML files are written appended, raw (not base64), zlib-compressed, with UInt64 headers.
"""

from __future__ import annotations

import json
import math
import os
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkDataObject
from vtkmodules.vtkIOXML import (
    vtkXMLImageDataReader,
    vtkXMLImageDataWriter,
    vtkXMLPolyDataReader,
    vtkXMLPolyDataWriter,
    vtkXMLUnstructuredGridReader,
    vtkXMLUnstructuredGridWriter,
)

from filters.memory import format_bytes, memory_limit

from ..algorithm import vtk_messages
from .outfiles import atomic_path, frames_folder, remove_frames, sweep_temporaries
from .xmlcheck import UnsafeFileError, check_vtk_xml

if TYPE_CHECKING:
    from collections.abc import Callable, Iterable

    from numpy.typing import NDArray
    from pyvista import DataSet

__all__ = [
    "SeriesWriter",
    "SeriesError",
    "read_series",
    "read_collection",
    "read_frame",
    "validate_series",
    "check_finite_dataset",
    "write_frame",
    "frame_extension",
]

_WRITERS = {
    "vtkPolyData": (".vtp", vtkXMLPolyDataWriter),
    "vtkUnstructuredGrid": (".vtu", vtkXMLUnstructuredGridWriter),
    "vtkImageData": (".vti", vtkXMLImageDataWriter),
}
_READERS = {
    ".vtp": vtkXMLPolyDataReader,
    ".vtu": vtkXMLUnstructuredGridReader,
    ".vti": vtkXMLImageDataReader,
}


class SeriesError(ValueError):
    """A collection file is missing, malformed, or lists frames that cannot be read."""


def _format_time(t: float) -> str:
    # repr gives the shortest string that reads back to the same double: 0.1 stays "0.1".
    return repr(float(t))


def _atomic_write_text(path: Path, text: str) -> None:
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())


def check_finite_dataset(data: vtkDataObject, what: str = "dataset") -> None:
    """Raise ``ValueError`` if the points or any floating-point array of ``data`` is non-finite."""
    arrays = []
    if hasattr(data, "GetPoints") and data.GetPoints() is not None:
        arrays.append(("points", data.GetPoints().GetData()))
    for label, attributes in (("point", data.GetAttributes(0)), ("cell", data.GetAttributes(1)),
                              ("field", data.GetFieldData())):
        if attributes is None:
            continue
        for i in range(attributes.GetNumberOfArrays()):
            array = attributes.GetArray(i)
            if array is not None:
                arrays.append((f"{label} array {array.GetName()!r}", array))
    for name, array in arrays:
        values = numpy_support.vtk_to_numpy(array)
        if np.issubdtype(values.dtype, np.floating) and not np.isfinite(values).all():
            raise ValueError(f"refusing to write {what}: {name} holds NaN or infinite values")


def frame_extension(data: vtkDataObject) -> str:
    """The XML file extension of ``data``'s type (``.vtp``, ``.vtu`` or ``.vti``)."""
    cls = data.GetClassName()
    if cls not in _WRITERS:
        raise TypeError(f"cannot write {cls} as a series frame; supported: {sorted(_WRITERS)}")
    return _WRITERS[cls][0]


def write_frame(data: vtkDataObject, path: str | Path) -> Path:
    """Write one dataset as a VTK XML file, atomically (temporary file, then rename).

    Appended raw data, zlib compression, UInt64 headers; refuses non-finite values.
    """
    path = Path(path)
    frame_extension(data)
    check_finite_dataset(data, str(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    writer = _WRITERS[data.GetClassName()][1]()
    writer.SetInputData(data)
    writer.SetDataModeToAppended()
    writer.EncodeAppendedDataOff()
    writer.SetCompressorTypeToZLib()
    # level 1: float arrays hardly compress at any level (3.98 against 4.00 MB for a 31k-particle
    # frame at level 5), and level 1 writes 20-30 % faster
    writer.SetCompressionLevel(1)
    writer.SetHeaderTypeToUInt64()
    with atomic_path(path) as tmp:  # a unique name, removed if the write fails or is stopped
        writer.SetFileName(str(tmp))
        with vtk_messages() as log:
            ok = writer.Write() == 1 and writer.GetErrorCode() == 0
        if not ok:
            raise OSError(f"VTK could not write {path}"
                          + (f": {log.errors[0]}" if log.errors else ""))
    return path


class SeriesWriter:
    """Write a PVD series one frame at a time, valid after every frame.

    Parameters
    ----------
    path : str or Path
        The collection file, ``DIR/NAME.pvd``.  Frames go to ``DIR/NAME/NAME_%06d.EXT`` and a
        ParaView ``DIR/NAME.EXT.series`` file is kept beside it.
    resume : bool
        Keep the frames already listed in an existing collection and append after them.
        Otherwise the series starts empty (old frames of this series are removed on the first
        write, so nothing stale is left behind).

    Attributes
    ----------
    entries : list of (float, str)
        Time and relative file name of every frame written so far.
    """

    def __init__(self, path: str | Path, *, resume: bool = False):
        self.path = Path(path)
        if self.path.suffix != ".pvd":
            raise ValueError(f"a series path must end in .pvd, got {str(self.path)!r}")
        self.name = self.path.stem
        if not self.name.isidentifier():
            raise ValueError(f"a series name must be a Python identifier such as 'particles', "
                             f"got {self.name!r}")
        self.frames_dir = frames_folder(self.path.parent, self.name)  # a link is refused
        self.entries: list[tuple[float, str]] = []
        self._class: str | None = None
        self._fresh = not resume
        if resume and self.path.exists():
            self.entries = self._own_entries(read_collection(self.path))
            if self.entries:
                ext = Path(self.entries[0][1]).suffix
                self._class = next(c for c, (e, _) in _WRITERS.items() if e == ext)

    def __len__(self) -> int:
        return len(self.entries)

    @property
    def times(self) -> list[float]:
        """Times of the frames written so far."""
        return [t for t, _ in self.entries]

    def _own_entries(self, entries: list[tuple[float, str]]) -> list[tuple[float, str]]:
        """Check that a collection on disk lists exactly the frames this writer would write.

        Resuming deletes the frames after the resume point, so it must only ever act on files
        named ``NAME/NAME_%06d.EXT`` inside the series' own folder, numbered from 0: a collection
        edited to list ``../x`` or an absolute path is refused.
        """
        if not entries:
            return []
        ext = Path(entries[0][1]).suffix
        if ext not in _READERS:
            raise SeriesError(f"{self.path} lists {entries[0][1]!r}; a series frame ends in "
                              f"one of {sorted(_READERS)}")
        for index, (_, name) in enumerate(entries):  # times: checked by read_collection
            expected = f"{self.name}/{self.name}_{index:06d}{ext}"
            if name != expected:
                raise SeriesError(
                    f"{self.path} lists frame {index} as {name!r}, not {expected!r}: it was not "
                    f"written by blobflow, so it cannot be resumed (run without resume)")
        return list(entries)

    def truncate(self, n_frames: int) -> None:
        """Keep only the first ``n_frames`` frames (used when resuming several series at once).

        Only files inside the series' own frame folder are ever deleted.
        """
        folder = self.frames_dir.resolve()
        for _, name in self.entries[n_frames:]:
            target = (self.path.parent / name).resolve()
            if target.parent != folder:  # never delete outside NAME/ (checked on load too)
                raise SeriesError(f"refusing to delete {target}: outside {folder}")
            target.unlink(missing_ok=True)
        self.entries = self.entries[:n_frames]
        self._write_collections()

    def _clear_stale(self) -> None:
        # the one rule of pipeline.io.outfiles: frames named NAME_<digits>.vt?, nothing else
        frames_folder(self.path.parent, self.name)
        remove_frames(self.frames_dir, self.name)
        sweep_temporaries(self.frames_dir)
        self._fresh = False

    def write(self, data: vtkDataObject, time: float) -> Path:
        """Append ``data`` as the frame at ``time`` (s) and rewrite the collection files.

        Raises
        ------
        TypeError
            If ``data``'s type differs from the series' first frame (one data type per series) or
            cannot be written as a single XML file.
        ValueError
            If ``time`` does not increase, or the data holds NaN or infinite values.
        """
        cls = data.GetClassName()
        if cls not in _WRITERS:
            raise TypeError(f"cannot write {cls} as a series frame; supported: {sorted(_WRITERS)}")
        if self._class is not None and cls != self._class:
            raise TypeError(f"series {self.name!r} holds {self._class}, cannot add a {cls}")
        time = float(time)
        if self.entries and time <= self.entries[-1][0]:
            raise ValueError(f"frame times must increase: {time} after {self.entries[-1][0]}")
        check_finite_dataset(data, f"frame t = {time} of series {self.name!r}")
        if self._fresh:
            self._clear_stale()
        self._class = cls
        ext = _WRITERS[cls][0]
        file_name = f"{self.name}_{len(self.entries):06d}{ext}"
        final = write_frame(data, self.frames_dir / file_name)
        self.entries.append((time, f"{self.name}/{file_name}"))
        self._write_collections()
        return final

    @classmethod
    def from_files(cls, path: str | Path, entries: Iterable[tuple[float, str]]) -> SeriesWriter:
        """Write the collection files for frames already on disk and return the writer.

        Parameters
        ----------
        path : str or Path
            The ``.pvd`` file; frames must be in its folder ``NAME/``.
        entries : list of (float, str)
            Time and path relative to the collection's folder of every frame, in order.
        """
        writer = cls(path, resume=False)
        writer._fresh = False
        writer.entries = [(float(t), str(name)) for t, name in entries]
        if writer.entries:
            ext = Path(writer.entries[0][1]).suffix
            writer._class = next(c for c, (e, _) in _WRITERS.items() if e == ext)
        writer._write_collections()
        return writer

    def _write_collections(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        lines = [
            '<?xml version="1.0"?>',
            '<VTKFile type="Collection" version="1.0" byte_order="LittleEndian" '
            'header_type="UInt64">',
            "  <Collection>",
        ]
        for t, name in self.entries:
            lines.append(f'    <DataSet timestep="{_format_time(t)}" group="" part="0" '
                         f'file="{name}"/>')
        lines += ["  </Collection>", "</VTKFile>", ""]
        _atomic_write_text(self.path, "\n".join(lines))
        if self._class is not None:
            ext = _WRITERS[self._class][0]
            series = {
                "file-series-version": "1.0",
                "files": [{"name": name, "time": float(t)} for t, name in self.entries],
            }
            _atomic_write_text(self.path.with_name(f"{self.name}{ext}.series"),
                               json.dumps(series, indent=1) + "\n")


def read_collection(path: str | Path) -> list[tuple[float, str]]:
    """Times and relative file names listed by a ``.pvd`` or ``.series`` file.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    SeriesError
        If the file is not a valid collection.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such series file: {path}")
    # a list in memory takes about 30 times its text: refuse one that cannot fit
    limit = memory_limit() // 32
    if path.stat().st_size > limit:
        raise SeriesError(f"{path} is {format_bytes(path.stat().st_size)}, more than a "
                          f"collection of frames can be ({format_bytes(limit)}: 1/32 of the "
                          f"memory limit)")
    try:
        if path.suffix == ".series":
            doc = json.loads(path.read_text(encoding="utf-8"))
            entries = [(float(f["time"]), str(f["name"])) for f in doc["files"]]
        elif path.suffix == ".pvd":
            root = ET.parse(path).getroot()
            if root.get("type") != "Collection":
                raise SeriesError(f"{path} is not a VTK Collection file")
            entries = [(float(d.get("timestep", "0")), d.get("file")) for d in root.iter("DataSet")]
        else:
            raise SeriesError(f"a series file ends in .pvd or .series, got {path.name!r}")
    except (ET.ParseError, json.JSONDecodeError, KeyError, TypeError, ValueError,
            OverflowError, RecursionError) as exc:
        if isinstance(exc, SeriesError):
            raise
        raise SeriesError(f"{path} is not a valid series file: {exc}") from None
    except OSError as exc:
        raise SeriesError(f"{path} cannot be read: {exc.strerror or exc}") from None
    if any(name is None for _, name in entries):
        raise SeriesError(f"{path} lists a DataSet without a file")
    previous = -math.inf
    for index, (time, _) in enumerate(entries):
        if not (math.isfinite(time) and time > previous):
            raise SeriesError(f"{path} lists frame {index} at t = {time!r}: frame times must be "
                              f"finite and increasing")
        previous = time
    return entries


def validate_series(path: str | Path, on_frame: Callable[[int, vtkDataObject], object] | None = None
                    ) -> list[tuple[float, str]]:
    """Read a collection and every frame it lists; raise :class:`SeriesError` naming the first
    missing, truncated or corrupt one.  Returns the entries of :func:`read_collection`.

    ``on_frame(index, data)``, when given, sees each frame as it is read (one at a time), so
    that a caller can check what it needs of the input before any work starts."""
    path = Path(path)
    entries = read_collection(path)
    for index, (_, name) in enumerate(entries):
        data = read_frame(path.parent / name)
        if on_frame is not None:
            on_frame(index, data)
    return entries


def read_frame(path: str | Path) -> vtkDataObject:
    """Read one VTK XML file (``.vtp``, ``.vtu``, ``.vti``) with VTK's own reader."""
    path = Path(path)
    reader_class = _READERS.get(path.suffix)
    if reader_class is None:
        raise SeriesError(f"cannot read {path.name}: supported {sorted(_READERS)}")
    if not path.is_file():
        raise SeriesError(f"series frame {path} is missing")
    try:
        check_vtk_xml(path)  # declared sizes against the file and memory, before VTK allocates
    except UnsafeFileError as exc:
        raise SeriesError(f"series frame {exc}") from None
    except OSError as exc:
        raise SeriesError(f"series frame {path} cannot be read: {exc.strerror or exc}") from None
    reader = reader_class()
    with vtk_messages() as log:
        readable = reader.CanReadFile(str(path))
        if readable:
            reader.SetFileName(str(path))
            reader.Update()
    if not readable:
        raise SeriesError(f"series frame {path} is not a readable VTK XML file")
    if log.errors:
        raise SeriesError(f"series frame {path} is corrupt or truncated: {log.errors[0]}")
    data = reader.GetOutputDataObject(0)
    _check_frame_complete(reader, data, path)
    return data


def _check_frame_complete(reader, data, path) -> None:
    """Refuse a frame that VTK read without error but with less than its header declares."""
    n_points, n_cells = data.GetNumberOfPoints(), data.GetNumberOfCells()
    if hasattr(reader, "GetNumberOfPoints"):  # vtp / vtu: counts from the XML header
        if reader.GetNumberOfPoints() != n_points or reader.GetNumberOfCells() != n_cells:
            raise SeriesError(
                f"series frame {path} is truncated: its header declares "
                f"{reader.GetNumberOfPoints()} points and {reader.GetNumberOfCells()} cells, "
                f"{n_points} and {n_cells} could be read")
    for label, attributes, declared, count in (
            ("point", data.GetPointData(), reader.GetNumberOfPointArrays(), n_points),
            ("cell", data.GetCellData(), reader.GetNumberOfCellArrays(), n_cells)):
        if attributes.GetNumberOfArrays() != declared:
            raise SeriesError(f"series frame {path} is truncated: {declared} {label} arrays "
                              f"declared, {attributes.GetNumberOfArrays()} could be read")
        for i in range(attributes.GetNumberOfArrays()):
            array = attributes.GetAbstractArray(i)
            if array.GetNumberOfTuples() != count:
                raise SeriesError(
                    f"series frame {path} is corrupt: {label} array {array.GetName()!r} has "
                    f"{array.GetNumberOfTuples()} values for {count} {label}s")


def read_series(path: str | Path) -> tuple[NDArray[np.float64], list[DataSet]]:
    """Read a whole series.

    Parameters
    ----------
    path : str or Path
        A ``.pvd`` or ``.series`` file.

    Returns
    -------
    times : (F,) float64 array
        Frame times (s).
    datasets : list of pyvista.DataSet
        The frames, read with VTK's XML readers.
    """
    import pyvista as pv

    path = Path(path)
    entries = read_collection(path)
    datasets = [pv.wrap(read_frame(path.parent / name)) for _, name in entries]
    return np.array([t for t, _ in entries], dtype=np.float64), datasets
