"""Parts of the ``blobflow`` command line (:mod:`pipeline.cli`): the ``gallery``, ``export`` and
``paraview`` commands, help texts completed when printed (scene defaults, kernels), and the
notice printed while Numba compiles.

Commands raise ``ValueError`` for a user's mistake; :mod:`pipeline.cli` prints it as one line
with exit code 2.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping

__all__ = ["add_gallery_parser", "gallery_command", "add_export_parser", "export_command",
           "add_paraview_parser", "paraview_command", "display_problem", "scene_defaults_epilog",
           "surface_help", "announce_compilation"]


def scene_defaults_epilog(parser: argparse.ArgumentParser) -> None:
    """``run --help``: every installed scene's default duration and fps."""
    from ..scene import available_scenes, load_scene

    lines = ["scenes (default duration at default fps; `blobflow list --verbose` shows their "
             "parameters):"]
    for name in available_scenes():
        try:
            scene = load_scene(name)
        except Exception as exc:  # noqa: BLE001 - one broken scene must not hide the others
            lines.append(f"  {name}: cannot be loaded ({type(exc).__name__})")
            continue
        lines.append(f"  {name}: {scene.duration:g} s at {scene.fps:g} fps")
    parser.epilog = "\n".join(lines)
    parser.formatter_class = argparse.RawDescriptionHelpFormatter


def surface_help(parser: argparse.ArgumentParser) -> None:
    """``surface --help``: the kernels and the defaults of the surface options."""
    from filters.kernels import SPLAT_KERNELS

    from ..surface.options import SURFACE_DEFAULTS

    for action in parser._actions:
        if action.dest == "kernel" and "one of" not in action.help:
            action.help += (f": one of {', '.join(SPLAT_KERNELS)} "
                            f"(default: {SURFACE_DEFAULTS['kernel']})")
        elif action.dest == "smooth_iterations" and "default" not in action.help:
            action.help += f" (default: {SURFACE_DEFAULTS['smooth_iterations']})"
    parser.epilog = ("further options (--option NAME=VALUE) and their defaults: "
                     + ", ".join(f"{k}={v}" for k, v in SURFACE_DEFAULTS.items()
                                 if k not in ("radius", "kernel", "smooth_iterations")))


# -- gallery ------------------------------------------------------------------------------------
def add_gallery_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("gallery", help="run every scene with its defaults and draw one still of "
                       "each (the README's pictures)",
                       description="Draw one still per scene (at the scene's still time, else "
                       "its most interesting frame; 640x480, with its colliders) from a run "
                       "of the scene's defaults: a "
                       "complete run of exactly the defaults in RUNS/SCENE or in outputs/SCENE "
                       "(where `blobflow run SCENE` writes) is reused, else the scene is run "
                       "into RUNS/SCENE with --no-render.")
    p.add_argument("scenes", nargs="*", metavar="SCENE", help="scenes to draw (default all)")
    p.add_argument("--out", default="docs", metavar="DIR", help="folder of the stills SCENE.png")
    p.add_argument("--runs", default=str(Path("outputs") / "gallery"), metavar="DIR",
                   help="folder of the scenes' runs, reused when complete with the defaults")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def gallery_command(args: argparse.Namespace, *, run: Callable[[list[str]], int],
                    check_writable: Callable[[Path], None]) -> int:
    """``blobflow gallery``: ``run(argv)`` runs a scene (``blobflow run``), ``check_writable``
    refuses a folder that cannot be written."""
    from ..render.gallery import gallery_still, run_is_current
    from ..render.pictures import RenderUnavailableError
    from ..scene import available_scenes, load_scene

    installed = list(available_scenes())
    names = args.scenes or installed
    unknown = [n for n in names if n not in installed]
    if unknown:
        raise ValueError(f"unknown scene {unknown[0]!r}; scenes: {', '.join(installed)}")
    out, runs = Path(args.out), Path(args.runs)
    check_writable(out)
    check_writable(runs)
    quiet = ["-q"] if args.quiet else []
    for name in names:
        scene = load_scene(name)
        candidates = [runs / name, Path("outputs") / name]
        directory = next((d for d in candidates if run_is_current(d, scene)), None)
        if directory is not None:
            print(f"{name}: reusing the run in {directory}")
        else:
            directory = runs / name
            code = run(["run", name, "--out", str(directory), "--no-render", *quiet])
            if code != 0:
                print(f"blobflow: gallery stopped: the run of {name!r} failed", file=sys.stderr)
                return code
        try:
            path, index, reason = gallery_still(directory, out / f"{name}.png",
                                                time=scene.still,
                                                outputs=scene.build().drawn_outputs())
        except RenderUnavailableError as exc:
            raise ValueError(str(exc)) from None
        print(f"{name}: wrote {path} (frame {index}, {reason})")
    return 0


# -- export -------------------------------------------------------------------------------------
def add_export_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("export", help="write series as one USD stage (Blender, Houdini, ...)",
                       description="Write one or more series (.pvd or .series) as one USD stage: "
                       "particles as Points (widths, velocities, ids), surfaces as Meshes whose "
                       "topology may change every frame, strands as BasisCurves; one time "
                       "sample per frame, z-up, metres. Needs usd-core "
                       "(pip install \"blobflow[usd]\").")
    p.add_argument("series", nargs="+", help=".pvd or .series files, one prim each")
    p.add_argument("--usd", required=True, metavar="FILE",
                   help="output stage: .usd or .usdc (binary) or .usda (text)")
    p.add_argument("--fps", type=float, metavar="F",
                   help="time codes per second (default: the run's fps from its scene.json, "
                        "else from the frame times)")
    p.add_argument("--radius", type=float, metavar="R",
                   help="particle radius (m) for the points' widths where a series has no "
                        "radius array (default: half the run's spacing, else 0.005)")


def export_command(args: argparse.Namespace) -> int:
    """``blobflow export``: ValueError (one line, exit code 2) for bad input, before writing."""
    from ..io.series import SeriesError, validate_series
    from ..io.usd import UsdUnavailableError, export_usd

    out = Path(args.usd)
    if out.suffix not in (".usd", ".usda", ".usdc"):
        raise ValueError(f"--usd must end in .usd, .usda or .usdc, got {out}")
    try:
        for path in args.series:
            validate_series(path)  # every frame, before anything is written
    except (FileNotFoundError, SeriesError) as exc:
        raise ValueError(str(exc)) from None
    folder = out.parent if str(out.parent) else Path(".")
    if not folder.is_dir() or not os.access(folder, os.W_OK):
        raise ValueError(f"--usd: folder {folder} does not exist or cannot be written")
    try:
        path = export_usd(args.series, out, fps=args.fps, radius=args.radius)
    except (UsdUnavailableError, ValueError) as exc:
        raise ValueError(str(exc)) from None
    print(f"wrote {path}")
    return 0


# -- paraview -----------------------------------------------------------------------------------
def add_paraview_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("paraview", help="where blobflow's ParaView plugin is, or start ParaView "
                       "with it", description="Print the paths of blobflow's ParaView plugin "
                       "(filter 'blobflow Particle Surface', one source per scene) and how to "
                       "load it; --launch starts the ParaView GUI with it loaded, then opens "
                       "FILES (it needs a display: headless, run it under xvfb-run).")
    p.add_argument("--launch", action="store_true",
                   help="start `paraview` with the plugin loaded (and open FILES)")
    p.add_argument("files", nargs="*", metavar="FILE", help="files to open with --launch")


def display_problem(environ: Mapping[str, str] | None = None) -> str | None:
    """Why ParaView's window could not open here (one line), or None when it can (or when
    this cannot be told: not Linux, a Qt platform of its own, no Xlib to ask).

    With ``DISPLAY`` set, Xlib is asked to connect to it (``XOpenDisplay``), as Qt would.
    """
    environ = os.environ if environ is None else environ
    if not sys.platform.startswith("linux") or environ.get("QT_QPA_PLATFORM"):
        return None
    if environ.get("WAYLAND_DISPLAY"):
        return None
    hint = ("ParaView's window needs a display: run it on a desktop, or headless under Xvfb: "
            "`xvfb-run -a blobflow paraview --launch ...` (Debian: apt-get install xvfb)")
    display = environ.get("DISPLAY")
    if not display:
        return f"no display (DISPLAY is not set); {hint}"
    import ctypes
    import ctypes.util

    try:
        xlib = ctypes.CDLL(ctypes.util.find_library("X11") or "libX11.so.6")
    except OSError:
        return None
    xlib.XOpenDisplay.restype = ctypes.c_void_p
    xlib.XOpenDisplay.argtypes = [ctypes.c_char_p]
    xlib.XCloseDisplay.argtypes = [ctypes.c_void_p]
    handle = xlib.XOpenDisplay(display.encode())
    if not handle:
        return f"cannot connect to the display {display!r}; {hint}"
    xlib.XCloseDisplay(handle)
    return None


def paraview_command(args: argparse.Namespace) -> int:
    """``blobflow paraview``: print the plugin's paths, or start ParaView with it.

    ParaView 5.11 refuses data files beside ``--script`` ("--script excludes filenames"): the
    files go to the startup script in ``BLOBFLOW_PARAVIEW_OPEN``, which opens them once the
    plugin is loaded.
    """
    import json
    import shutil
    import subprocess

    here = Path(__file__).resolve().parent.parent / "paraview"
    plugin, startup = here / "plugin.py", here / "startup.py"
    if not args.launch:
        if args.files:
            raise ValueError("FILE arguments need --launch")
        print(f"ParaView plugin: {plugin}\n"
              f"  GUI:      paraview --script={startup}\n"
              f"            (or Tools > Manage Plugins > Load New, where the ParaView's Python "
              f"plugins load)\n"
              f"  pvpython: exec(open({str(startup)!r}).read())\n"
              f"  blobflow's Python (BLOBFLOW_PYTHON): {sys.executable}")
        return 0
    paraview = shutil.which("paraview")
    if paraview is None:
        raise ValueError("paraview is not on PATH (Debian: apt-get install paraview)")
    files = [Path(f).resolve() for f in args.files]
    missing = [str(f) for f, given in zip(files, args.files, strict=False) if not f.exists()]
    if missing:
        raise ValueError(f"FILE: no such file: {missing[0]}")
    problem = display_problem()
    if problem:
        raise ValueError(problem)
    env = dict(os.environ, BLOBFLOW_PYTHON=os.environ.get("BLOBFLOW_PYTHON", sys.executable),
               BLOBFLOW_PARAVIEW_PLUGIN=str(plugin),
               BLOBFLOW_PARAVIEW_OPEN=json.dumps([str(f) for f in files]))
    return subprocess.call([paraview, f"--script={startup}"], env=env)


_NOTICE = None


def announce_compilation() -> None:
    """Print one line on stderr when Numba starts compiling a kernel that is not in its cache
    (the first run; later runs load the cached kernels and print nothing), once per call."""
    global _NOTICE
    from numba.core import event

    class Notice(event.Listener):
        said = False

        def on_start(self, event_):
            if not self.said:
                self.said = True
                from tqdm.auto import tqdm

                tqdm.write("blobflow: compiling Numba kernels (first run only: about a minute, "
                           "cached for later runs)", file=sys.stderr)

        def on_end(self, event_):
            pass

    if _NOTICE is None:
        _NOTICE = Notice()
        event.register("numba:compile", _NOTICE)
    _NOTICE.said = False
