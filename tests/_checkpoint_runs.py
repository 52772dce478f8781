"""Flows for the checkpoint tests, and a driver that runs one and kills its own process.

Usage: python _checkpoint_runs.py OUT FLOW WHERE INDEX

FLOW is ``ballistic`` (ballistic particles and their elevation, two series, 11 frames, a
checkpoint every 4) or ``drop`` (the SPH drop at a small size, 7 frames, a checkpoint every 3).
The process sends itself SIGKILL (nothing runs after it: no handler, no clean-up) at frame INDEX:

* ``after_frame``: after the frame and its checkpoint (if it has one) are written;
* ``mid_frame``: after the first series' frame is written, before the second's (ballistic);
* ``before_checkpoint``: after the frame, before its checkpoint is written;
* ``inside_checkpoint``: with the new checkpoint complete in its temporary file, not yet renamed.
"""

import os
import signal
import sys
from pathlib import Path


def build(kind, simulation=None):
    """The flow named ``kind`` (``ballistic``: of ``simulation`` when given) and its
    ``checkpoint_every``."""
    if kind == "ballistic":
        from _helpers import ballistic
        from vtkmodules.vtkFiltersCore import vtkElevationFilter

        from pipeline import Flow, SimulationSource

        flow = Flow(SimulationSource(simulation or ballistic(), fps=20, frames=11))
        flow.add("elevation", vtkElevationFilter())
        return flow, 4
    if kind == "drop":
        from pipeline.scene import load_scene

        flow = load_scene("drop").build(surface=False, spacing=0.02)
        flow.source.set_frames(10.0, frames=7)
        return flow, 3
    raise ValueError(f"unknown flow {kind!r}")


def run(out, kind, *, resume=False):
    """Run the flow ``kind`` into ``out``; return the flow and its series."""
    flow, every = build(kind)
    return flow, flow.run(out, resume=resume, progress=False, checkpoint_every=every)


def _kill():
    os.kill(os.getpid(), signal.SIGKILL)


def _main(out, kind, where, index):
    import pipeline.compose as compose
    from pipeline.io.series import SeriesWriter

    flow, every = build(kind)
    on_frame = None
    if where == "after_frame":
        def on_frame(i, t):
            if i == index:
                _kill()
    elif where == "mid_frame":
        write = SeriesWriter.write

        def guarded(self, data, time):
            if self.name == "elevation" and len(self.entries) == index:
                _kill()
            return write(self, data, time)

        SeriesWriter.write = guarded
    elif where in ("before_checkpoint", "inside_checkpoint"):
        original = compose.write_checkpoint
        replace = os.replace

        def renaming(src, dst):
            if str(dst).endswith(".checkpoint.npz"):
                _kill()
            return replace(src, dst)

        def writing(path, checkpoint):
            if checkpoint.frame == index:
                if where == "before_checkpoint":
                    _kill()
                os.replace = renaming
            return original(path, checkpoint)

        compose.write_checkpoint = writing
    else:
        raise ValueError(f"unknown kill point {where!r}")
    flow.run(out, progress=False, on_frame=on_frame, checkpoint_every=every)
    raise SystemExit(f"the run ended without being killed at frame {index}")


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).parent))
    _main(Path(sys.argv[1]), sys.argv[2], sys.argv[3], int(sys.argv[4]))
