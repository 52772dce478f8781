"""Base class of blobflow's VTK algorithms: Python exceptions reach the caller.

VTK calls a Python algorithm's ``RequestData`` from C++; an exception raised there is printed and
turned into a failed request, and ``Update()`` returns as if nothing happened.  Algorithms derived
from :class:`Algorithm` keep the exception, and :func:`raise_pending` (used by
:class:`pipeline.Flow`) re-raises it in the caller, so a simulation that blows up stops the run
with its own error message instead of writing an empty frame.
"""

from __future__ import annotations

from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase

__all__ = ["Algorithm", "raise_pending"]


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
