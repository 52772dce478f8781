"""What a long call tells its user: warning categories, the compile notice, a progress bar.

- :class:`BlobflowWarning`: the category of blobflow's warnings (e.g. a point array named in
  ``attributes`` that the particles lack); filter it with the :mod:`warnings` module.
- :class:`CompileNotice`: issued once per call when Numba starts compiling a kernel that is not
  in its on-disk cache (the first call on a machine, or after an upgrade, takes a minute or two;
  later calls load the compiled kernels). Numba announces each compilation that misses its
  cache (the ``numba:compile`` event), so a warm cache gives no notice. Silence it with
  ``warnings.filterwarnings("ignore", category=CompileNotice)``.
- :func:`stage_progress`: a progress bar over the stages of a VTK chain (``progress_bar=True``
  of :func:`pipeline.surface.reconstruct`, as PyVista's filters have).
"""

from __future__ import annotations

import contextlib
import sys
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

__all__ = ["BlobflowWarning", "CompileNotice", "compile_notice", "stage_progress"]


class BlobflowWarning(UserWarning):
    """A warning of blobflow's about its input (the call goes on)."""


class CompileNotice(BlobflowWarning):
    """Numba is compiling blobflow's kernels: this call takes a minute or two longer, once."""


_PACKAGES = tuple(str(Path(__file__).resolve().parent.parent / name) for name in
                  ("pipeline", "filters"))


def _user_frame(frame):
    """The first frame at or above ``frame`` outside blobflow's packages and contextlib."""
    while frame is not None:
        name = frame.f_code.co_filename
        if not (name.startswith(_PACKAGES) or name == contextlib.__file__):
            return frame
        frame = frame.f_back
    return None


def _distance(frame, target) -> int | None:
    """How many frames above ``frame`` ``target`` is (None when it is not above it)."""
    depth = 0
    while frame is not None:
        if frame is target:
            return depth
        frame = frame.f_back
        depth += 1
    return None


@contextmanager
def compile_notice(what: str) -> Iterator[None]:
    """Issue one :class:`CompileNotice` if Numba compiles a kernel inside the ``with`` block.

    The warning names the user's line that led to the call (the first frame outside blobflow's
    packages) as its origin.

    Parameters
    ----------
    what : str
        What is being computed, for the message (e.g. ``"the surface"``).
    """
    from numba.core import event

    origin = _user_frame(sys._getframe(1))

    class Listener(event.Listener):
        said = False

        def on_start(self, event_):
            if self.said:
                return
            self.said = True
            depth = _distance(sys._getframe(), origin)
            warnings.warn(f"blobflow: compiling Numba kernels for {what} (the first call only: "
                          f"a minute or two; later calls load them from Numba's cache)",
                          CompileNotice, stacklevel=2 if depth is None else depth + 1)

        def on_end(self, event_):
            pass

    listener = Listener()
    event.register("numba:compile", listener)
    try:
        yield
    finally:
        event.unregister("numba:compile", listener)


@contextmanager
def stage_progress(stages: Sequence, enabled: bool, desc: str) -> Iterator[None]:
    """A tqdm bar over VTK algorithms: one step each time a stage finishes, the running stage's
    name beside it. Nothing when ``enabled`` is false.

    Parameters
    ----------
    stages : sequence of vtkAlgorithm
        The chain about to be updated (each runs once).
    enabled : bool
        Show the bar (on stderr).
    desc : str
        The bar's label.
    """
    if not enabled:
        yield
        return
    from tqdm.auto import tqdm

    bar = tqdm(total=len(stages), desc=desc, unit="stage")
    observers = []
    for stage in stages:
        name = type(stage).__name__

        def start(_obj, _event, name=name):
            bar.set_postfix_str(name, refresh=True)

        def end(_obj, _event):
            bar.update(1)

        observers.append((stage, stage.AddObserver("StartEvent", start),
                          stage.AddObserver("EndEvent", end)))
    try:
        yield
    finally:
        for stage, a, b in observers:
            stage.RemoveObserver(a)
            stage.RemoveObserver(b)
        bar.close()
