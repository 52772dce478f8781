"""Pieces every ``blobflow`` command shares (:mod:`pipeline.cli`, :mod:`pipeline.cli_surface`):
the usage error reported as one line with exit code 2, the Dask cluster options, the check that
an output folder can be written."""

from __future__ import annotations

import tempfile
from pathlib import Path

__all__ = ["UsageError", "add_cluster_options", "client", "close_client", "report_memory",
           "check_writable"]


class UsageError(Exception):
    """A mistake of the user's: reported as one line, exit code 2."""


def add_cluster_options(parser) -> None:
    """``--workers N`` or ``--scheduler ADDRESS`` (frames on a Dask cluster), one of them."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--workers", type=int, metavar="N",
                       help="run frames in parallel on a local Dask cluster of N processes")
    group.add_argument("--scheduler", metavar="ADDRESS",
                       help="run frames on an existing Dask cluster (tcp://host:port); its "
                            "workers must see the same paths")


def client(args):
    """The Dask client the options ask for, or None (serial); one-line errors."""
    if args.workers is None and args.scheduler is None:
        return None
    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers must be >= 1, got {args.workers}")
    from .frames import SchedulerError, connect

    try:
        return connect(scheduler=args.scheduler, workers=args.workers)
    except (SchedulerError, ValueError) as exc:
        raise UsageError(str(exc)) from None


def close_client(client) -> None:
    """Close a client of :func:`client` and the local cluster it started, if any."""
    if client is not None:
        cluster = getattr(client, "cluster", None)
        client.close()
        if cluster is not None:
            cluster.close()


def report_memory(result) -> None:
    """Print the largest peak memory of the workers of a :class:`pipeline.frames` result."""
    if result.peak_memory:
        worst = max(result.peak_memory.values()) / 2**20
        print(f"peak memory per worker: up to {worst:.0f} MiB over {len(result.peak_memory)} "
              f"process(es)")


def check_writable(directory: Path) -> None:
    """Fail early, with one line, if ``directory`` cannot be created or written.

    Tries for real (``os.access`` says yes to root under ``/sys`` and ``/proc``): creates the
    missing folders and a temporary file, then removes what it created.
    """
    probe = directory
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir():
        raise UsageError(f"cannot create output folder {directory}: {probe} is not a folder")
    created = []
    try:
        missing = [directory, *directory.parents][: len(directory.parts) - len(probe.parts)]
        for folder in reversed(missing):
            folder.mkdir()
            created.append(folder)
        with tempfile.TemporaryFile(dir=directory):
            pass
    except OSError as exc:
        raise UsageError(f"output folder {directory} cannot be written: "
                         f"{exc.strerror or exc}") from None
    finally:
        for folder in reversed(created):
            try:
                folder.rmdir()
            except OSError:
                pass
