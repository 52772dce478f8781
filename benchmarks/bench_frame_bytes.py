"""Bytes a particle of the particle frames of ``drop`` and ``dam_break``, with and without the
simulation's state in every frame.

Each scene runs at its default size (no surface) through ``Flow.run``; after every frame the same
frame is also written with the state attached as ``state:*`` field data, as blobflow wrote
frames before the checkpoint moved beside the series (:mod:`pipeline.io.checkpoint`).  Both files
are written by :func:`pipeline.io.series.write_frame` (raw appended, zlib level 1).  The checkpoint
file's size is recorded too (one file per run, not per frame).

Usage::

    flock /tmp/blobflow-heavy.lock python benchmarks/bench_frame_bytes.py [--frames-drop 31]
        [--frames-dam-break 11] [--out benchmarks/results/frame_bytes.json]
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipeline.io.convert import state_to_field_data  # noqa: E402
from pipeline.io.series import read_frame, write_frame  # noqa: E402
from pipeline.scene import load_scene  # noqa: E402


def measure(scene: str, frames: int, folder: Path) -> dict:
    """Run ``scene`` for ``frames`` frames at 30 fps; bytes a particle of every frame."""
    flow = load_scene(scene).build(surface=False)
    flow.source.set_frames(30.0, frames=frames)
    sim = flow.source.simulation
    lean, with_state = [], []

    def on_frame(index, t):
        path = folder / "particles" / f"particles_{index:06d}.vtp"
        data = read_frame(path)
        state_to_field_data(data, sim.state)  # as every frame carried it before
        legacy = write_frame(data, folder / "legacy" / path.name)
        n = sim.state.n_points
        lean.append(round(path.stat().st_size / n, 1))
        with_state.append(round(legacy.stat().st_size / n, 1))

    start = time.perf_counter()
    flow.run(folder, progress=False, on_frame=on_frame)
    return {
        "particles": sim.state.n_points,
        "frames": frames,
        "fps": 30.0,
        "bytes_per_particle": lean,
        "bytes_per_particle_with_state_in_frame": with_state,
        "largest": max(lean),
        "largest_with_state_in_frame": max(with_state),
        "checkpoint_bytes": (folder / "particles.checkpoint.npz").stat().st_size,
        "wall_s": round(time.perf_counter() - start, 1),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames-drop", type=int, default=31)
    parser.add_argument("--frames-dam-break", type=int, default=11)
    parser.add_argument("--out", default=str(Path(__file__).parent / "results" /
                                             "frame_bytes.json"))
    args = parser.parse_args(argv)
    results = {"machine": platform.machine(), "python": platform.python_version(), "scenes": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for scene, frames in (("drop", args.frames_drop), ("dam_break", args.frames_dam_break)):
            results["scenes"][scene] = measure(scene, frames, Path(tmp) / scene)
            r = results["scenes"][scene]
            print(f"{scene}: {r['particles']} particles, largest frame {r['largest']} B a "
                  f"particle ({r['largest_with_state_in_frame']} with the state in it), "
                  f"checkpoint {r['checkpoint_bytes']} B")
    Path(args.out).write_text(json.dumps(results, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
