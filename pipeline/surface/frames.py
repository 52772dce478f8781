"""The surface of every frame of a particle series (:func:`surface_series`), serially or on a
Dask cluster through :func:`pipeline.tasks.map_frames`, with a record beside the series of what
its frames were computed from (:func:`check_provenance`), so that ``resume`` never keeps frames
of another input or other options.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from filters.validation import check_int

from ..algorithm import run_chain
from ..io.convert import set_time
from ..io.folderlock import holds_folder
from ..io.outfiles import atomic_path, frame_names
from ..io.series import read_collection, read_frame, write_frame
from ..tasks import FramesResult, map_frames
from .across_frames import smooth_series_across_frames
from .stages import surface_stages

if TYPE_CHECKING:
    from dask.distributed import Client

__all__ = ["surface_series", "surface_frame", "check_provenance", "provenance_path"]


def surface_frame(in_file: str, out_file: str, time: float, options: dict) -> None:
    """Task: read one particle frame, reconstruct its surface, write it (``.vtp``)."""
    particles = read_frame(in_file)
    copy = run_chain(surface_stages(**options), particles, what=f"surface of {in_file}")
    set_time(copy, time)
    write_frame(copy, out_file)


def provenance_path(output_path: str | Path) -> Path:
    """The file beside a series that records what its frames were computed from
    (``NAME.source.json``)."""
    output_path = Path(output_path)
    return output_path.with_name(f"{output_path.stem}.source.json")


def _provenance(particles_path: Path, options: dict, across_frames: int) -> dict:
    """What a surface series is computed from: the input collection, every input frame's
    size and modification time, and the options."""
    frames = []
    for _, rel in read_collection(particles_path):
        try:
            stat = os.stat(particles_path.parent / rel)
            frames.append([rel, stat.st_size, stat.st_mtime_ns])
        except OSError:
            frames.append([rel, None, None])
    return {"input": str(particles_path.resolve()), "frames": frames,
            "options": json.loads(json.dumps(options, sort_keys=True, default=repr)),
            "across_frames": int(across_frames)}


def _provenance_change(old: dict, new: dict) -> str | None:
    """How ``new`` differs from ``old`` (one phrase), or None."""
    if old.get("input") != new["input"]:
        return f"from another input ({old.get('input')})"
    if old.get("frames") != new["frames"]:
        before = {f[0]: f[1:] for f in old.get("frames") or [] if isinstance(f, list) and f}
        changed = [f[0] for f in new["frames"] if before.get(f[0]) != f[1:]]
        what = f"frame {changed[0]} changed" if changed else "its frames changed"
        return f"from another version of the input ({what} since)"
    if old.get("across_frames") != new["across_frames"]:
        return (f"with --across-frames {old.get('across_frames')}, not "
                f"{new['across_frames']}")
    before, after = old.get("options") or {}, new["options"]
    keys = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
    if keys:
        listed = ", ".join(f"{k} {before.get(k, 'default')!r} -> {after.get(k, 'default')!r}"
                           for k in keys[:4])
        return f"with other options ({listed})"
    return None


def check_provenance(output_path: str | Path, record: dict, resume: bool) -> None:
    """On ``resume``, refuse to keep frames computed from another input or with other options;
    then record what this run computes from (``NAME.source.json``, atomically).

    Raises
    ------
    ValueError
        If ``resume`` and the frames on disk were computed from something else, or nothing
        says what they were computed from; the message says how to recompute them.
    """
    output_path = Path(output_path)
    path = provenance_path(output_path)
    if resume:
        old = None
        if path.is_file():
            try:
                old = json.loads(path.read_text(encoding="utf-8"))
            except (OSError, ValueError, RecursionError):
                old = None
        frames = frame_names(output_path.parent / output_path.stem, output_path.stem)
        change = ("from an unknown input (no readable record of it)"
                  if frames and not isinstance(old, dict)
                  else _provenance_change(old, record) if isinstance(old, dict) else None)
        if change is not None:
            raise ValueError(f"--resume: the frames of {output_path} were computed {change}; "
                             f"run without --resume to compute them again")
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")


@holds_folder("output_path")
def surface_series(particles_path: str | Path, output_path: str | Path, *,
                   client: Client | None = None, resume: bool = False,
                   progress: bool = True, across_frames: int = 0,
                   **surface_options: Any) -> FramesResult:
    """Reconstruct the surface of every frame of a particle series.

    ``surface_options`` are those of :func:`pipeline.surface.surface_stages` (``radius``,
    ``cell_size``, ``kernel``, ``smooth_iterations``, ...).  See :func:`pipeline.tasks.map_frames`
    for ``client`` and ``resume``. ``across_frames`` ``K`` in [0, 10]: with ``K > 0`` every frame's
    surface is then smoothed with those of the ``K`` frames on each side
    (:mod:`pipeline.surface.across_frames`; the particles need an ``id`` array).

    What the frames are computed from (the input's frames and the options) is recorded beside
    the series (:func:`check_provenance`); ``resume`` refuses frames computed from anything
    else instead of keeping them.
    """
    across_frames = check_int("across_frames", across_frames, 0, 10)
    surface_stages(**surface_options)  # validate the options here, before any task runs
    particles_path, output_path = Path(particles_path), Path(output_path)
    if output_path.suffix != ".pvd":
        raise ValueError(f"output_path must end in .pvd, got {str(output_path)!r}")
    record = _provenance(particles_path, surface_options, across_frames)
    check_provenance(output_path, record, resume)  # before any frame is kept or removed
    if across_frames:
        def single(source, target, **kwargs):
            check_provenance(target, record, kwargs.get("resume", False))
            return map_frames(source, target, surface_frame, surface_options, **kwargs)

        return smooth_series_across_frames(particles_path, output_path, across_frames,
                                           surface_options, single=single, client=client,
                                           resume=resume, progress=progress)
    return map_frames(particles_path, output_path, surface_frame, surface_options, client=client,
                      resume=resume, progress=progress)
