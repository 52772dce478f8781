"""The checkpoint of a run: one file beside its series, from which the run resumes.

A :class:`~pipeline.compose.Flow` run keeps the simulation's state in ``NAME.checkpoint.npz``
beside the series ``NAME.pvd`` of its first output (``particles.checkpoint.npz``), rewritten
every few frames and at the end.  The frames carry what a viewer needs; the state (positions,
velocities and every extra array of :class:`filters.State`, bit for bit) is in this one file.

The file is a NumPy ``.npz`` archive of plain numeric arrays (its bytes depend on the state only),
written to a temporary file, flushed to disk and renamed over the previous one, so the previous
checkpoint stays whole until the new one is complete.  It is read with ``allow_pickle=False`` and
every member must be a numeric array: nothing in it is ever executed.  Besides ``state:NAME`` arrays
(:meth:`filters.State.to_arrays`) it holds:

* ``format``: (1,) int64, the layout version (1);
* ``frame``: (1,) int64, the index of the frame the state belongs to, and ``time``: (1,)
  float64, that frame's time (s);
* ``digest:SERIES``: (32,) uint8, the SHA-256 of that frame's file in every written series, so
  that a checkpoint is used only with the very frames it was written with.
"""

from __future__ import annotations

import hashlib
import math
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from filters.simulation import State

from .outfiles import atomic_path

__all__ = [
    "Checkpoint",
    "CheckpointError",
    "CHECKPOINT_SUFFIX",
    "checkpoint_path",
    "file_digest",
    "read_checkpoint",
    "write_checkpoint",
]

#: The checkpoint of the series ``DIR/NAME.pvd`` is ``DIR/NAME`` + this suffix.
CHECKPOINT_SUFFIX = ".checkpoint.npz"
_FORMAT = 1
_STATE = "state:"
_DIGEST = "digest:"


class CheckpointError(ValueError):
    """A checkpoint file is unreadable, damaged, or not one blobflow wrote."""


@dataclass
class Checkpoint:
    """A simulation state and the frame it belongs to.

    Attributes
    ----------
    state : filters.State
        The state after frame ``frame`` was made.
    frame : int
        Index of that frame in the series (>= 0).
    time : float
        Its time (s).
    digests : dict of str to bytes
        SHA-256 of that frame's file in every written series, by series name.
    """

    state: State
    frame: int
    time: float
    digests: dict = field(default_factory=dict)


def checkpoint_path(series: str | Path) -> Path:
    """The checkpoint file beside a series: ``DIR/NAME.pvd`` (or ``DIR/NAME.vtp.series``) ->
    ``DIR/NAME.checkpoint.npz``."""
    series = Path(series)
    name = series.name.split(".")[0]
    return series.with_name(name + CHECKPOINT_SUFFIX)


def file_digest(path: str | Path) -> bytes:
    """SHA-256 of a file's bytes (32 bytes)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.digest()


def write_checkpoint(path: str | Path, checkpoint: Checkpoint) -> Path:
    """Write ``checkpoint`` to ``path`` atomically (temporary file, fsync, rename).

    Parameters
    ----------
    path : str or Path
        The ``.npz`` file; an existing one is replaced only once the new one is on disk.
    checkpoint : Checkpoint

    Returns
    -------
    Path
    """
    path = Path(path)
    if not isinstance(checkpoint.state, State):
        raise TypeError(f"checkpoint.state must be a filters.State, got "
                        f"{type(checkpoint.state).__name__}")
    arrays = {"format": np.array([_FORMAT], dtype=np.int64),
              "frame": np.array([int(checkpoint.frame)], dtype=np.int64),
              "time": np.array([float(checkpoint.time)], dtype=np.float64)}
    for name, digest in checkpoint.digests.items():
        arrays[_DIGEST + name] = np.frombuffer(bytes(digest), dtype=np.uint8).copy()
    for name, values in checkpoint.state.to_arrays().items():
        values = np.ascontiguousarray(values)
        if values.dtype.kind not in "biuf":
            raise TypeError(f"state array {name!r} has dtype {values.dtype}: a checkpoint holds "
                            f"numeric arrays only")
        arrays[_STATE + name] = values
    path.parent.mkdir(parents=True, exist_ok=True)
    # a temporary name of this process (pipeline.io.outfiles): two writers never share one, and
    # a killed run's leftover is swept by the next
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        _write_npz(f, arrays)
        f.flush()
        os.fsync(f.fileno())
    return path


def _write_npz(f, arrays: dict) -> None:
    """An ``.npz`` archive (what ``np.load`` reads) whose bytes depend only on ``arrays``:
    members in the given order, stored, with a fixed date (``np.savez`` stamps the clock), so
    that a resumed run ends with the same checkpoint file as an uninterrupted one."""
    with zipfile.ZipFile(f, "w", compression=zipfile.ZIP_STORED, allowZip64=True) as archive:
        for name, values in arrays.items():
            info = zipfile.ZipInfo(name + ".npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.external_attr = 0o644 << 16
            with archive.open(info, "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(values), allow_pickle=False)


def _scalar(arrays: dict, name: str, kind: str):
    value = arrays.get(name)
    if value is None or value.shape != (1,) or value.dtype.kind not in kind:
        raise CheckpointError(f"its {name!r} entry is missing or malformed")
    return value[0]


def read_checkpoint(path: str | Path) -> Checkpoint:
    """Read a checkpoint written by :func:`write_checkpoint`, refusing anything else.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    CheckpointError
        If the file is not a complete checkpoint: not an ``.npz`` archive, a member that is
        not a numeric array (an object array would need pickle, which is never allowed), or
        a state that :meth:`filters.State.from_arrays` refuses (wrong shapes, non-finite
        positions or velocities, a missing array).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no checkpoint at {path}")
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {name: archive[name] for name in archive.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as exc:
        raise CheckpointError(f"{path} is not a readable checkpoint: {exc}") from None
    try:
        for name, values in arrays.items():
            if values.dtype.kind not in "biuf":
                raise CheckpointError(f"its member {name!r} is not a numeric array")
        if int(_scalar(arrays, "format", "i")) != _FORMAT:
            raise CheckpointError(f"its format {int(arrays['format'][0])} is not {_FORMAT}")
        frame = int(_scalar(arrays, "frame", "i"))
        time = float(_scalar(arrays, "time", "f"))
        if frame < 0 or not math.isfinite(time):
            raise CheckpointError(f"it names frame {frame} at t = {time}")
        digests = {}
        for name, values in arrays.items():
            if name.startswith(_DIGEST):
                if values.shape != (32,) or values.dtype != np.uint8:
                    raise CheckpointError(f"its member {name!r} is not a SHA-256 digest")
                digests[name[len(_DIGEST):]] = values.tobytes()
        state_arrays = {name[len(_STATE):]: values for name, values in arrays.items()
                        if name.startswith(_STATE)}
        try:
            state = State.from_arrays(state_arrays)
        except (ValueError, TypeError) as exc:
            raise CheckpointError(f"its state is invalid: {exc}") from None
        if state.time != time:
            raise CheckpointError(f"its state is at t = {state.time}, its frame at t = {time}")
    except CheckpointError as exc:
        raise CheckpointError(f"{path} is not a valid checkpoint: {exc}") from None
    return Checkpoint(state, frame, time, digests)
