"""Tasks for the frame-parallel tests, pickled by value so Dask workers need not import tests/."""

import os
from pathlib import Path

import numpy as np
from vtkmodules.util import numpy_support

from pipeline.io.series import read_frame, write_frame


def lift_task(in_file, out_file, time, options):
    """Deterministic per-frame work: add a ``height`` array (z * scale) and write the frame."""
    data = read_frame(in_file)
    z = numpy_support.vtk_to_numpy(data.GetPoints().GetData())[:, 2] * options.get("scale", 1.0)
    array = numpy_support.numpy_to_vtk(np.ascontiguousarray(z), deep=True)
    array.SetName("height")
    data.GetPointData().AddArray(array)
    write_frame(data, out_file)


def failing_task(in_file, out_file, time, options):
    """Fails for the frame index in ``options['bad']`` every time."""
    if Path(in_file).stem.endswith(f"_{options['bad']:06d}"):
        raise RuntimeError("this frame is cursed")
    lift_task(in_file, out_file, time, options)


def killing_task(in_file, out_file, time, options):
    """Kills its own worker process the first time it sees frame ``options['victim']``."""
    marker = Path(options["marker"])
    if Path(in_file).stem.endswith(f"_{options['victim']:06d}") and not marker.exists():
        marker.write_text(str(os.getpid()))
        os._exit(1)  # the worker dies mid-task; the nanny starts a new one
    lift_task(in_file, out_file, time, options)
