"""The ``blobflow surface`` command (:mod:`pipeline.cli`): a particle series' surface, frame by
frame or across frames, serially or on a Dask cluster, with the producing run's surface options.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from . import tools as cli_tools
from .common import (
    UsageError,
    add_cluster_options,
    check_name_length,
    check_workers,
    check_writable,
    close_client,
    report_memory,
)
from .common import client as make_client

if TYPE_CHECKING:
    import argparse

__all__ = ["add_surface_parser", "surface_command"]


def add_surface_parser(sub: argparse._SubParsersAction) -> None:
    """The ``surface`` command's parser."""
    p_surface = sub.add_parser("surface", help="reconstruct the surface of every frame of a "
                               "particle series (serially or on a Dask cluster)")
    p_surface.add_argument("particles", help="particle series (.pvd or .series)")
    p_surface.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p_surface.add_argument("--name", default="surface",
                           help="series name (default surface); a liquid's surface is drawn as "
                                "water whatever its name (it says so in its field data)")
    p_surface.add_argument("--radius", type=float, metavar="R",
                           help="particle radius (m); default half the spacing of the run that "
                                "wrote the particles (its scene.json), else 0.01")
    p_surface.add_argument("--cell-size", type=float, metavar="H",
                           help="voxel edge (m), default radius / 2")
    p_surface.add_argument("--kernel", metavar="K", help="splatting kernel")
    p_surface.add_argument("--smooth-iterations", type=int, metavar="N",
                           help="windowed-sinc iterations")
    p_surface.add_argument("--option", dest="options", action="append", default=[],
                           metavar="NAME=VALUE", help="further surface option (repeatable), as "
                                                      "in pipeline.surface.surface_stages")
    p_surface.add_argument("--across-frames", type=int, default=0, metavar="K",
                           help="smooth every frame's surface with those of the K frames on each "
                                "side, the particles followed by id (0 to 10; default 0: each "
                                "frame alone; 2 for movies)")
    p_surface.add_argument("--resume", action="store_true", help="skip frames already written")
    p_surface.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    add_cluster_options(p_surface)
    p_surface.help_hook = cli_tools.surface_help


def _surface_options(args, source: Path) -> dict:
    """Options of the surface: the producing run's (its ``scene.json`` beside the particles,
    when there is one), then the command line's flags and ``--option`` assignments."""
    from ..assignments import parse_assignments
    from ..surface.options import SURFACE_PARAMETERS, surface_options_from_record

    options = {}
    record_path = source.parent / "scene.json"
    if record_path.is_file():
        try:
            options = surface_options_from_record(json.loads(record_path.read_text("utf-8")))
        except (OSError, ValueError, TypeError) as exc:
            raise UsageError(f"{record_path} is not a blobflow run record ({exc})") from None
    flags = dict(radius=args.radius, cell_size=args.cell_size, kernel=args.kernel,
                 smooth_iterations=args.smooth_iterations)
    options.update({k: v for k, v in flags.items() if v is not None})
    try:
        options.update(parse_assignments(args.options, SURFACE_PARAMETERS, flag="--option",
                                         owner="the surface"))
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    return options


def surface_command(args: argparse.Namespace) -> int:
    """``blobflow surface``: the surface of every frame of a particle series."""
    from ..io.folderlock import FolderLockedError, lock_folder
    from ..io.outfiles import OwnershipError, frames_folder
    from ..surface.frames import surface_series
    from ..tasks import FramesError

    if not args.name.isidentifier():
        raise UsageError(f"--name must be a plain name such as 'surface' (letters, digits, _), "
                         f"got {args.name!r}")
    source = Path(args.particles)
    out = Path(args.out)
    check_name_length(out, args.name, ".source.json", "--name")
    target = out / f"{args.name}.pvd"
    input_frames = source.parent / source.name.split(".")[0]
    if (target.resolve() == source.resolve()
            or (out / args.name).resolve() == input_frames.resolve()):
        raise UsageError(f"--out {out} with --name {args.name} would overwrite the input series "
                         f"{source}; choose another --out or --name")
    if not 0 <= args.across_frames <= 10:
        raise UsageError(f"--across-frames must be in [0, 10], got {args.across_frames}")
    check_workers(args)
    options = _surface_options(args, source)
    _fit_budget_to_memory(args, options)
    try:
        from ..surface.stages import surface_stages

        surface_stages(**options)  # with the budget it will run with
    except (TypeError, ValueError) as exc:
        raise UsageError(str(exc)) from None
    entries = _check_input(source, options, args.across_frames)  # every frame, up front
    inputs = {(source.parent / name).resolve() for _, name in entries}
    if any(p.parent == (out / args.name).resolve() for p in inputs):
        raise UsageError(f"--out {out} with --name {args.name} would overwrite the input frames; "
                         f"choose another --out or --name")
    check_writable(out)
    client = None
    try:
        with lock_folder(out):  # one writer per folder
            for name in (args.name, f"_{args.name}_single"):
                frames_folder(out, name)  # a link or a file in the way is refused
            client = make_client(args)
            result = surface_series(args.particles, target, client=client,
                                    resume=args.resume, progress=not args.quiet,
                                    across_frames=args.across_frames, **options)
    except (FolderLockedError, OwnershipError) as exc:
        raise UsageError(str(exc)) from None
    except ValueError as exc:  # the provenance of the frames kept by --resume
        raise UsageError(str(exc)) from None
    except FramesError as exc:
        print(f"blobflow: {exc}", file=sys.stderr)
        print(f"blobflow: the frames that succeeded are in {out}; rerun with --resume",
              file=sys.stderr)
        return 1
    finally:
        close_client(client)
    print(f"wrote {result.path} ({result.computed} frames computed, {result.skipped} kept)")
    report_memory(result)
    return 0


def _check_input(source: Path, options: dict, across_frames: int):
    """Read every frame of the input once, before any work, and refuse what no frame can
    succeed with: a missing or damaged frame, particles beyond the voxel index's reach at this
    cell size, particles so crowded that the work would be quadratic, or (with
    ``--across-frames``) frames without the ``id`` array the particles are followed by."""
    import numpy as np
    from vtkmodules.util import numpy_support

    from filters.kernels import SPLAT_DEFAULTS
    from filters.surface.crowding import CrowdingError, check_crowding
    from filters.surface.grid import check_block_range

    from ..io.series import SeriesError, validate_series
    from ..surface.options import SURFACE_DEFAULTS

    radius = float(options.get("radius", SURFACE_DEFAULTS["radius"]))
    cell = float(options.get("cell_size") or radius / 2)
    block = int(options.get("block_size", 8))
    kernel = options.get("kernel", SURFACE_DEFAULTS["kernel"])
    support = float(options.get("support_r") or SPLAT_DEFAULTS[kernel]["support"]) * radius

    def check(index, data):
        points = data.GetPoints() if hasattr(data, "GetPoints") else None
        if points is None or data.GetNumberOfPoints() == 0:
            return
        xyz = numpy_support.vtk_to_numpy(points.GetData()).astype(np.float64, copy=False)
        finite = xyz[np.isfinite(xyz).all(axis=1)]
        what = f"the particles of frame {index}"
        try:
            check_block_range(what, finite, cell, block)
            if options.get("radius_array") is None:
                check_crowding(finite, support, what)
        except (CrowdingError, ValueError) as exc:
            raise UsageError(str(exc)) from None
        if across_frames and data.GetPointData().GetArray("id") is None:
            raise UsageError(f"--across-frames follows the particles by their 'id' point "
                             f"array, which frame {index} of {source} does not have")

    try:
        return validate_series(source, on_frame=check)
    except (FileNotFoundError, SeriesError) as exc:
        raise UsageError(str(exc)) from None


def _fit_budget_to_memory(args, options: dict) -> None:
    """Tie the per-frame grid budget to this machine before any frame starts.

    Each local worker may hold one frame's grid, up to ``max_bytes``.  Left at its default, the
    budget is lowered so that all workers together fit :func:`filters.memory.memory_limit`;
    given explicitly, a budget the machine cannot hold is refused.  A remote ``--scheduler``'s
    workers have their own memory and keep the budget as given.
    """
    from filters.memory import MemoryLimitError, check_memory, format_bytes, memory_limit
    from filters.surface.grid import DEFAULT_MAX_BYTES

    if args.scheduler is not None:
        return
    concurrent = args.workers or 1
    if "max_bytes" not in options:
        options["max_bytes"] = int(max(1, min(DEFAULT_MAX_BYTES, memory_limit() // concurrent)))
        return
    try:
        check_memory(f"{concurrent} frame(s) at once, max_bytes = "
                     f"{format_bytes(options['max_bytes'])} each",
                     concurrent * options["max_bytes"], hint="lower max_bytes or --workers")
    except MemoryLimitError as exc:
        raise UsageError(str(exc)) from None
