"""What blobflow writes in an output folder, and the one rule by which it removes anything.

Every writer and every clean-up goes through this module, so that only files blobflow wrote are
ever removed:

* a series ``NAME`` is ``NAME.pvd``, ``NAME.vtp.series`` (``.vtu``/``.vti``), ``NAME.xdmf``,
  ``NAME.h5``, ``NAME.source.json`` (what a surface series was computed from),
  ``NAME.checkpoint.npz`` (a run's checkpoint) and its frames ``NAME/NAME_<digits>.vtp``
  (``.vtu``/``.vti``): a frame is removed only when its name matches :func:`is_frame_name` exactly
  (never every ``NAME_*``), and the frames folder only when it is left empty;
* a file is written under a temporary name unique to the process (:func:`temporary_path`:
  ``.NAME.HOST-PID-TOKEN.tmp.SUFFIX``) and renamed into place (:func:`atomic_path`), which removes
  the temporary file when the writing fails or is interrupted; temporaries of processes that no
  longer run are swept by :func:`sweep_temporaries`;
* a sub-folder blobflow writes into must be a real folder of the output folder:
  :func:`frames_folder` refuses a symbolic link, a file, or a folder on another file system (a
  mount), instead of following it into somebody else's files.
"""

from __future__ import annotations

import hashlib
import os
import re
import secrets
import socket
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Iterable, Iterator

__all__ = ["OwnershipError", "FRAME_SUFFIXES", "is_frame_name", "frame_names",
           "frames_folder", "remove_frames", "remove_series", "series_files",
           "temporary_path", "atomic_path", "is_temporary_name", "sweep_temporaries"]

#: Extensions of the frames blobflow writes.
FRAME_SUFFIXES = (".vtp", ".vtu", ".vti")

_TEMPORARY = re.compile(r"^\..+\.([0-9a-f]{4})-(\d+)-[0-9a-f]{8}\.tmp(\.[A-Za-z0-9]+)?$")


def _host_tag() -> str:
    """Four hex digits naming this machine in temporary names (a shared folder may be written
    from several machines; only this one's processes can be checked)."""
    return hashlib.sha1(socket.gethostname().encode()).hexdigest()[:4]


class OwnershipError(ValueError):
    """A path blobflow would write or clean is not its own (a link, a file, another mount)."""


def is_frame_name(file_name: str, name: str) -> bool:
    """Whether ``file_name`` is a frame of the series ``name``: ``NAME_<digits>.vt[pui]``."""
    return re.fullmatch(rf"{re.escape(name)}_\d+\.vt[pui]", file_name) is not None


def frame_names(folder: Path, name: str) -> list[Path]:
    """The frames of series ``name`` in ``folder`` (plain files matching
    :func:`is_frame_name`), sorted; none when the folder does not exist."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir()
                  if is_frame_name(p.name, name) and (p.is_symlink() or p.is_file()))


def frames_folder(directory: str | Path, name: str, *, create: bool = False) -> Path:
    """The frames folder ``directory/name`` of a series, checked to be blobflow's to use.

    Raises
    ------
    OwnershipError
        If it is a symbolic link, not a folder, or on another file system than
        ``directory`` (a mount point): a run must not follow it into other files.
    """
    directory = Path(directory)
    folder = directory / name
    if folder.is_symlink():
        raise OwnershipError(f"{folder} is a symbolic link (to {os.readlink(folder)}); blobflow "
                             f"writes its frames only into a folder of its own: remove the link "
                             f"or choose another --out")
    if folder.exists():
        if not folder.is_dir():
            raise OwnershipError(f"{folder} is not a folder; blobflow needs that name for the "
                                 f"frames of series {name!r}: move it or choose another --out")
        if directory.is_dir() and os.stat(folder).st_dev != os.stat(directory).st_dev:
            raise OwnershipError(f"{folder} is another file system mounted in the output "
                                 f"folder; blobflow does not write its frames there")
    elif create:
        folder.mkdir(parents=True, exist_ok=True)
    return folder


def remove_frames(folder: str | Path, name: str, keep: Iterable[str] = ()) -> int:
    """Remove the frames of series ``name`` from ``folder`` except the file names in ``keep``.

    Only names matching :func:`is_frame_name` are touched. Returns how many were removed.
    """
    keep = set(keep)
    removed = 0
    for path in frame_names(Path(folder), name):
        if path.name not in keep:
            path.unlink(missing_ok=True)
            removed += 1
    return removed


def series_files(directory: str | Path, name: str) -> list[Path]:
    """The files of series ``name`` directly in ``directory`` (collections, XDMF) that exist."""
    directory = Path(directory)
    names = [f"{name}.pvd", f"{name}.xdmf", f"{name}.h5", f"{name}.source.json",
             f"{name}.checkpoint.npz",
             *(f"{name}{suffix}.series" for suffix in FRAME_SUFFIXES)]
    return [directory / n for n in names if (directory / n).is_file()
            or (directory / n).is_symlink()]


def remove_series(directory: str | Path, name: str) -> None:
    """Remove series ``name`` from ``directory``: its collection files, its frames, and its
    frames folder when nothing else is left in it (other files there are kept)."""
    directory = Path(directory)
    folder = frames_folder(directory, name)
    for path in series_files(directory, name):
        path.unlink(missing_ok=True)
    if folder.is_dir():
        remove_frames(folder, name)
        sweep_temporaries(folder)
        try:
            folder.rmdir()
        except OSError:  # not empty: files that are not blobflow's stay
            pass


def temporary_path(path: str | Path) -> Path:
    """A temporary name beside ``path``, unique to this process and call:
    ``.NAME.HOST-PID-TOKEN.tmp.SUFFIX`` (the suffix kept, so writers that choose a format by it
    still do)."""
    path = Path(path)
    token = secrets.token_hex(4)
    return path.with_name(f".{path.stem}.{_host_tag()}-{os.getpid()}-{token}.tmp{path.suffix}")


def is_temporary_name(file_name: str) -> bool:
    """Whether ``file_name`` is a name :func:`temporary_path` makes."""
    return _TEMPORARY.match(file_name) is not None


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Write ``path`` atomically: yields a temporary path to write, renamed to ``path`` when
    the block ends normally and removed when it raises (an error, Ctrl-C, a termination)."""
    path = Path(path)
    tmp = temporary_path(path)
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if tmp.exists() or tmp.is_symlink():
            tmp.unlink(missing_ok=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return pid > 0  # someone else's process (or a pid not representable): leave its files
    return True


def sweep_temporaries(folder: str | Path) -> int:
    """Remove the temporary files (:func:`temporary_path`) in ``folder`` whose process no
    no longer runs on this machine (a run killed with ``kill -9``); returns how many were
    removed."""
    folder = Path(folder)
    if not folder.is_dir() or folder.is_symlink():
        return 0
    removed, host = 0, _host_tag()
    for path in folder.iterdir():
        match = _TEMPORARY.match(path.name)
        if (match and match.group(1) == host and int(match.group(2)) != os.getpid()
                and not _alive(int(match.group(2)))):
            if path.is_file() or path.is_symlink():
                path.unlink(missing_ok=True)
                removed += 1
    return removed
