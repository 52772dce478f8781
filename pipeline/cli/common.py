"""Pieces every ``blobflow`` command shares (:mod:`pipeline.cli`, :mod:`pipeline.cli.surface`):
the usage error reported as one line with exit code 2, the Dask cluster options, the check that
an output folder can be written."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from argparse import ArgumentParser, Namespace

    from dask.distributed import Client

    from ..tasks import FramesResult

__all__ = ["UsageError", "add_cluster_options", "client", "close_client", "report_memory",
           "check_writable", "check_name_length", "check_workers", "max_workers", "cores",
           "WORKER_MEMORY"]


class UsageError(Exception):
    """A mistake of the user's: reported as one line, exit code 2."""


def add_cluster_options(parser: ArgumentParser) -> None:
    """``--workers N`` or ``--scheduler ADDRESS`` (frames on a Dask cluster), one of them."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--workers", type=int, metavar="N",
                       help="run frames in parallel on a local Dask cluster of N processes")
    group.add_argument("--scheduler", metavar="ADDRESS",
                       help="run frames on an existing Dask cluster (tcp://host:port); its "
                            "workers must see the same paths")


#: Memory (bytes) one local worker process takes before it holds a frame: Python, NumPy, VTK
#: and the compiled kernels (measured: about 250 MiB).
WORKER_MEMORY = 256 * 2**20


def cores() -> int:
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def max_workers() -> tuple[int, str]:
    """The most local worker processes this machine can run, and why: two per core (more only
    queue for the cores) and as many as the memory limit holds at :data:`WORKER_MEMORY`
    each."""
    from filters.memory import format_bytes, memory_limit

    by_cores = 2 * cores()
    by_memory = max(int(memory_limit() // WORKER_MEMORY), 1)
    if by_memory < by_cores:
        return by_memory, (f"the memory limit of {format_bytes(memory_limit())} holds "
                           f"{by_memory} workers of about {format_bytes(WORKER_MEMORY)} each")
    return by_cores, f"this machine has {cores()} cores (at most two workers each)"


def check_workers(args: Namespace) -> None:
    """Refuse ``--workers`` below 1 or above :func:`max_workers`, with the limit and why."""
    if args.workers is None:
        return
    if args.workers < 1:
        raise UsageError(f"--workers must be >= 1, got {args.workers}")
    limit, why = max_workers()
    if args.workers > limit:
        raise UsageError(f"--workers {args.workers} is more than {limit}: {why}")


def client(args: Namespace) -> Client | None:
    """The Dask client the options ask for, or None (serial); one-line errors."""
    if args.workers is None and args.scheduler is None:
        return None
    check_workers(args)
    from ..tasks import SchedulerError, connect

    try:
        return connect(scheduler=args.scheduler, workers=args.workers)
    except (SchedulerError, ValueError) as exc:
        raise UsageError(str(exc)) from None


def close_client(client: Client | None) -> None:
    """Close a client of :func:`client` and the local cluster it started, if any."""
    if client is not None:
        cluster = getattr(client, "cluster", None)
        client.close()
        if cluster is not None:
            cluster.close()


def report_memory(result: FramesResult) -> None:
    """Print the largest peak memory of the workers of a :class:`pipeline.tasks.FramesResult`."""
    if result.peak_memory:
        worst = max(result.peak_memory.values()) / 2**20
        print(f"peak memory per worker: up to {worst:.0f} MiB over {len(result.peak_memory)} "
              f"process(es)")


def check_writable(directory: Path) -> None:
    """Fail early, with one line, if ``directory`` cannot be created or written.

    Tries for real (``os.access`` says yes to root under ``/sys`` and ``/proc``): creates the
    missing folders and a temporary file, then removes what it created.
    """
    created = []
    try:
        probe = directory
        while not probe.exists():
            probe = probe.parent
        if not probe.is_dir():
            raise UsageError(f"cannot create output folder {directory}: {probe} is not a folder")
        missing = [directory, *directory.parents][: len(directory.parts) - len(probe.parts)]
        for folder in reversed(missing):
            folder.mkdir()
            created.append(folder)
        with tempfile.TemporaryFile(dir=directory):
            pass
    except OSError as exc:
        raise UsageError(f"output folder {_short(directory)} cannot be written: "
                         f"{exc.strerror or exc}") from None
    finally:
        for folder in reversed(created):
            try:
                folder.rmdir()
            except OSError:
                pass


def _short(path) -> str:
    text = str(path)
    return text if len(text) <= 160 else f"{text[:80]}...{text[-60:]}"


def check_name_length(directory: Path, name: str, longest_suffix: str, flag: str) -> None:
    """Refuse, with one line, a series name whose files would exceed the file system's limit
    on a name's length (``NAME_000000.vtp.series``...)."""
    probe = Path(directory)
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    try:
        limit = os.pathconf(probe, "PC_NAME_MAX")
    except (OSError, ValueError):
        limit = 255
    longest = len(name.encode()) + len(longest_suffix)
    if longest > limit:
        raise UsageError(f"{flag} is {len(name)} characters long: the file names made from it "
                         f"(up to {longest} bytes) exceed this file system's limit of {limit}")
