"""A temporal VTK source that wraps any :class:`filters.Simulation`."""

from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np
from vtkmodules.vtkCommonDataModel import vtkDataObject
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline

from filters.simulation import TIME_DECIMALS, Simulation, State, frame_times
from filters.validation import check_bool, check_choice, check_int

from .algorithm import Algorithm
from .io.convert import frame_to_vtk

__all__ = ["SimulationSource"]

_SDDP = vtkStreamingDemandDrivenPipeline
_VTK_TYPES = {"polydata": "vtkPolyData", "unstructured": "vtkUnstructuredGrid"}


class SimulationSource(Algorithm):
    """Temporal VTK source publishing the frames of a simulation.

    The source publishes ``TIME_STEPS`` and ``TIME_RANGE`` from ``fps`` and ``duration`` (or
    ``frames``), rounded as they are written.  Asked for a time by a downstream
    ``UPDATE_TIME_STEP``, it advances the simulation from its current state; asked for an earlier
    time, it restores the latest cached frame state at or before that time instead of simulating
    again from 0.  Asking twice for the same time does not step.

    Its outputs keep their particles in one order, by ``id`` (:func:`pipeline.io.convert.id_order`),
    whatever order the simulation keeps them in, and carry what a viewer needs, not the
    simulation's state: a :class:`Flow` keeps a checkpoint beside the series it writes
    (:mod:`pipeline.io.checkpoint`).

    Parameters
    ----------
    simulation : filters.Simulation
        The simulation to drive.  Its current state is time 0 of the series.
    fps : float
        Frames per second (> 0).
    duration : float, optional
        Simulated seconds (>= 0).  Default 2 s when neither ``duration`` nor ``frames`` is given.
    frames : int, optional
        Number of frames instead of ``duration``.
    cache_size : int
        How many frame states (besides the initial one, which is always kept) to keep for going
        back in time; the least recently used is dropped first.  ``0`` keeps only the initial one.
    dataset : {"polydata", "unstructured"}, optional
        Output type; the simulation's natural type when omitted.
    checkpoint : bool
        Whether a :meth:`Flow.run <pipeline.compose.Flow.run>` of this source keeps a
        checkpoint of the simulation beside its series, so that the run can be resumed
        (``resume=True``); the frames never carry one.

    Attributes
    ----------
    simulation : filters.Simulation
    times : (F,) float64 array
        The published times (s).
    """

    def __init__(self, simulation: Simulation, fps: float = 30.0, duration: float | None = None,
                 frames: int | None = None, *, cache_size: int = 16, dataset: str | None = None,
                 checkpoint: bool = True):
        if not isinstance(simulation, Simulation):
            raise TypeError(f"simulation must be a filters.Simulation, "
                            f"got {type(simulation).__name__}")
        spec = simulation.output_spec
        dataset = check_choice("dataset", dataset or spec.dataset, tuple(_VTK_TYPES))
        Algorithm.__init__(self, nInputPorts=0, nOutputPorts=1, outputType=_VTK_TYPES[dataset])
        self.simulation = simulation
        self.dataset = dataset
        self.checkpoint = check_bool("checkpoint", checkpoint)
        self.cache_size = check_int("cache_size", cache_size, 0)
        self.set_frames(fps, duration, frames)
        self._initial = simulation.get_state()
        self._cache: OrderedDict[float, State] = OrderedDict()
        self._from_initial = True  # the cached states were simulated from ``_initial``
        self._last_output = None  # (time, dataset) of the last RequestData

    # -- configuration -------------------------------------------------------------------------
    def set_frames(self, fps: float = 30.0, duration: float | None = None,
                   frames: int | None = None) -> None:
        """Set the published times: ``frames`` frames, or enough for ``duration`` seconds."""
        if duration is None and frames is None:
            duration = 2.0
        self.times = frame_times(fps, duration=duration, frames=frames)
        self.fps = float(fps)
        self.Modified()

    def reset(self, state: State | None = None) -> None:
        """Restart from ``state`` (or the initial state), which becomes the cached start."""
        self._from_initial = state is None or state is self._initial
        state = self._initial if state is None else state
        self.simulation.set_state(state)
        self._cache.clear()
        self._remember(self.simulation.get_state())
        self._last_output = None
        self.Modified()

    def rewind(self) -> None:
        """Back to the initial state, keeping the cached frame states when they were simulated
        from it (frames asked for before a run are not simulated again; the solvers are
        deterministic, so they are the states the run would reach); otherwise :meth:`reset`."""
        if not self._from_initial:
            self.reset()
            return
        self.simulation.set_state(self._initial)
        self._last_output = None
        self.Modified()

    def restore(self, state: State) -> None:
        """Continue from a checkpoint (e.g. the last frame of a series on disk, to resume)."""
        self.simulation.set_state(state)
        self._from_initial = False
        self._remember(self.simulation.get_state())
        self._last_output = None
        self.Modified()

    # -- VTK pipeline --------------------------------------------------------------------------
    def RequestInformation(self, request, inInfo, outInfo):
        info = outInfo.GetInformationObject(0)
        info.Remove(_SDDP.TIME_STEPS())
        info.Remove(_SDDP.TIME_RANGE())
        for t in self.times:
            info.Append(_SDDP.TIME_STEPS(), float(t))
        info.Set(_SDDP.TIME_RANGE(), [float(self.times[0]), float(self.times[-1])], 2)
        return 1

    def _requested_time(self, info) -> float:
        if info.Has(_SDDP.UPDATE_TIME_STEP()):
            t = info.Get(_SDDP.UPDATE_TIME_STEP())
        else:
            t = self.simulation.state.time
        # Snap to a published time when it is one up to round-off (ParaView passes them back).
        i = int(np.argmin(np.abs(self.times - t)))
        if abs(self.times[i] - t) <= 1e-9 * max(1.0, abs(t)):
            return float(self.times[i])
        if not math.isfinite(t):
            raise ValueError(f"requested time must be finite, got {t}")
        return round(min(max(t, float(self.times[0])), float(self.times[-1])), TIME_DECIMALS)

    def RequestData(self, request, inInfo, outInfo):
        info = outInfo.GetInformationObject(0)
        t = self._requested_time(info)
        output = vtkDataObject.GetData(outInfo, 0)
        if (self._last_output is not None and self._last_output[0] == t
                and self.simulation.state.time == t):
            output.ShallowCopy(self._last_output[1])
            output.GetInformation().Set(vtkDataObject.DATA_TIME_STEP(), t)
            return 1
        self._go_to(t)
        data = self.current_dataset()
        # remembered after the frame: a simulation may tidy its state while making one (SPH
        # sorts its particles by cell), and a run continued from this state (a checkpoint, a
        # step back in time) must continue from what an uninterrupted run had
        self._remember(self.simulation.get_state())
        output.ShallowCopy(data)
        output.GetInformation().Set(vtkDataObject.DATA_TIME_STEP(), t)
        self._last_output = (t, data)
        return 1

    # -- time travel ---------------------------------------------------------------------------
    def go_to(self, t: float) -> None:
        """Bring the simulation to time ``t``, from the cache when ``t`` is in the past."""
        self._go_to(t)
        self._remember(self.simulation.get_state())

    def _go_to(self, t: float) -> None:
        sim = self.simulation
        if sim.state.time > t:
            sim.set_state(self._cached_before(t))
        elif sim.state.time < t:
            cached = self._cached_before(t)
            if cached.time > sim.state.time:
                sim.set_state(cached)
        if sim.state.time < t:
            sim.advance_to(t)

    def current_dataset(self) -> vtkDataObject:
        """The simulation's current frame as a VTK dataset, its particles in ``id`` order."""
        sim = self.simulation
        return frame_to_vtk(sim.frame(), sim.output_spec, self.dataset)

    def state_at(self, t: float) -> State | None:
        """A copy of the state cached at time ``t`` (s) after its frame was made, or ``None``.

        The initial state is not returned for time 0: a simulation may change its state while
        making a frame (SPH sorts its particles), so only the state after the frame is what a
        run continues from.
        """
        state = self._cache.get(t)
        return None if state is None else state.copy()

    def _cached_before(self, t: float) -> State:
        best = self._initial if self._initial.time <= t else None
        for time, state in self._cache.items():
            if time <= t and (best is None or time > best.time):
                best = state
        if best is None:
            raise ValueError(f"no cached state at or before t = {t}")
        if best.time in self._cache:
            self._cache.move_to_end(best.time)
        return best

    def _remember(self, state: State) -> None:
        if state.time == self._initial.time:
            return
        self._cache[state.time] = state
        self._cache.move_to_end(state.time)
        while len(self._cache) > self.cache_size:
            self._cache.popitem(last=False)

    @property
    def cached_times(self) -> list[float]:
        """Times of the cached states, the initial one first."""
        return [self._initial.time] + sorted(self._cache)
