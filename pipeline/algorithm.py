"""Base classes of blobflow's VTK algorithms, and running chains of them: errors reach the caller.

VTK calls a Python algorithm's ``RequestData`` from C++; an exception raised there is printed and
turned into a failed request, and ``Update()`` returns as if nothing happened.  Algorithms derived
from :class:`Algorithm` keep the exception, and :func:`raise_pending` re-raises it in the caller,
so a simulation that blows up stops the run with its own error message instead of writing an
empty frame. :func:`connect_chain` wires a chain of algorithms (any VTK algorithm, ours or not),
:func:`update` updates one and re-raises what failed, :func:`run_chain` does both for a chain fed
by a data object; :class:`pipeline.Flow` and the frame tasks of :mod:`pipeline.tasks` use them.

A :class:`ParticleStage` (feature smoothing, attribute interpolation) reads the particles on its
second input port: :func:`connect_chain` connects that port to the chain's input.

:func:`vtk_messages` keeps what VTK would print (its output window and its logger) while a block
runs, so a failure is reported as one line with VTK's first error instead of dozens of lines of
VTK text on stderr.
"""

from __future__ import annotations

import re
from contextlib import contextmanager
from typing import TYPE_CHECKING

from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
from vtkmodules.vtkCommonCore import vtkLogger, vtkOutputWindow, vtkStringOutputWindow

if TYPE_CHECKING:
    from collections.abc import Iterable, Iterator, Sequence
    from typing import Any

    from vtkmodules.vtkCommonDataModel import vtkDataObject
    from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm

__all__ = ["Algorithm", "ParticleStage", "raise_pending", "vtk_messages", "VTKMessages",
           "connect_chain", "update", "run_chain"]


class Algorithm(VTKPythonAlgorithmBase):
    """A ``VTKPythonAlgorithmBase`` that remembers the exception of a failed request."""

    def __init__(self, *args: Any, **kwargs: Any):
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


class ParticleStage(Algorithm):
    """An :class:`Algorithm` whose input port 0 takes the output of the previous stage and input
    port 1 the particles the chain started from (connected by :func:`connect_chain`).

    Parameters
    ----------
    inputType : str
        Data type of port 0; port 1 takes any ``vtkPointSet``.
    outputType : str
        Data type of the output.
    """

    #: The input port that takes the particles.
    PARTICLES_PORT = 1

    def __init__(self, inputType: str = "vtkPolyData", outputType: str = "vtkPolyData"):
        Algorithm.__init__(self, nInputPorts=2, inputType=inputType, nOutputPorts=1,
                           outputType=outputType)

    def FillInputPortInformation(self, port, info):
        from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm

        info.Set(vtkAlgorithm.INPUT_REQUIRED_DATA_TYPE(),
                 "vtkPointSet" if port == self.PARTICLES_PORT else self.InputType)
        return 1


def raise_pending(algorithms: Iterable[vtkAlgorithm]) -> None:
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
def vtk_messages() -> Iterator[VTKMessages]:
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


def connect_chain(algorithms: Sequence[vtkAlgorithm], upstream: vtkAlgorithm | None = None,
                  data: vtkDataObject | None = None) -> None:
    """Connect a chain: each algorithm's input port 0 to the previous one's output port 0.

    The first algorithm's port 0, and port 1 of every :class:`ParticleStage` of the chain, get
    the chain's input: the output of ``upstream`` (a VTK algorithm) or the data object ``data``.

    Parameters
    ----------
    algorithms : sequence of vtkAlgorithm
    upstream : vtkAlgorithm, optional
    data : vtkDataObject, optional
        Exactly one of ``upstream`` and ``data``.
    """
    if (upstream is None) == (data is None):
        raise ValueError("connect_chain needs exactly one of upstream and data")

    def feed(algorithm, port):
        if upstream is not None:
            algorithm.SetInputConnection(port, upstream.GetOutputPort(0))
        else:
            algorithm.SetInputDataObject(port, data)

    previous = None
    for algorithm in algorithms:
        if previous is None:
            feed(algorithm, 0)
        else:
            algorithm.SetInputConnection(0, previous.GetOutputPort(0))
        if isinstance(algorithm, ParticleStage):
            feed(algorithm, ParticleStage.PARTICLES_PORT)
        previous = algorithm


def update(algorithm: vtkAlgorithm, chain: Iterable[vtkAlgorithm], time: float | None = None,
           what: str = "the VTK pipeline") -> vtkDataObject:
    """Update ``algorithm`` (at ``time`` when given) and return a shallow copy of its output.

    The first exception kept by any algorithm of ``chain`` (:func:`raise_pending`) is re-raised;
    a failure of a VTK filter without a Python exception raises ``RuntimeError`` naming
    ``what``, the time and VTK's first error (VTK's own text is not printed).
    """
    with vtk_messages() as log:  # our own exception says it better than VTK's echo of it
        ok = algorithm.Update() if time is None else algorithm.UpdateTimeStep(float(time))
    raise_pending(chain)
    if not ok:
        detail = log.errors[0] if log.errors else "no message"
        at = "" if time is None else f" at t = {time}"
        raise RuntimeError(f"{what} failed{at} ({algorithm.GetClassName()}): {detail}")
    data = algorithm.GetOutputDataObject(0)
    copy = data.NewInstance()
    copy.ShallowCopy(data)
    return copy


def run_chain(algorithms: Iterable[vtkAlgorithm], data: vtkDataObject, time: float | None = None,
              what: str = "the VTK pipeline") -> vtkDataObject:
    """Feed ``data`` to a chain (:func:`connect_chain`), update its last algorithm
    (:func:`update`) and return a copy of the result."""
    algorithms = list(algorithms)
    connect_chain(algorithms, data=data)
    return update(algorithms[-1], algorithms, time, what)
