"""One writer per output folder: a lock file holding the writer's pid and host.

``blobflow run`` and ``blobflow surface`` (and :meth:`pipeline.Flow.run`,
:func:`pipeline.tasks.map_frames`) hold the lock of their output folder while they write it.
A second writer is refused with :class:`FolderLockedError`, whose message names the process
that holds the folder, instead of the two deleting each other's frames.

The lock is the file ``.blobflow.lock`` in the folder, locked with ``flock(2)`` (taken
atomically by the kernel and released by it when the process ends, however it ends) and holding
``{"pid", "host", "command", "since"}`` for the message.  A lock file left by a process that
died (``kill -9``, a power cut) holds no ``flock`` and is taken over: stale locks recover by
themselves.  The lock is re-entrant within a process (a command that locks its folder may call
library functions that lock it again).
"""

from __future__ import annotations

import fcntl
import functools
import inspect
import json
import os
import socket
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Callable, Iterator
    from typing import Any

__all__ = ["LOCK_NAME", "FolderLockedError", "lock_folder", "holds_folder", "lock_owner"]

#: Name of the lock file in a locked folder.
LOCK_NAME = ".blobflow.lock"

_HELD: dict[str, list] = {}  # real path -> [file descriptor, count]
_GUARD = threading.Lock()


class FolderLockedError(RuntimeError):
    """Another process writes the folder (the message names it)."""


def lock_owner(folder: str | Path) -> dict | None:
    """What the lock file of ``folder`` says about its holder (``pid``, ``host``, ``command``,
    ``since``), or None when there is none or it cannot be read."""
    try:
        fd = os.open(Path(folder) / LOCK_NAME, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError:
        return None
    try:
        text = os.read(fd, 65536).decode("utf-8", "replace")
    finally:
        os.close(fd)
    try:
        owner = json.loads(text)
    except ValueError:
        return None
    return owner if isinstance(owner, dict) else None


def _describe(owner: dict | None) -> str:
    if not owner:
        return "another process (its lock file is being written)"
    since = owner.get("since")
    when = (time.strftime(" since %Y-%m-%d %H:%M:%S", time.localtime(since))
            if isinstance(since, (int, float)) else "")
    return (f"{owner.get('command') or 'blobflow'} (pid {owner.get('pid')} on host "
            f"{owner.get('host')}{when})")


def _acquire(folder: Path) -> int:
    path = folder / LOCK_NAME
    for _ in range(100):  # another process may remove the file between our open and lock
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
        except OSError as exc:
            if path.is_symlink():
                raise FolderLockedError(f"{path} is a symbolic link, not blobflow's lock "
                                        f"file: remove it") from None
            raise FolderLockedError(f"cannot create the lock file {path}: "
                                    f"{exc.strerror or exc}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise FolderLockedError(
                f"output folder {folder} is being written by {_describe(lock_owner(folder))}; "
                f"wait for it to finish or choose another folder") from None
        except OSError as exc:
            os.close(fd)
            raise FolderLockedError(f"cannot lock {path}: {exc.strerror or exc}") from None
        try:
            same = os.fstat(fd).st_ino == os.stat(path, follow_symlinks=False).st_ino
        except FileNotFoundError:
            same = False
        if not same:  # the holder removed the file as we opened it: lock the new one
            os.close(fd)
            continue
        record = {"pid": os.getpid(), "host": socket.gethostname(),
                  "command": " ".join(["blobflow", *sys.argv[1:3]]) if sys.argv else "blobflow",
                  "since": time.time()}
        os.ftruncate(fd, 0)
        os.pwrite(fd, (json.dumps(record) + "\n").encode(), 0)
        return fd
    raise FolderLockedError(f"cannot take the lock {path}: it keeps changing")


def _release(folder: Path, fd: int) -> None:
    try:
        os.unlink(folder / LOCK_NAME)  # while locked: a waiting process sees the file go
    except OSError:
        pass
    os.close(fd)


@contextmanager
def lock_folder(folder: str | Path) -> Iterator[Path]:
    """Hold the lock of ``folder`` (created if missing) while the block runs.

    Folders created for the lock are removed again when the block leaves them empty (a
    command refused after taking the lock leaves nothing behind).

    Raises
    ------
    FolderLockedError
        If another process holds it; the message names that process (pid, host, command).
    """
    folder = Path(folder)
    missing = []  # folders this call creates, removed again if they are left empty
    probe = folder
    while not probe.exists() and probe != probe.parent:
        missing.append(probe)
        probe = probe.parent
    folder.mkdir(parents=True, exist_ok=True)
    key = os.path.realpath(folder)
    with _GUARD:
        held = _HELD.get(key)
        if held is not None:
            held[1] += 1
        else:
            try:
                _HELD[key] = [_acquire(folder), 1]
            except BaseException:
                _remove_empty(missing)
                raise
    try:
        yield folder
    finally:
        with _GUARD:
            held = _HELD[key]
            held[1] -= 1
            if held[1] == 0:
                del _HELD[key]
                _release(folder, held[0])
                _remove_empty(missing)


def _remove_empty(folders) -> None:
    """Remove the folders a lock created, deepest first, where nothing was written in them."""
    for created in folders:
        try:
            created.rmdir()
        except OSError:
            return


def holds_folder(argument: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Decorator: hold the lock of the folder given as ``argument`` while the function runs
    (for a ``.pvd`` path, the folder that holds it)."""
    def decorate(function):
        signature = inspect.signature(function)

        @functools.wraps(function)
        def wrapper(*args, **kwargs):
            bound = signature.bind(*args, **kwargs)
            target = Path(bound.arguments[argument])
            folder = target.parent if target.suffix == ".pvd" else target
            with lock_folder(folder):
                return function(*args, **kwargs)
        return wrapper
    return decorate
