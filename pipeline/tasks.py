"""Frame-parallel work on a written series: serially, or on a Dask cluster.

A simulation runs forward in time on one machine, but turning its particle frames into surfaces, or
rendering them, is one independent task per frame.  :func:`map_frames` runs such tasks in order
here, or on a ``dask.distributed`` cluster (an existing one, or a ``LocalCluster``) when given a
client, and:

* writes every frame atomically, so a frame on disk is always complete;
* writes the collection file (``.pvd`` + ``.series``) once, after every frame is done;
* lets Dask retry a failed task, reports a frame that fails twice by number with its error, and
  leaves the frames that succeeded on disk, so ``resume=True`` only does what is missing;
* produces byte-identical files whether it runs serially or in parallel (the tasks are
  deterministic and each one writes its own file).

Dask is optional (``pip install blobflow[dask]``): nothing here imports it unless a client or a
cluster is asked for.
"""

from __future__ import annotations

import os
import resource
import socket
import struct
import threading
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from tqdm.auto import tqdm

from .io.folderlock import holds_folder
from .io.outfiles import frames_folder, remove_frames, sweep_temporaries
from .io.series import SeriesWriter, read_collection, read_frame

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    from dask.distributed import Client

__all__ = [
    "FrameFailure",
    "FramesError",
    "FramesResult",
    "map_frames",
    "run_tasks",
    "frame_done",
    "connect",
    "SchedulerError",
    "CONNECT_TIMEOUT",
    "PROBE_TIMEOUT",
]


class SchedulerError(RuntimeError):
    """The Dask scheduler cannot be reached, or Dask is not installed."""


@dataclass(frozen=True)
class FrameFailure:
    """A frame whose task failed on every attempt."""

    index: int
    time: float
    error: str


class FramesError(RuntimeError):
    """Some frames failed; the others are on disk and ``resume=True`` retries only the failed."""

    def __init__(self, failures: list[FrameFailure], output: Path):
        self.failures = failures
        self.output = output
        listed = "; ".join(f"frame {f.index} (t = {f.time:g} s): {f.error}" for f in failures[:5])
        more = f"; and {len(failures) - 5} more" if len(failures) > 5 else ""
        super().__init__(f"{len(failures)} frame(s) failed: {listed}{more}")


@dataclass
class FramesResult:
    """What :func:`map_frames` did.

    Attributes
    ----------
    path : Path
        The collection written.
    computed, skipped : int
        Frames computed now, and frames already on disk (``resume``).
    peak_memory : dict of str to int
        Peak resident memory (bytes) of every process that ran a task, by ``host:pid``.
    """

    path: Path
    computed: int = 0
    skipped: int = 0
    peak_memory: dict = field(default_factory=dict)


def _peak_rss() -> int:
    # ru_maxrss is in KiB on Linux.
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024


def frame_done(path: Path) -> bool:
    """Whether ``path`` is a frame on disk that reads back (else it is to be computed)."""
    if not path.is_file():
        return False
    try:
        read_frame(path)
        return True
    except Exception:  # noqa: BLE001 - an unreadable frame is simply redone
        return False


def _run_task(task, in_file: str, out_file: str, time: float, options: dict) -> dict:
    """Run one frame's task in this process; return who ran it and its peak memory."""
    task(in_file, out_file, time, options)
    return {"worker": f"{socket.gethostname()}:{os.getpid()}", "peak_rss": _peak_rss()}


#: Largest first message (bytes) a Dask scheduler's handshake is taken to have.
_HANDSHAKE_LIMIT = 2**20


#: Seconds a scheduler has to send its whole handshake (:func:`_probe_scheduler`).
PROBE_TIMEOUT = 5.0


def _probe_scheduler(address: str, timeout: float | None = None) -> None:
    """Check that a ``tcp://`` address answers like a Dask scheduler, before Dask connects.

    A Dask server writes a handshake as soon as it accepts a connection: an 8-byte
    little-endian length, that many bytes (a frame count, the frames' lengths and the frames
    that fit), then the frames that did not.  Dask's own client trusts those lengths and waits
    for them without a deadline, so a server that sends nothing (an HTTP server), other bytes,
    or a part of a handshake and then nothing, keeps it waiting forever or makes it allocate
    whatever the bytes encode.  This probe reads the whole handshake within ``timeout``
    seconds in all and refuses anything else with one clear message.
    """
    scheme, _, rest = address.rpartition("://")
    if scheme not in ("", "tcp"):
        return  # tls://, ucx://, inproc://: left to Dask
    host, _, port_text = rest.rpartition(":")
    host = host.strip("[]")
    try:
        port = int(port_text)
    except ValueError:
        raise SchedulerError(f"scheduler address must be tcp://host:port, "
                             f"got {address!r}") from None
    if not host or not 0 < port < 65536:
        raise SchedulerError(f"scheduler address must be tcp://host:port, got {address!r}")
    timeout = PROBE_TIMEOUT if timeout is None else timeout
    deadline = time.monotonic() + timeout
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except (OSError, UnicodeError) as exc:
        raise SchedulerError(f"cannot reach the Dask scheduler at {address}: "
                             f"{getattr(exc, 'strerror', None) or exc}") from None
    not_dask = f"{address} does not speak Dask's protocol: not a Dask scheduler"

    def receive(n: int, what: str) -> bytes:
        data = b""
        while len(data) < n:
            left = deadline - time.monotonic()
            if left <= 0:
                raise SchedulerError(f"{address} sent {what} within {timeout:g} s: not a "
                                     f"Dask scheduler")
            sock.settimeout(left)
            try:
                chunk = sock.recv(min(n - len(data), 1 << 16))
            except OSError:  # socket.timeout included
                continue
            if not chunk:
                raise SchedulerError(f"{address} closed the connection without a Dask "
                                     f"handshake: not a Dask scheduler")
            data += chunk
        return data

    with sock:
        (size,) = struct.unpack("<Q", receive(8, "no Dask handshake"))
        if not 16 <= size <= _HANDSHAKE_LIMIT:
            raise SchedulerError(f"{not_dask} (its first message claims {size} bytes)")
        block = receive(size, "only a part of a Dask handshake")
        (count,) = struct.unpack_from("<Q", block)
        if not 1 <= count <= 64 or 8 * (1 + count) > size:
            raise SchedulerError(f"{not_dask} (its first message claims {count} frames)")
        lengths = struct.unpack_from(f"<{count}Q", block, 8)
        if sum(lengths) > _HANDSHAKE_LIMIT:
            raise SchedulerError(f"{not_dask} (its first message claims {sum(lengths)} bytes)")
        missing = max(sum(lengths) - (size - 8 * (1 + count)), 0)
        receive(missing, "only a part of a Dask handshake")


#: Seconds a Dask client may take to connect, handshake and register with a scheduler.
CONNECT_TIMEOUT = 10.0


def _client_within(scheduler: str, timeout: float):
    """``Client(scheduler)``, given up after ``timeout`` seconds whatever the server does.

    Dask's own ``timeout`` covers the connection but not every later step of its start (a
    server may answer the handshake and then nothing): the client starts in a thread that is
    abandoned, and reported, when it is late."""
    from dask.distributed import Client

    box: dict = {}

    def start():
        try:
            box["client"] = Client(scheduler, timeout=f"{timeout:g}s")
        except BaseException as exc:  # noqa: BLE001 - handed to the caller
            box["error"] = exc

    thread = threading.Thread(target=start, daemon=True, name="blobflow-dask-connect")
    thread.start()
    thread.join(timeout + 5.0)
    if thread.is_alive():
        raise SchedulerError(f"the Dask scheduler at {scheduler} did not finish connecting "
                             f"within {timeout + 5.0:g} s")
    if "error" in box:
        exc = box["error"]
        if isinstance(exc, (OSError, TimeoutError, ValueError, TypeError)):
            raise SchedulerError(f"cannot reach the Dask scheduler at {scheduler}: "
                                 f"{exc}") from None
        raise exc
    return box["client"]


def connect(scheduler: str | None = None, workers: int | None = None) -> Client:
    """A Dask client: to ``scheduler`` (``tcp://host:port``), or to a new ``LocalCluster``.

    Parameters
    ----------
    scheduler : str, optional
        Address of an existing scheduler; its workers must see the same file paths.
    workers : int, optional
        Start a local cluster of this many single-threaded worker processes.

    Raises
    ------
    SchedulerError
        If Dask is not installed, the address does not send a whole Dask handshake within
        :data:`PROBE_TIMEOUT` seconds, or the client has not started
        :data:`CONNECT_TIMEOUT` + 5 seconds later.
    ValueError
        For ``workers < 1`` or both arguments.
    """
    if scheduler is not None and workers is not None:
        raise ValueError("give either scheduler or workers, not both")
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise SchedulerError("Dask is not installed: pip install 'blobflow[dask]'") from None
    if scheduler is not None:
        _probe_scheduler(scheduler)
        return _client_within(scheduler, CONNECT_TIMEOUT)
    # One thread per worker process; Numba's own threads pinned to one so that N workers use N
    # cores instead of fighting over them.
    cluster = LocalCluster(n_workers=workers or 1, threads_per_worker=1, processes=True,
                           dashboard_address=":0", host="127.0.0.1",
                           env={"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
                                "OPENBLAS_NUM_THREADS": "1"})
    return Client(cluster)


def run_tasks(jobs: Sequence[tuple[int, float, tuple]], *, client: Client | None = None,
              retries: int = 1, progress: bool = True, desc: str = "frames",
              total: int | None = None, initial: int = 0) -> tuple[list[dict], list[FrameFailure]]:
    """Run ``_run_task(*args)`` for every ``(index, time, args)`` job, here or on ``client``.

    Returns
    -------
    infos : list of dict
        What each successful task returned (who ran it, its peak memory).
    failures : list of FrameFailure
        Jobs that failed on every attempt, by index.
    """
    infos, failures = [], []
    bar = tqdm(total=total if total is not None else len(jobs), initial=initial, unit="frame",
               disable=not progress, desc=desc)
    try:
        if client is None:
            for i, t, args in jobs:
                for attempt in range(retries + 1):
                    try:
                        infos.append(_run_task(*args))
                        bar.update(1)
                        break
                    except Exception as exc:  # noqa: BLE001 - reported per frame
                        if attempt == retries:
                            failures.append(FrameFailure(i, t, f"{type(exc).__name__}: {exc}"))
        else:
            from dask.distributed import as_completed

            token = uuid.uuid4().hex[:8]  # unique keys: Dask would reuse an equal key's result
            futures = {client.submit(_run_task, *args, retries=retries, pure=False,
                                     key=f"{desc}-{i}-{token}"): (i, t) for i, t, args in jobs}
            for future in as_completed(futures):
                i, t = futures[future]
                try:
                    # result(), not the status: a finished result held by a worker that dies
                    # right after is lost and recomputed, and result() waits for that
                    info = future.result()
                except Exception as exc:  # noqa: BLE001 - reported per frame
                    failures.append(FrameFailure(i, t, f"{type(exc).__name__}: {exc}"))
                else:
                    infos.append(info)
                    bar.update(1)
    finally:
        bar.close()
    return infos, sorted(failures, key=lambda f: f.index)


@holds_folder("output_path")  # one writer per folder (re-entrant: the CLI holds it too)
def map_frames(input_path: str | Path, output_path: str | Path,
               task: Callable[[str, str, float, dict], object], options: dict | None = None, *,
               client: Client | None = None, resume: bool = False, progress: bool = True,
               retries: int = 1, extension: str = ".vtp") -> FramesResult:
    """Run ``task`` on every frame of a series and write the results as a new series.

    Parameters
    ----------
    input_path : str or Path
        A ``.pvd`` or ``.series`` collection.
    output_path : str or Path
        The ``.pvd`` to write; frames go to its folder ``NAME/NAME_%06d.EXT``.
    task : callable
        ``task(in_file, out_file, time, options)``, importable by name (Dask pickles it): reads
        ``in_file``, writes ``out_file`` atomically (e.g. with
        :func:`pipeline.io.series.write_frame`).
    options : dict, optional
        Passed to every task.
    client : dask.distributed.Client, optional
        Run on this cluster; serially here when omitted.
    resume : bool
        Skip frames already on disk and readable.
    retries : int
        Extra attempts for a failed task (Dask's ``retries``; done here when serial).
    extension : str
        Extension of the frames the task writes.

    Raises
    ------
    FramesError
        If some frames failed on every attempt; the successful frames stay on disk and no
        collection file is written.
    pipeline.io.folderlock.FolderLockedError
        If another process writes the output folder.
    pipeline.io.outfiles.OwnershipError
        If the frames folder is a symbolic link, a file or another mount.
    """
    input_path = Path(input_path)
    output_path = Path(output_path)
    if output_path.suffix != ".pvd":
        raise ValueError(f"output_path must end in .pvd, got {str(output_path)!r}")
    options = dict(options or {})
    entries = read_collection(input_path)
    name = output_path.stem
    frames_dir = frames_folder(output_path.parent, name, create=True)  # a link is refused
    jobs, done_entries = [], []
    result = FramesResult(output_path)
    if not resume:
        # a fresh run leaves no frame of another run beside its own, removed by the one rule
        # of pipeline.io.outfiles (NAME_<digits>.vt?, nothing else: the user's files stay)
        remove_frames(frames_dir, name)
    sweep_temporaries(frames_dir)
    for i, (t, rel) in enumerate(entries):
        out_rel = f"{name}/{name}_{i:06d}{extension}"
        out_file = output_path.parent / out_rel
        done_entries.append((t, out_rel))
        if resume and frame_done(out_file):
            result.skipped += 1
            continue
        jobs.append((i, t, str(input_path.parent / rel), str(out_file)))
    infos, failures = run_tasks(
        [(i, t, (task, in_file, out_file, t, options)) for i, t, in_file, out_file in jobs],
        client=client, retries=retries, progress=progress, desc=name, total=len(entries),
        initial=result.skipped)
    result.computed = len(infos)
    for info in infos:
        key = info["worker"]
        result.peak_memory[key] = max(result.peak_memory.get(key, 0), info["peak_rss"])
    if failures:
        raise FramesError(sorted(failures, key=lambda f: f.index), output_path)
    SeriesWriter.from_files(output_path, done_entries)
    return result
