"""The simulation protocol every blobflow simulation implements.

A simulation is split, in the manner of NVIDIA Warp's ``sim`` module, into

* a **model**: everything fixed at construction (masses, rest lengths, topology, parameters).
  Models are immutable; their arrays are made read-only.
* a **state**: what evolves (``time``, ``positions``, ``velocities`` and any extra arrays).  A
  :class:`State` can be copied, restored and flattened to a dict of arrays, which is how the
  pipeline writes a checkpoint into every frame so that a run can resume from any frame on disk.

A :class:`Simulation` couples one model with one state and advances it with :meth:`Simulation.step`
or :meth:`Simulation.advance_to`.  What it produces for visualisation is described by an
:class:`OutputSpec` (point arrays and topology) and returned by :meth:`Simulation.frame` as a
:class:`Frame` of plain NumPy arrays.  Nothing here imports VTK: the pipeline package turns frames
into VTK datasets.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "State",
    "Frame",
    "OutputSpec",
    "Simulation",
    "SimulationError",
    "SimulationUnstableError",
    "frame_times",
    "TIME_DECIMALS",
    "MAX_FRAMES",
    "MAX_FPS",
]

#: Published and written times are rounded to this many decimals, so that ``3 / 10`` is written
#: and published as ``0.3`` and not ``0.30000000000000004``.
TIME_DECIMALS = 9

_STATE_PREFIX = "extra:"


class SimulationError(RuntimeError):
    """Base class of the errors a simulation raises while running."""


class SimulationUnstableError(SimulationError):
    """A simulation diverged: a value became non-finite or left its valid range.

    Parameters
    ----------
    time : float
        Simulated time (s) at which the problem was detected.
    quantity : str
        Name of the quantity that diverged (``"positions"``, ``"density error"``, ...).
    cause : str
        The likely cause and what to change, in words.
    """

    def __init__(self, time: float, quantity: str, cause: str = ""):
        self.time = float(time)
        self.quantity = quantity
        self.cause = cause
        message = f"simulation became unstable at t = {self.time:.6g} s: {quantity}"
        if cause:
            message += f" ({cause})"
        super().__init__(message)


def _as_points(name: str, value, n: int | None = None) -> np.ndarray:
    """Return ``value`` as a C-contiguous ``(N, 3) float64`` copy, or raise naming ``name``."""
    array = np.array(value, dtype=np.float64, copy=True, order="C")
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {array.shape}")
    if n is not None and array.shape[0] != n:
        raise ValueError(f"{name} must have {n} rows to match positions, got {array.shape[0]}")
    if not np.isfinite(array).all():
        raise ValueError(f"{name} contains NaN or infinite values")
    return array


@dataclass
class State:
    """The evolving part of a simulation.

    Parameters
    ----------
    positions : (N, 3) float64 array
        Particle positions (m).
    velocities : (N, 3) float64 array, optional
        Particle velocities (m/s); zeros when omitted.
    time : float
        Simulated time (s).
    step : int
        Number of steps taken since time 0.
    extra : dict of str to ndarray
        Any further arrays the simulation evolves (densities, emitter counters, RNG state...).
        They are copied and checkpointed with the state.
    """

    positions: np.ndarray
    velocities: np.ndarray | None = None
    time: float = 0.0
    step: int = 0
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        self.positions = _as_points("positions", self.positions)
        n = self.positions.shape[0]
        if self.velocities is None:
            self.velocities = np.zeros((n, 3))
        else:
            self.velocities = _as_points("velocities", self.velocities, n)
        if not math.isfinite(self.time):
            raise ValueError(f"time must be finite, got {self.time}")
        self.time = float(self.time)
        self.step = int(self.step)
        self.extra = {str(k): np.array(v, copy=True) for k, v in self.extra.items()}

    @property
    def n_points(self) -> int:
        """Number of particles ``N``."""
        return self.positions.shape[0]

    def copy(self) -> State:
        """Return a deep copy (arrays are copied)."""
        return State(self.positions, self.velocities, self.time, self.step, self.extra)

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Flatten to a dict of arrays, exact to the bit, for checkpoints.

        Returns
        -------
        dict of str to ndarray
            ``time`` (1,) float64, ``step`` (1,) int64, ``positions``, ``velocities`` and one
            ``extra:NAME`` entry per extra array.
        """
        arrays = {
            "time": np.array([self.time], dtype=np.float64),
            "step": np.array([self.step], dtype=np.int64),
            "positions": self.positions.copy(),
            "velocities": self.velocities.copy(),
        }
        for name, value in self.extra.items():
            arrays[_STATE_PREFIX + name] = np.array(value, copy=True)
        return arrays

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray]) -> State:
        """Rebuild a state written by :meth:`to_arrays`."""
        missing = {"time", "step", "positions", "velocities"} - set(arrays)
        if missing:
            raise ValueError(f"checkpoint is missing the arrays {sorted(missing)}")
        extra = {
            name[len(_STATE_PREFIX):]: np.asarray(value)
            for name, value in arrays.items()
            if name.startswith(_STATE_PREFIX)
        }
        return cls(
            positions=np.asarray(arrays["positions"], dtype=np.float64).reshape(-1, 3),
            velocities=np.asarray(arrays["velocities"], dtype=np.float64).reshape(-1, 3),
            time=float(np.asarray(arrays["time"]).ravel()[0]),
            step=int(np.asarray(arrays["step"]).ravel()[0]),
            extra=extra,
        )


@dataclass(frozen=True)
class OutputSpec:
    """What a simulation's frames contain.

    Parameters
    ----------
    point_arrays : tuple of (str, int)
        Name and number of components of every point-data array, in a stable order.  Names follow
        the project's conventions: ``velocity``, ``density``, ``pressure``, ``id``.
    topology : {"vertices", "lines", "polys", "cells"}
        ``"vertices"``: one vertex cell per point (particles); ``"lines"`` (hair, springs) and
        ``"polys"`` (cloth, surfaces) as VTK cell arrays; ``"cells"``: volumetric cells with VTK
        cell types (an unstructured grid).
    fixed_topology : bool
        Whether the connectivity is the same in every frame (cloth, jello, hair), which allows
        exports such as XDMF that share one mesh across time.
    cell_arrays : tuple of (str, int)
        Name and number of components of every cell-data array (e.g. the strain energy density
        of finite elements), in a stable order; none by default.
    """

    point_arrays: tuple = (("velocity", 3), ("id", 1))
    topology: str = "vertices"
    fixed_topology: bool = True
    cell_arrays: tuple = ()

    def __post_init__(self):
        if self.topology not in ("vertices", "lines", "polys", "cells"):
            raise ValueError(
                "topology must be one of 'vertices', 'lines', 'polys', 'cells', "
                f"got {self.topology!r}"
            )

    @property
    def dataset(self) -> str:
        """The natural VTK dataset type: ``"unstructured"`` for cells, ``"polydata"`` otherwise."""
        return "unstructured" if self.topology == "cells" else "polydata"


@dataclass
class Frame:
    """One output frame as plain arrays.

    Parameters
    ----------
    time : float
        Simulated time (s).
    points : (M, 3) float64 array
        Output points (m).  Often the particle positions; for an embedded mesh, the mesh vertices.
    point_data : dict of str to ndarray
        Arrays of M rows, named as in the simulation's :class:`OutputSpec`.
    connectivity : tuple (offsets, indices) of int64 arrays, optional
        Cells in CSR form: cell ``c`` uses ``indices[offsets[c]:offsets[c+1]]``.  ``None`` for
        vertices, where every point is its own vertex cell.
    cell_types : (C,) uint8 array, optional
        VTK cell type of every cell, for ``topology == "cells"``.
    cell_data : dict of str to ndarray, optional
        Arrays of C rows, one per cell, named as in the :class:`OutputSpec`'s ``cell_arrays``.
    field_data : dict of str to ndarray
        Arrays about the whole frame (an energy account), written as field data.
    """

    time: float
    points: np.ndarray
    point_data: dict
    connectivity: tuple | None = None
    cell_types: np.ndarray | None = None
    cell_data: dict | None = None
    field_data: dict = field(default_factory=dict)


#: Most frames one run may have (a million frames is over nine hours at 30 fps).
MAX_FRAMES = 1_000_000
#: Highest frame rate: frame times are rounded to :data:`TIME_DECIMALS` decimals and must differ.
MAX_FPS = 1e6


def frame_times(fps: float, duration: float | None = None, frames: int | None = None) -> np.ndarray:
    """Times of the frames of a run, rounded to :data:`TIME_DECIMALS` decimals.

    Parameters
    ----------
    fps : float
        Frames per second, in (0, :data:`MAX_FPS`].
    duration : float, optional
        Length of the run (s), >= 0.  The frames are ``0, 1/fps, ...`` up to ``duration``, at
        most :data:`MAX_FRAMES` of them.
    frames : int, optional
        Number of frames instead of ``duration``, in [1, :data:`MAX_FRAMES`].  Give exactly one
        of the two.

    Returns
    -------
    (F,) float64 array
        ``round(i / fps, 9)`` for ``i = 0 .. F-1``.
    """
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and 0 < fps <= MAX_FPS):
        raise ValueError(f"fps must be a number in (0, {MAX_FPS:g}], got {fps!r}")
    if (duration is None) == (frames is None):
        raise ValueError("give exactly one of duration (s) and frames (count)")
    if frames is None:
        if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration >= 0):
            raise ValueError(f"duration must be a number >= 0 (s), got {duration!r}")
        count = math.floor(duration * fps + 1e-9) + 1
        if count > MAX_FRAMES:
            raise ValueError(f"duration {duration:g} s at {fps:g} fps gives {count:.4g} frames, "
                             f"more than the {MAX_FRAMES:,} a run may have")
        frames = int(count)
    elif not (isinstance(frames, (int, np.integer)) and 1 <= frames <= MAX_FRAMES):
        raise ValueError(f"frames must be an integer in [1, {MAX_FRAMES:,}], got {frames!r}")
    return np.array([round(i / fps, TIME_DECIMALS) for i in range(int(frames))], dtype=np.float64)


class Simulation:
    """Base class of every simulation: a fixed model and an evolving :class:`State`.

    Subclasses set ``self.model`` and ``self.state`` in ``__init__``, implement :meth:`_step`
    (advance ``self.state`` arrays by ``dt`` in place, without touching ``time`` or ``step``), and
    may override :attr:`output_spec`, :meth:`frame` and :meth:`max_step`.

    Attributes
    ----------
    model : object
        Immutable parameters and topology.
    state : State
        The evolving state.
    steps_taken : int
        Number of calls to :meth:`step` since construction (including those made by
        :meth:`advance_to`); used by the pipeline's tests to prove that a cached frame is not
        re-simulated.
    """

    #: Largest step (s) :meth:`advance_to` takes; subclasses set it from their stability limit.
    max_dt: float = 1.0 / 240.0
    #: Words added to :class:`SimulationUnstableError` when positions or velocities become NaN.
    instability_hint: str = "the time step is probably too large for the forces involved"

    model: object
    state: State
    steps_taken: int = 0

    # -- protocol -------------------------------------------------------------------------
    @property
    def output_spec(self) -> OutputSpec:
        """Description of the frames this simulation returns."""
        return OutputSpec()

    def frame(self) -> Frame:
        """The current state as output arrays (copies)."""
        s = self.state
        return Frame(
            time=s.time,
            points=s.positions.copy(),
            point_data={
                "velocity": s.velocities.copy(),
                "id": np.arange(s.n_points, dtype=np.int64),
            },
        )

    def _step(self, dt: float) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def max_step(self) -> float:
        """Largest stable step (s) for the current state; :attr:`max_dt` unless overridden."""
        return self.max_dt

    # -- driving ----------------------------------------------------------------------------
    def step(self, dt: float) -> None:
        """Advance the state by ``dt`` seconds (one step of the integrator).

        Raises
        ------
        ValueError
            If ``dt`` is not a finite number > 0.
        SimulationUnstableError
            If positions or velocities become non-finite.
        """
        if not (isinstance(dt, (int, float, np.floating)) and math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a finite number > 0 (s), got {dt!r}")
        self._step(float(dt))
        self.state.time += float(dt)
        self.state.step += 1
        self.steps_taken += 1
        self.check_finite()

    def advance_to(self, time: float) -> None:
        """Step forward until the state's time equals ``time`` exactly.

        Steps of at most :meth:`max_step`; the last one is shortened to land on ``time``, and the
        state's time is then set to ``time`` so that frame times never drift.

        Raises
        ------
        ValueError
            If ``time`` is earlier than the current time (restore an earlier state instead).
        """
        time = float(time)
        if not math.isfinite(time):
            raise ValueError(f"time must be finite, got {time}")
        current = self.state.time
        if time < current - 1e-12:
            raise ValueError(
                f"cannot advance backwards from t = {current} to t = {time}; restore a saved state"
            )
        while self.state.time < time:
            remaining = time - self.state.time
            dt = self.max_step()
            if remaining <= dt * (1.0 + 1e-9):
                self.step(remaining)
                self._land_on(time)  # exactly on the frame time: no drift
                break
            if self.split_last_steps and remaining < 2.0 * dt:
                dt = 0.5 * remaining
            self.step(dt)

    #: Cross the time left in two equal steps where it is between one and two steps, so that no
    #: last step is a sliver (solvers whose projection acts within the step they are given).
    split_last_steps: bool = False

    def _land_on(self, time: float) -> None:
        """Set the state's time to ``time`` after the last, shortened step."""
        self.state.time = time

    def check_finite(self) -> None:
        """Raise :class:`SimulationUnstableError` if positions or velocities are non-finite."""
        s = self.state
        for name, array in (("positions", s.positions), ("velocities", s.velocities)):
            if not np.isfinite(array).all():
                raise SimulationUnstableError(s.time, f"non-finite {name}", self.instability_hint)

    def get_state(self) -> State:
        """A copy of the current state."""
        return self.state.copy()

    def set_state(self, state: State) -> None:
        """Restore a state (copied), e.g. one returned by :meth:`get_state` or a checkpoint.

        Raises
        ------
        ValueError
            If the state's array shapes do not match this simulation's.
        """
        if not isinstance(state, State):
            raise TypeError(f"state must be a State, got {type(state).__name__}")
        current = self.state
        if state.positions.shape != current.positions.shape and not self.variable_count:
            raise ValueError(
                f"state has {state.n_points} points, this simulation has {current.n_points}"
            )
        self.state = state.copy()

    #: True for simulations whose particle count changes (emitters); relaxes :meth:`set_state`.
    variable_count: bool = False
