"""The gallery: one still per scene, made from the scene's own defaults (``blobflow gallery``).

Each scene is run with its defaults (``blobflow run SCENE --no-render`` into ``RUNS/SCENE``,
unless a complete run of exactly those defaults is there already) and drawn at its most
interesting frame (:func:`pipeline.render.interesting_frame`) with its colliders, into
``OUT/SCENE.png`` (the README's scene table shows ``docs/SCENE.png``).  Regenerating the gallery
after a change to a scene or to the renderer keeps the pictures from drifting from the code.
"""

from __future__ import annotations

import json
from pathlib import Path

from filters.simulation import frame_times

from .series import SeriesError, read_collection

__all__ = ["run_is_current", "run_series", "gallery_still", "GALLERY_SIZE"]

#: Size (pixels) of the gallery's stills.
GALLERY_SIZE = (640, 480)


def _normal(value):
    """A parameter value as JSON gives it back (tuples as lists)."""
    return json.loads(json.dumps(value, default=list))


def run_is_current(directory, scene) -> bool:
    """Whether ``directory`` holds a complete run of ``scene`` with its defaults.

    True when its ``scene.json`` names the scene with exactly its default parameters and frame
    rate, and every series it lists has the frame times of the scene's default duration.

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
    for name in outputs:
        try:
            times = [t for t, _ in read_collection(directory / f"{name}.pvd")]
        except (FileNotFoundError, SeriesError):
            return False
        if times != expected:
            return False
    return True


def run_series(directory) -> list[Path]:
    """The series of a run folder, in the order its ``scene.json`` lists its outputs."""
    directory = Path(directory)
    record = json.loads((directory / "scene.json").read_text(encoding="utf-8"))
    return [directory / f"{name}.pvd" for name in record.get("outputs", [])]


def gallery_still(directory, out, *, size=GALLERY_SIZE) -> tuple[Path, int, str]:
    """Draw the gallery's still of the run in ``directory`` to ``out`` (PNG).

    Returns
    -------
    path : Path
        The image.
    index : int
        The frame drawn (the most interesting one).
    reason : str
        Why that frame.
    """
    from .render import interesting_frame, render_still

    series = run_series(directory)
    index, reason = interesting_frame(series)
    path, index = render_still(series, out, time_index=index, size=size)
    return path, index, reason
