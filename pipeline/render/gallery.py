"""The gallery: one still per scene, made from the scene's own defaults (``blobflow gallery``).

Each scene is run with its defaults (``blobflow run SCENE --no-render`` into ``RUNS/SCENE``,
unless a complete run of exactly those defaults, newer than the code that computes it, is there
already) and drawn at the scene's still time (:attr:`pipeline.scene.Scene.still`), else at its
most interesting frame (:func:`pipeline.render.interesting_frame`), with its colliders, into
``OUT/SCENE.png`` (the README's scene table shows ``docs/SCENE.png``).  Regenerating the gallery
after a change to a scene or to the renderer keeps the pictures from drifting from the code.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from filters.simulation import frame_times

from ..io.series import SeriesError, read_collection

if TYPE_CHECKING:
    from collections.abc import Sequence

    from ..scene import Scene

__all__ = ["run_is_current", "run_series", "gallery_still", "code_mtime", "GALLERY_SIZE",
           "DRAWING_MODULES"]

#: Size (pixels) of the gallery's stills.
GALLERY_SIZE = (640, 480)

#: Subpackages and modules of ``pipeline`` that draw or drive runs without changing their
#: numbers: a change to them does not make a run stale.
DRAWING_MODULES = ("cli", "paraview", "render", "__main__", "version")


def code_mtime(scene: Scene) -> float:
    """Newest modification time (s since the epoch) of the Python sources that compute a run of
    ``scene``: the ``filters`` package, the scene's own package and ``pipeline`` but for
    :data:`DRAWING_MODULES`."""
    import filters

    folders = [Path(filters.__file__).parent]
    module = sys.modules.get(getattr(scene.build_function, "__module__", ""), None)
    if module is not None and getattr(module, "__file__", None):
        folders.append(Path(module.__file__).parent)
    files = [f for folder in folders for f in folder.rglob("*.py")]
    root = Path(__file__).resolve().parent.parent  # pipeline/
    files += [f for f in root.rglob("*.py")
              if f.relative_to(root).parts[0].removesuffix(".py") not in DRAWING_MODULES]
    return max(f.stat().st_mtime for f in files)


def _normal(value):
    """A parameter value as JSON gives it back (tuples as lists)."""
    return json.loads(json.dumps(value, default=list))


def run_is_current(directory: str | Path, scene: Scene) -> bool:
    """Whether ``directory`` holds a complete, current run of ``scene`` with its defaults.

    True when its ``scene.json`` names the scene with exactly its default parameters and frame
    rate, every series it lists has the frame times of the scene's default duration, and every
    series was written after the last change to the code that computes it (:func:`code_mtime`).

    Parameters
    ----------
    directory : str or Path
        A run folder (``blobflow run --out``).
    scene : pipeline.scene.Scene
    """
    directory = Path(directory)
    try:
        record = json.loads((directory / "scene.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    if not isinstance(record, dict) or record.get("scene") != scene.name:
        return False
    if record.get("parameters") != _normal(scene.defaults()) or record.get("fps") != scene.fps:
        return False
    expected = [float(t) for t in frame_times(scene.fps, duration=scene.duration)]
    outputs = record.get("outputs") or []
    if not outputs:
        return False
    newest_code = code_mtime(scene)
    for name in outputs:
        path = directory / f"{name}.pvd"
        try:
            times = [t for t, _ in read_collection(path)]
        except (FileNotFoundError, SeriesError):
            return False
        if times != expected or path.stat().st_mtime < newest_code:
            return False
    return True


def run_series(directory: str | Path, outputs: Sequence[str] | None = None) -> list[Path]:
    """The series of a run folder, in the order its ``scene.json`` lists its outputs; only those
    named in ``outputs`` (e.g. :meth:`pipeline.compose.Flow.drawn_outputs`) when given."""
    directory = Path(directory)
    record = json.loads((directory / "scene.json").read_text(encoding="utf-8"))
    names = [n for n in record.get("outputs", []) if outputs is None or n in outputs]
    return [directory / f"{name}.pvd" for name in names]


def gallery_still(directory: str | Path, out: str | Path, *,
                  size: tuple[int, int] = GALLERY_SIZE, time: float | None = None,
                  outputs: Sequence[str] | None = None) -> tuple[Path, int, str]:
    """Draw the gallery's still of the run in ``directory`` to ``out`` (PNG): the frame nearest
    ``time`` (s; a scene's :attr:`~pipeline.scene.Scene.still`), else the most interesting one.

    Only the outputs named in ``outputs`` are drawn (the scene's
    :meth:`~pipeline.compose.Flow.drawn_outputs`; default every series of the run), so that a
    series written for other tools (the tetrahedra around an embedded mesh) stays off the
    picture.

    Returns
    -------
    path : Path
        The image.
    index : int
        The frame drawn (the most interesting one).
    reason : str
        Why that frame.
    """
    from .pictures import frame_at_time, interesting_frame, render_still

    series = run_series(directory, outputs) or run_series(directory)
    if time is not None:
        index, reason = frame_at_time(series, time), f"the scene's still at t = {time:g} s"
    else:
        index, reason = interesting_frame(series)
    path, index = render_still(series, out, time_index=index, size=size)
    return path, index, reason
