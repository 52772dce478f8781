"""The ``blobflow`` command line (also ``python -m pipeline``).

Exit codes: 0 success; 1 the run failed while simulating (the frames written so far stay valid);
2 bad usage or input (one line on stderr, nothing written); 130 interrupted.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from ..io.folderlock import FolderLockedError, lock_folder
from ..io.outfiles import OwnershipError, atomic_path, frames_folder, remove_series
from . import surface as cli_surface
from . import tools as cli_tools
from .common import UsageError
from .common import add_cluster_options as _add_cluster_options
from .common import check_workers as _check_workers
from .common import check_writable as _check_writable
from .common import client as _client
from .common import close_client as _close

if TYPE_CHECKING:
    from collections.abc import Sequence

__all__ = ["main"]


class _Parser(argparse.ArgumentParser):
    """One-line errors; every option's help shows its default; ``help_hook(parser)``, when
    set, completes the help (scene defaults, kernel names) only when it is printed, so that
    ordinary commands do not import the scenes or Numba to build it."""

    help_hook = None

    def error(self, message):  # one line, not usage + message
        raise UsageError(message)

    def format_help(self):
        if self.help_hook is not None:
            self.help_hook(self)
        for action in self._actions:
            default = action.default
            if (action.help and action.help is not argparse.SUPPRESS and action.option_strings
                    and default not in (None, False, [], argparse.SUPPRESS)
                    and "default" not in action.help):
                action.help += f" (default: {default})"
        return super().format_help()


def _build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="blobflow", description="Particle simulations and implicit surfaces as "
                     "VTK pipelines, written as ParaView-ready time series.")
    parser.add_argument("--version", action="version", version=f"blobflow {_version()}",
                        help="print blobflow's version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    p_list = sub.add_parser("list", help="list the installed scenes")
    p_list.add_argument("-v", "--verbose", action="store_true",
                        help="also list every scene's parameters with defaults, types and "
                             "descriptions")

    p_run = sub.add_parser("run", help="run a scene into an output folder")
    p_run.add_argument("scene", help="scene name (see `blobflow list`)")
    length = p_run.add_mutually_exclusive_group()
    length.add_argument("--duration", type=float, metavar="S",
                        help="simulated seconds (default: the scene's, listed below)")
    length.add_argument("--frames", type=int, metavar="N",
                        help="number of frames instead of --duration")
    p_run.add_argument("--fps", type=float, metavar="F",
                       help="frames per second (default: the scene's, listed below)")
    p_run.add_argument("--out", metavar="DIR", help="output folder (default outputs/SCENE)")
    p_run.add_argument("--set", dest="assignments", action="append", default=[],
                       metavar="NAME=VALUE", help="override a scene parameter (repeatable)")
    p_run.add_argument("--resume", action="store_true",
                       help="continue the series already in the output folder")
    p_run.add_argument("--no-render", action="store_true",
                       help="write the series only, no turntable GIF or movie")
    p_run.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p_run.help_hook = cli_tools.scene_defaults_epilog

    p_render = sub.add_parser("render", help="render series offscreen: a time-lapse or a turntable")
    p_render.add_argument("series", nargs="+", help=".pvd or .series files drawn together")
    p_render.add_argument("--turntable", type=int, metavar="N",
                          help="orbit N distinct views around one time step (a seamless loop) "
                               "instead of a time-lapse")
    when = p_render.add_mutually_exclusive_group()
    when.add_argument("--time", type=float, metavar="S",
                      help="time (s) of the turntable: the nearest frame (default the most "
                           "interesting frame: largest liquid surface or kinetic energy)")
    when.add_argument("--time-index", type=int, metavar="I",
                      help="frame index of the turntable instead of --time")
    p_render.add_argument("--orbit", type=float, default=0.0, metavar="DEG",
                          help="degrees the camera orbits during a time-lapse")
    p_render.add_argument("--out", metavar="FILE.gif|FILE.mp4|DIR",
                          help="output (default beside the first series)")
    p_render.add_argument("--size", default="640x480", metavar="WxH", help="image size in pixels")
    p_render.add_argument("--color-by", metavar="ARRAY", help="colour by a point array")
    p_render.add_argument("--fps", type=float, metavar="F", help="movie frame rate")
    p_render.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    _add_cluster_options(p_render)

    cli_surface.add_surface_parser(sub)

    p_info = sub.add_parser("info", help="describe a written series (.pvd or .series)")
    p_info.add_argument("series", help="path to a .pvd or .series file")

    cli_tools.add_gallery_parser(sub)
    cli_tools.add_export_parser(sub)
    cli_tools.add_paraview_parser(sub)
    return parser


def _version() -> str:
    from ..version import version

    return version()


# -- list ---------------------------------------------------------------------------------------
def _cmd_list(args) -> int:
    from ..scene import available_scenes, load_scene

    names = list(available_scenes())
    if not names:
        print("no scenes installed")
        return 0
    width = max(map(len, names))
    for name in names:
        try:
            scene = load_scene(name)
        except Exception as exc:  # noqa: BLE001 - one broken scene must not hide the others
            print(f"{name:<{width}}  (cannot be loaded: {type(exc).__name__}: {exc})")
            continue
        print(f"{name:<{width}}  {scene.description}")
        if args.verbose:
            print(f"    (default run: {scene.duration:g} s at {scene.fps:g} fps)")
            for p in scene.parameters.values():
                print(f"    {p.name} = {p.default!r}  ({p.kind}) {p.doc}")
    return 0


# -- run ----------------------------------------------------------------------------------------
def _scene_record(scene, parameters, fps, outputs) -> dict:
    return {"scene": scene.name, "fps": fps, "parameters": parameters, "outputs": outputs}


#: What ``blobflow run`` writes beside the series (renders, colliders), removed with a previous
#: run.
_RUN_FILES = ("turntable.gif", "movie.mp4", "colliders.vtp")


def _read_record(out: Path) -> dict | None:
    """The ``scene.json`` of a previous run in ``out``, or None; one-line error if unreadable."""
    path = out / "scene.json"
    if not path.is_file():
        return None
    try:
        if path.stat().st_size > 2**24:
            raise ValueError("larger than 16 MiB")
        record = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(record, dict):
            raise ValueError("not a JSON object")
    except (OSError, ValueError, RecursionError) as exc:
        raise UsageError(f"{path} is not a blobflow run record ({exc}); choose another --out "
                         f"or remove it") from None
    return record


def _remove_previous_run(out: Path, record: dict) -> None:
    """Delete the series and renders a previous run of the same scene left in ``out``.

    Only what blobflow writes is touched, by the one rule of :mod:`pipeline.io.outfiles`: the
    collection files and the frames ``NAME/NAME_<digits>.vt?`` of each output the record lists
    (the frames folder only when nothing else is left in it), and the renders.
    """
    for name in _record_outputs(record):
        remove_series(out, name)
    _remove_renders(out)


def _record_outputs(record: dict) -> list[str]:
    """The output names a run record lists (plain names only)."""
    outputs = record.get("outputs", [])
    return [n for n in outputs if isinstance(n, str) and n.isidentifier()] \
        if isinstance(outputs, list) else []


def _remove_renders(out: Path) -> None:
    """Delete the renders (:data:`_RUN_FILES`) a previous run wrote in ``out``."""
    for file_name in _RUN_FILES:
        (out / file_name).unlink(missing_ok=True)


def _write_text_atomic(path: Path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _compile_surface_alongside(flow, record: dict) -> None:
    """On a first run, compile the liquid surface's kernels in a second process while the
    simulation compiles and steps (:mod:`pipeline.cli.warmup`)."""
    from ..surface.options import surface_options_from_record
    from .warmup import compile_surface_in_background, simulate_while

    worker = compile_surface_in_background(surface_options_from_record(record),
                                           flow.source.simulation.output_spec)
    if worker is not None:
        simulate_while(worker, flow.source)


def _run_settings(args, scene):
    """``(out, fps, duration)`` of ``blobflow run``, checked before anything is read."""
    out = Path(args.out) if args.out else Path("outputs") / scene.name
    fps = scene.fps if args.fps is None else args.fps
    if args.frames is None and args.duration is None:
        duration = scene.duration
    else:
        duration = args.duration
    if not (math.isfinite(fps) and fps > 0):
        raise UsageError(f"--fps must be > 0 and finite, got {fps}")
    if duration is not None and not (math.isfinite(duration) and duration >= 0):
        raise UsageError(f"--duration must be >= 0 seconds and finite, got {duration}")
    if duration is not None and not math.isfinite(duration * fps):
        raise UsageError(f"--duration {duration:g} s at --fps {fps:g} is more frames than "
                         f"can be counted")
    if args.frames is not None and args.frames < 1:
        raise UsageError(f"--frames must be >= 1, got {args.frames}")
    return out, fps, duration


def _cmd_run(args) -> int:
    from ..scene import load_scene

    try:
        scene = load_scene(args.scene)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    out, fps, duration = _run_settings(args, scene)
    try:
        overrides = scene.parse_assignments(args.assignments)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    _check_writable(out)
    try:
        with lock_folder(out):  # one writer per folder, from the first read to the last write
            return _run_locked(args, scene, out, fps, duration, overrides)
    except FolderLockedError as exc:
        raise UsageError(str(exc)) from None


def _run_locked(args, scene, out: Path, fps: float, duration, overrides: dict) -> int:
    from filters.simulation import SimulationError

    from ..io.series import SeriesError

    parameters = {**scene.defaults(), **overrides}
    saved = _read_record(out)
    if saved is not None and saved.get("scene") != scene.name:
        raise UsageError(f"{out} holds a run of scene {saved.get('scene')!r}, not {scene.name!r}; "
                         f"choose another --out or remove it")
    if args.resume and saved is not None:
        saved_params = saved.get("parameters", {})
        saved_params = saved_params if isinstance(saved_params, dict) else {}
        saved_params = {k: (tuple(v) if isinstance(v, list) else v)
                        for k, v in saved_params.items()}
        clashes = [k for k, v in overrides.items() if k in saved_params and saved_params[k] != v]
        if clashes:
            raise UsageError(
                f"--resume with other parameters than the run in {out}: {', '.join(clashes)}"
            )
        parameters = {**parameters, **saved_params}
        if args.fps is None:
            fps = saved.get("fps", fps)
        elif saved.get("fps") not in (None, fps):
            raise UsageError(f"--resume needs the same --fps as the run in {out} ({saved['fps']})")
    try:
        flow = scene.build(**parameters)
        flow.source.set_frames(fps, duration=duration, frames=args.frames)
    except (ValueError, TypeError, OverflowError) as exc:
        raise UsageError(f"scene {scene.name!r}: {exc}") from None
    try:  # every folder the run writes or cleans is its own, before anything is changed
        for name in {*flow.written_outputs(), *(_record_outputs(saved) if saved else [])}:
            frames_folder(out, name)
    except OwnershipError as exc:
        raise UsageError(str(exc)) from None
    if args.resume:
        try:
            flow.check_resume(out)
        except (SeriesError, ValueError) as exc:
            raise UsageError(f"cannot resume: {exc}") from None

    if saved is not None and not args.resume:
        _remove_previous_run(out, saved)
    record = _scene_record(scene, parameters, fps, flow.written_outputs())
    text = json.dumps(record, indent=1, default=list) + "\n"
    started = []

    def on_frame(index, time):
        # a resume changes the folder only once its checkpoint has been restored and a frame
        # written: a checkpoint that does not fit leaves the record and the renders as they were
        if not started:
            started.append(True)
            if args.resume:
                _remove_renders(out)  # the renders of the shorter run no longer show it
                _write_text_atomic(out / "scene.json", text)

    if not args.resume:
        _write_text_atomic(out / "scene.json", text)
    if not args.resume and "surface" in flow.written_outputs():
        _compile_surface_alongside(flow, record)
    try:
        paths = flow.run(out, resume=args.resume, progress=not args.quiet, on_frame=on_frame)
    except SeriesError as exc:  # a checkpoint frame on disk that cannot be read
        if args.resume and not started:  # nothing was changed: the input is at fault
            raise UsageError(f"cannot resume: {exc}") from None
        print(f"blobflow: error: {exc}", file=sys.stderr)
        return 1
    except SimulationError as exc:
        print(f"blobflow: {exc}", file=sys.stderr)
        print(f"blobflow: the frames written before the failure are valid in {out}",
              file=sys.stderr)
        return 1
    except (ValueError, TypeError, KeyError, IndexError) as exc:
        if args.resume and not started:  # restoring the checkpoint failed: nothing was changed
            raise UsageError(f"cannot resume from the checkpoint in {out}: it does not fit scene "
                             f"{scene.name!r} with these parameters ({type(exc).__name__}: "
                             f"{exc})") from None
        raise
    if args.resume and not started:
        _write_text_atomic(out / "scene.json", text)
    if not args.no_render:
        from ..render.pictures import RenderUnavailableError, render_run

        try:
            drawn = [paths[name] for name in flow.drawn_outputs()] or list(paths.values())
            paths.update(render_run(drawn, out, time=scene.still,
                                    progress=not args.quiet))
        except RenderUnavailableError as exc:
            # the series are the run's result; pictures need a system library
            print(f"blobflow: rendering skipped: {exc}", file=sys.stderr)
    print(f"wrote {len(flow.times)} frames of scene {scene.name!r} to {out}/")
    for name, path in paths.items():
        print(f"  {name}: {path}")
    return 0


# -- render -------------------------------------------------------------------------------------
def _cmd_render(args) -> int:
    from ..io.series import SeriesError, read_collection, validate_series
    from ..render.pictures import (
        RenderUnavailableError,
        check_fps,
        check_movie_length,
        parse_size,
        timelapse,
        turntable,
    )
    from ..tasks import FramesError

    paths = [Path(p) for p in args.series]
    stem = paths[0].name.split(".")[0]
    default = f"{stem}_turntable.gif" if args.turntable else f"{stem}.mp4"
    out = Path(args.out) if args.out else paths[0].parent / default
    if args.turntable is not None and args.turntable < 2:
        raise UsageError(f"--turntable must be >= 2 frames, got {args.turntable}")
    if not math.isfinite(args.orbit):
        raise UsageError(f"--orbit must be a finite number of degrees, got {args.orbit}")
    _check_workers(args)
    try:
        size = parse_size(args.size)
        if args.fps is not None:
            check_fps(args.fps)
        if args.turntable is not None:  # limits first: before any frame is read
            check_movie_length(args.turntable, size, out, turntable=True)
        else:
            check_movie_length(len(read_collection(paths[0])), size, out, turntable=False)
        for path in paths:
            validate_series(path)  # every frame, before anything is drawn or written
    except (FileNotFoundError, SeriesError, ValueError) as exc:
        raise UsageError(f"--{exc}" if str(exc).startswith("fps ") else str(exc)) from None
    if args.turntable is None and (args.time is not None or args.time_index is not None):
        raise UsageError("--time and --time-index choose the turntable's time step: give "
                         "--turntable N too")
    if args.time is not None:
        from ..render.pictures import frame_at_time

        try:
            frame_at_time(paths, args.time)
        except ValueError as exc:
            raise UsageError(f"--{exc}") from None
    if out.suffix and out.suffix.lower() not in (".gif", ".mp4"):
        raise UsageError(f"--out must end in .gif or .mp4, or name a folder for PNG files; "
                         f"got {out}")
    _check_writable(out.parent if out.suffix else out)
    client = _client(args)
    try:
        if client is not None:
            from ..render.pictures import render_frames

            result = render_frames(paths, out, client=client, turntable_frames=args.turntable,
                                   time_index=args.time_index, time=args.time,
                                   orbit=args.orbit, size=size,
                                   color_by=args.color_by, fps=args.fps, progress=not args.quiet)
        elif args.turntable:
            result = turntable(paths, out, frames=args.turntable, time_index=args.time_index,
                               time=args.time, size=size, color_by=args.color_by,
                               fps=args.fps or 24.0, progress=not args.quiet)
        else:
            result = timelapse(paths, out, orbit=args.orbit, size=size, color_by=args.color_by,
                               fps=args.fps, progress=not args.quiet)
    except (SeriesError, ValueError, IndexError, RenderUnavailableError) as exc:
        raise UsageError(str(exc)) from None
    except FramesError as exc:
        print(f"blobflow: {exc}", file=sys.stderr)
        return 1
    finally:
        _close(client)
    print(f"wrote {result}")
    return 0


def _usage_errors(command):
    """``command`` with its ValueError reported as a usage error (one line, exit code 2)."""
    def run(args):
        try:
            return command(args)
        except ValueError as exc:
            raise UsageError(str(exc)) from None
    return run


# -- info ---------------------------------------------------------------------------------------
def _cmd_info(args) -> int:
    import numpy as np
    import pyvista as pv

    from ..io.checkpoint import checkpoint_path
    from ..io.convert import STATE_PREFIX
    from ..io.series import SeriesError, read_collection, read_frame

    path = Path(args.series)
    # one frame in memory at a time: a series of any length is described in the memory of
    # its largest frame (which the file check bounds by the memory limit)
    try:
        entries = read_collection(path)
        times = np.array([t for t, _ in entries], dtype=np.float64)
        first, counts, rows = None, [], []
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        for t, name in entries:
            data = pv.wrap(read_frame(path.parent / name))
            if first is None:
                first = data
            counts.append(data.n_points)
            if data.n_points:
                bounds = np.asarray(data.bounds, dtype=float)
                lo, hi = np.minimum(lo, bounds[0::2]), np.maximum(hi, bounds[1::2])
            if len(entries) <= 12:
                rows.append(f"    t = {t:<10g} {data.n_points} points, {data.n_cells} cells")
    except (FileNotFoundError, SeriesError) as exc:
        raise UsageError(str(exc)) from None
    print(f"{path}: {len(times)} frames")
    if not len(times):
        return 0
    print(f"  times: {times[0]:g} .. {times[-1]:g} s" + (
        f" (every {np.diff(times).mean():g} s)" if len(times) > 1 else ""))
    print(f"  type: {type(first).__name__}")
    for label, attrs in (("point", first.point_data), ("cell", first.cell_data)):
        names = [f"{n} ({attrs[n].shape[1] if attrs[n].ndim > 1 else 1})" for n in attrs.keys()]
        print(f"  {label} arrays: {', '.join(names) or 'none'}")
    fields = [n for n in first.field_data.keys() if not n.startswith(STATE_PREFIX)]
    resumable = (checkpoint_path(path).is_file()
                 or any(n.startswith(STATE_PREFIX) for n in first.field_data.keys()))
    print(f"  field arrays: {', '.join(fields) or 'none'}"
          + ("; checkpointed (resumable)" if resumable else ""))
    if np.all(np.isfinite(lo)):
        print(f"  bounds: x {lo[0]:g} .. {hi[0]:g}, y {lo[1]:g} .. {hi[1]:g}, "
              f"z {lo[2]:g} .. {hi[2]:g}")
    print(f"  points per frame: {min(counts)} .. {max(counts)}")
    for row in rows:
        print(row)
    return 0


class Terminated(BaseException):
    """SIGTERM arrived: unwinds like Ctrl-C, so that temporary files are removed and the output
    folder's lock released (a BaseException, so that no ``except Exception`` swallows it)."""


def _terminate(signum, frame):
    raise Terminated()


def _with_signals(run):
    """Run ``run()`` with SIGTERM turned into :class:`Terminated` (main thread only)."""
    try:
        previous = signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread: leave signals alone
        return run()
    try:
        return run()
    finally:
        signal.signal(signal.SIGTERM, previous)


def _os_error(exc: OSError) -> str:
    """An OSError as one line: what failed and on which file."""
    where = f": {exc.filename}" if getattr(exc, "filename", None) else ""
    if len(where) > 200:
        where = where[:100] + "..." + where[-60:]
    return f"{exc.strerror or exc}{where}"


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``blobflow`` console script; returns the exit code.

    Every failure is one line on stderr: 2 for the user's input and the system's limits (an
    unwritable folder, a name too long, not enough memory), 1 for a run that failed while
    computing, 130 for Ctrl-C, 143 for SIGTERM; ``BLOBFLOW_DEBUG=1`` shows the traceback of an
    unexpected error.
    """
    parser = _build_parser()
    try:
        args = parser.parse_args(argv)
        if args.command in ("run", "surface", "render"):
            cli_tools.announce_compilation()
        command = {"list": _cmd_list, "run": _cmd_run, "render": _cmd_render,
                   "surface": cli_surface.surface_command, "info": _cmd_info,
                   "gallery": _usage_errors(lambda a: cli_tools.gallery_command(
                       a, run=main, check_writable=_check_writable)),
                   "export": _usage_errors(cli_tools.export_command),
                   "paraview": _usage_errors(cli_tools.paraview_command)}[args.command]
        return _with_signals(lambda: command(args))
    except SystemExit as exc:  # --help, --version
        return exc.code if isinstance(exc.code, int) else 0
    except UsageError as exc:
        print(f"blobflow: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("blobflow: interrupted; the frames written so far are valid (use --resume)",
              file=sys.stderr)
        return 130
    except Terminated:
        print("blobflow: terminated; the frames written so far are valid (use --resume)",
              file=sys.stderr)
        return 143
    except BrokenPipeError:  # e.g. `blobflow info ... | head`
        sys.stdout = open(os.devnull, "w")
        return 0
    except OSError as exc:  # the system refused: a name too long, a full disk, permissions
        print(f"blobflow: error: {_os_error(exc)}", file=sys.stderr)
        return 2
    except (OverflowError, MemoryError, RecursionError) as exc:
        print(f"blobflow: error: {type(exc).__name__}: {str(exc) or 'out of memory'}",
              file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 - the last resort: one line, never a traceback
        if os.environ.get("BLOBFLOW_DEBUG"):
            raise
        text = " ".join(str(exc).split())
        print(f"blobflow: error: {type(exc).__name__}: {text[:500]} (BLOBFLOW_DEBUG=1 shows "
              f"where)", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
