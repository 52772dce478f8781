"""blobflow's end of the ParaView plugin: commands that exchange VTK files and JSON.

ParaView runs on its own Python and VTK (Debian's ParaView 5.11: the system's Python 3.11 and
numpy 1.24), where blobflow's dependencies (a current Numba, numpy, VTK, PyVista) cannot be
imported. The plugin (``pipeline/paraview/plugin.py``) therefore imports nothing of blobflow:
it runs this module in blobflow's own environment, ``PYTHON -m pipeline.paraview.bridge COMMAND``::

    describe                      one JSON object on stdout: version, the scenes (description,
                                  fps, duration, outputs, parameters with default, kind and
                                  description) and the surface options (defaults, kernels)
    surface IN OUT OPTIONS_JSON   the surface of the points of the VTK XML file IN
                                  (:func:`pipeline.surface.reconstruct` with the options of the
                                  JSON object), written to OUT (.vtp)
    serve                         the same requests, one JSON line each on stdin
                                  (``{"command": "surface", "source": IN, "target": OUT,
                                  "options": {...}}``), one JSON answer line each on stdout
                                  (``{"ok": true}`` or ``{"ok": false, "error": "...",
                                  "code": 1 or 2}``), until stdin closes: the plugin keeps one
                                  such process, so only its first request pays for the imports
                                  and for loading the compiled kernels

Scenes run through the command line (``PYTHON -m pipeline run SCENE --out DIR --resume``),
which writes each frame as it goes; the plugin reads the frames from the collection. Errors are
one line on stderr and exit code 2 (bad input) or 1 (the computation failed).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Sequence
    from typing import TextIO

__all__ = ["describe", "serve", "main", "MAX_REQUEST"]


def _jsonable(value):
    if isinstance(value, tuple):
        return [_jsonable(v) for v in value]
    return value


def describe() -> dict:
    """What the plugin shows: blobflow's version, the installed scenes and the surface options.

    Returns
    -------
    dict
        ``{"version": str, "scenes": {name: {"description", "fps", "duration",
        "parameters": [{"name", "default", "kind", "doc"}, ...]}}, "surface": {"defaults":
        {...}, "kernels": [...], "anisotropic_kernels": [...]}}``; a scene that cannot be
        loaded is listed under ``"broken"`` with its error.
    """
    from filters.kernels import SPLAT_KERNELS
    from filters.surface.ellipsoids import ANISOTROPIC_KERNELS

    from ..scene import available_scenes, load_scene
    from ..surface.options import SURFACE_DEFAULTS
    from ..version import version

    scenes, broken = {}, {}
    for name in available_scenes():
        try:
            scene = load_scene(name)
        except Exception as exc:  # noqa: BLE001 - one broken scene must not hide the others
            broken[name] = f"{type(exc).__name__}: {exc}"
            continue
        scenes[name] = {
            "description": scene.description, "fps": scene.fps, "duration": scene.duration,
            "parameters": [{"name": p.name, "default": _jsonable(p.default), "kind": p.kind,
                            "doc": p.doc} for p in scene.parameters.values()],
        }
    return {"version": version(), "scenes": scenes, "broken": broken,
            "surface": {"defaults": {k: _jsonable(v) for k, v in SURFACE_DEFAULTS.items()},
                        "kernels": list(SPLAT_KERNELS),
                        "anisotropic_kernels": list(ANISOTROPIC_KERNELS)}}


def _surface(source: str, target: str, options_json: str) -> None:
    from ..io.series import SeriesError, read_frame, write_frame
    from ..surface.stages import reconstruct

    try:
        options = json.loads(options_json)
        if not isinstance(options, dict):
            raise ValueError("not a JSON object")
    except (ValueError, RecursionError) as exc:
        raise ValueError(f"OPTIONS_JSON must be a JSON object of surface options ({exc})") from None
    if "radius" not in options:
        raise ValueError("OPTIONS_JSON needs a 'radius' (m)")
    if isinstance(options.get("attributes"), list):
        options["attributes"] = tuple(options["attributes"])
    if Path(target).suffix != ".vtp":
        raise ValueError(f"OUT must end in .vtp, got {target!r}")
    try:
        particles = read_frame(source)
    except SeriesError as exc:
        raise ValueError(str(exc)) from None
    radius = options.pop("radius")
    write_frame(reconstruct(particles, radius, **options), target)


def _answer(request: dict) -> dict:
    """One request of :func:`serve` -> its answer."""
    from filters.simulation import SimulationError

    try:
        if not isinstance(request, dict) or request.get("command") != "surface":
            raise ValueError("a request is {\"command\": \"surface\", \"source\": ..., "
                             "\"target\": ..., \"options\": {...}}")
        _surface(str(request["source"]), str(request["target"]),
                 json.dumps(request.get("options", {})))
    except (TypeError, ValueError, KeyError) as exc:
        return {"ok": False, "code": 2, "error": f"blobflow: error: {exc}"}
    except (SimulationError, RuntimeError, OSError) as exc:
        return {"ok": False, "code": 1, "error": f"blobflow: {type(exc).__name__}: {exc}"}
    return {"ok": True}


#: Longest request line (characters) :func:`serve` reads; a longer one is answered with an
#: error and skipped, without holding it in memory.
MAX_REQUEST = 1 << 20


def _lines(stdin):
    """The request lines of ``stdin``, each cut at :data:`MAX_REQUEST` characters: yields
    ``(line, too_long)``."""
    while True:
        line = stdin.readline(MAX_REQUEST + 1)
        if not line:
            return
        if len(line) > MAX_REQUEST and not line.endswith("\n"):
            while True:  # skip the rest of the line, a piece at a time
                rest = stdin.readline(MAX_REQUEST)
                if not rest or rest.endswith("\n"):
                    break
            yield "", True
            continue
        yield line, False


def _request_answer(line: str) -> dict:
    """One request line -> its answer; nothing a request does stops the loop."""
    try:
        request = json.loads(line)
    except (ValueError, RecursionError) as exc:  # nesting deeper than Python's stack
        return {"ok": False, "code": 2, "error": f"blobflow: error: bad request "
                                                  f"({type(exc).__name__}: {str(exc)[:200]})"}
    previous, sys.stdout = sys.stdout, sys.stderr
    try:
        return _answer(request)
    except MemoryError:
        return {"ok": False, "code": 1, "error": "blobflow: MemoryError: the request needs more "
                                                 "memory than there is"}
    except RecursionError as exc:
        return {"ok": False, "code": 2, "error": f"blobflow: error: {exc}"}
    except Exception as exc:  # noqa: BLE001 - one request's failure is its answer
        return {"ok": False, "code": 1, "error": f"blobflow: {type(exc).__name__}: {exc}"}
    finally:
        sys.stdout = previous


def serve(stdin: TextIO | None = None, stdout: TextIO | None = None) -> None:
    """Answer JSON-line requests from ``stdin`` on ``stdout`` until ``stdin`` closes.

    Every line gets one answer line, whatever it holds: malformed or too deeply nested JSON,
    a line longer than :data:`MAX_REQUEST`, a request that fails or runs out of memory are
    answered ``{"ok": false, ...}`` and the loop goes on. Anything else written to
    ``sys.stdout`` while a request runs goes to stderr, so that the answers stay one line each.
    """
    stdin = sys.stdin if stdin is None else stdin
    stdout = sys.stdout if stdout is None else stdout
    for line, too_long in _lines(stdin):
        if too_long:
            answer = {"ok": False, "code": 2, "error": f"blobflow: error: bad request (longer "
                                                       f"than {MAX_REQUEST} characters)"}
        elif not line.strip():
            continue
        else:
            answer = _request_answer(line)
        stdout.write(json.dumps(answer) + "\n")
        stdout.flush()


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m pipeline.paraview.bridge COMMAND ...``; returns the exit code."""
    from filters.simulation import SimulationError

    argv = list(sys.argv[1:] if argv is None else argv)
    usage = ("usage: python -m pipeline.paraview.bridge describe | surface IN OUT OPTIONS_JSON "
             "| serve")
    try:
        if argv == ["describe"]:
            print(json.dumps(describe()))
        elif len(argv) == 4 and argv[0] == "surface":
            _surface(*argv[1:])
        elif argv == ["serve"]:
            serve()
        else:
            print(usage, file=sys.stderr)
            return 2
    except (TypeError, ValueError) as exc:
        print(f"blobflow: error: {exc}", file=sys.stderr)
        return 2
    except (SimulationError, RuntimeError, OSError, MemoryError) as exc:
        print(f"blobflow: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    except Exception as exc:  # noqa: BLE001 - one line, never a traceback
        print(f"blobflow: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
