"""Base class of blobflow's VTK algorithms: Python exceptions reach the caller.

VTK calls a Python algorithm's ``RequestData`` from C++; an exception raised there is printed and
turned into a failed request, and ``Update()`` returns as if nothing happened.  Algorithms derived
from :class:`Algorithm` keep the exception, and :func:`raise_pending` (used by
:class:`pipeline.Flow`) re-raises it in the caller, so a simulation that blows up stops the run
with its own error message instead of writing an empty frame.

:func:`vtk_messages` keeps what VTK would print (its output window and its logger) while a block
runs, so a failure is reported as one line with VTK's first error instead of dozens of lines of
VTK text on stderr.
"""

from __future__ import annotations

import re
from contextlib import contextmanager

from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
from vtkmodules.vtkCommonCore import vtkLogger, vtkOutputWindow, vtkStringOutputWindow

__all__ = ["Algorithm", "raise_pending", "vtk_messages", "VTKMessages"]


class Algorithm(VTKPythonAlgorithmBase):
    """A ``VTKPythonAlgorithmBase`` that remembers the exception of a failed request."""

    def __init__(self, *args, **kwargs):
        VTKPythonAlgorithmBase.__init__(self, *args, **kwargs)
        self.pending_error: BaseException | None = None

    def ProcessRequest(self, request, inInfo, outInfo):
        try:
            return VTKPythonAlgorithmBase.ProcessRequest(self, request, inInfo, outInfo)
        except BaseException as exc:  # noqa: BLE001 - handed back to the caller by raise_pending
            # BaseException too: a Ctrl-C during a long RequestData must stop the run, not be
            # swallowed by VTK while the run goes on writing a frame that was never computed.
            self.pending_error = exc
            return 0


def raise_pending(algorithms) -> None:
    """Re-raise (and clear) the first exception kept by any of ``algorithms``."""
    for algorithm in algorithms:
        error = getattr(algorithm, "pending_error", None)
        if error is not None:
            algorithm.pending_error = None
            raise error


class VTKMessages:
    """What VTK reported inside a :func:`vtk_messages` block."""

    _ERROR = re.compile(r"^ERROR: In [^\n]*\n(?:[^\n(]*\([^)]*\): )?(?P<message>[^\n]*)", re.M)

    def __init__(self):
        self.text = ""

    @property
    def errors(self) -> list[str]:
        """The first line of every error VTK reported, in order."""
        return [m.group("message").strip() for m in self._ERROR.finditer(self.text)]


@contextmanager
def vtk_messages():
    """Collect VTK's error and warning text instead of printing it.

    Yields a :class:`VTKMessages`; its ``text`` and ``errors`` are filled when the block ends
    (also when it raises).  VTK's output window and its logger's stderr sink are restored after.
    """
    window = vtkStringOutputWindow()
    window.SetDisplayModeToNever()
    previous = vtkOutputWindow.GetInstance()
    verbosity = vtkLogger.GetCurrentVerbosityCutoff()
    vtkOutputWindow.SetInstance(window)
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)
    messages = VTKMessages()
    try:
        yield messages
    finally:
        messages.text = window.GetOutput()
        vtkOutputWindow.SetInstance(previous)
        vtkLogger.SetStderrVerbosity(verbosity)
