"""A small builder that chains stages into named outputs and runs them over all frames."""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from tqdm.auto import tqdm
from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm

from filters.validation import check_bool, check_int, check_range

from .algorithm import connect_chain, update
from .io.checkpoint import (
    CHECKPOINT_SUFFIX,
    Checkpoint,
    CheckpointError,
    file_digest,
    read_checkpoint,
    write_checkpoint,
)
from .io.colliders import COLLIDERS_FILE, Collider, write_colliders
from .io.convert import has_state, state_from_dataset
from .io.folderlock import holds_folder
from .io.outfiles import sweep_temporaries
from .io.series import SeriesWriter, read_frame
from .io.xdmf import export_xdmf
from .sources import SimulationSource

if TYPE_CHECKING:
    from collections.abc import Callable, Iterator

    import numpy as np
    from pyvista import DataSet

    from filters.geometry import Shape

__all__ = ["Flow", "Stage"]


@dataclass
class Stage:
    """A named output of a :class:`Flow`: the last algorithm of a chain, how to write it, and
    whether the renders of a run draw it."""

    name: str
    algorithm: vtkAlgorithm
    chain: list = field(default_factory=list)
    write: bool = True
    xdmf: bool = False
    draw: bool = True


def _check_name(name: str) -> str:
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"an output name must be a Python identifier such as 'surface', "
                         f"got {name!r}")
    return name


class Flow:
    """Chain a :class:`SimulationSource` and any VTK algorithms into named, written outputs.

    Parameters
    ----------
    source : SimulationSource
        The temporal source; its output is the first named output.
    name : str
        Name of the source's output (and of its series), default ``"particles"``.
    write : bool
        Whether to write the source's output as a series.
    xdmf : bool
        Also export it as XDMF (fixed topology only).
    draw : bool
        Whether the renders of a run (``blobflow run``) draw it; a written output that is not
        drawn is only on disk (e.g. the tetrahedra around an embedded surface).

    Examples
    --------
    >>> flow = Flow(SimulationSource(sim, fps=30, duration=2.0))          # doctest: +SKIP
    >>> flow.add("surface", MetaballSplat(), MarchingCubes())             # doctest: +SKIP
    >>> flow.add_collider("floor", Plane((0, 0, 0), (0, 0, 1)), role="floor")  # doctest: +SKIP
    >>> flow.run("outputs/demo")                                          # doctest: +SKIP
    """

    def __init__(self, source: SimulationSource, name: str = "particles", *, write: bool = True,
                 xdmf: bool = False, draw: bool = True):
        if not isinstance(source, SimulationSource):
            raise TypeError(f"source must be a SimulationSource, got {type(source).__name__}")
        self.source = source
        self.stages: dict[str, Stage] = {}
        self.stages[_check_name(name)] = Stage(name, source, [source], check_bool("write", write),
                                               check_bool("xdmf", xdmf), check_bool("draw", draw))
        self._primary = name
        self.colliders: list[Collider] = []

    @property
    def times(self) -> np.ndarray:
        """The frame times the flow runs over (s)."""
        return self.source.times

    def add(self, name: str, *algorithms: vtkAlgorithm, input: str | None = None,
            write: bool = True, xdmf: bool = False, draw: bool = True) -> vtkAlgorithm:
        """Append a chain of VTK algorithms after the output ``input`` and name its result.

        Parameters
        ----------
        name : str
            Name of the new output (and of its series file ``NAME.pvd``).
        *algorithms : vtkAlgorithm
            One or more algorithms, ours or any VTK filter (``vtkFlyingEdges3D``, ...), connected
            in order: each one's input port 0 to the previous one's output port 0.
        input : str, optional
            The output to start from; the source's output when omitted.
        write : bool
            Write this output as a series when the flow runs.
        xdmf : bool
            Also export the series as XDMF + HDF5 at the end (fixed topology only,
            :func:`pipeline.io.xdmf.export_xdmf`).
        draw : bool
            Whether the renders of a run draw this output.

        Returns
        -------
        vtkAlgorithm
            The last algorithm of the chain.
        """
        _check_name(name)
        if name in self.stages:
            raise ValueError(f"an output named {name!r} exists already; "
                             f"names: {sorted(self.stages)}")
        write = check_bool("write", write)
        xdmf = check_bool("xdmf", xdmf)
        draw = check_bool("draw", draw)
        input = input or self._primary
        if input not in self.stages:
            raise ValueError(f"input must be one of {sorted(self.stages)}, got {input!r}")
        if not algorithms:
            raise ValueError("add() needs at least one algorithm")
        for algorithm in algorithms:
            if not isinstance(algorithm, vtkAlgorithm):
                raise TypeError(f"stages must be VTK algorithms, got {type(algorithm).__name__}")
        connect_chain(algorithms, upstream=self.stages[input].algorithm)
        chain = self.stages[input].chain + list(algorithms)
        self.stages[name] = Stage(name, algorithms[-1], chain, write, xdmf, draw)
        return algorithms[-1]

    def add_collider(self, name: str, shape: Shape, role: str = "solid", *,
                     size: float = 2.0) -> Collider:
        """Declare a floor, container or solid collider of the scene, written as ``colliders.vtp``.

        :meth:`run` writes every declared collider beside the series
        (:mod:`pipeline.io.colliders`); the renderer draws them.  Declare the shapes the simulation
        uses, so that what is drawn is what the bodies touch.

        Parameters
        ----------
        name : str
            Unique identifier (``"tank"``, ``"floor"``, ``"ball"``).
        shape : filters.geometry.Shape
            Its solid: a Plane for a floor, ``~Box(lower, upper)`` for a tank, a Sphere...
        role : {"floor", "container", "solid"}
            How it is drawn.
        size : float
            Side of the square drawn for a plane (m).

        Returns
        -------
        pipeline.io.colliders.Collider
        """
        collider = Collider(name, shape, role, size)
        if any(c.name == collider.name for c in self.colliders):
            raise ValueError(f"a collider named {name!r} exists already; names: "
                             f"{[c.name for c in self.colliders]}")
        self.colliders.append(collider)
        return collider

    def output(self, name: str, time: float) -> DataSet:
        """Output ``name`` at ``time`` (s) as a PyVista dataset.

        Parameters
        ----------
        name : str
            One of the flow's outputs.
        time : float
            Time (s); the simulation steps (or restores a cached state) to reach it.

        Returns
        -------
        pyvista.DataSet
            A copy (``pyvista.PolyData``, ``pyvista.UnstructuredGrid``, ...), which later
            updates of the flow leave alone.
        """
        import pyvista as pv

        return pv.wrap(self._output(name, time))

    def frames(self, name: str) -> Iterator[tuple[float, DataSet]]:
        """Yield ``(time, dataset)`` for every frame time of the flow (:meth:`output`)."""
        for t in self.times:
            yield float(t), self.output(name, float(t))

    def _output(self, name: str, time: float):
        if name not in self.stages:
            raise ValueError(f"name must be one of {sorted(self.stages)}, got {name!r}")
        stage = self.stages[name]
        return update(stage.algorithm, stage.chain, time,
                      what=f"output {name!r}: the VTK pipeline")

    def written_outputs(self) -> list[str]:
        """Names of the outputs that :meth:`run` writes as series."""
        return [s.name for s in self.stages.values() if s.write]

    def drawn_outputs(self) -> list[str]:
        """Names of the written outputs that the renders of a run draw."""
        return [s.name for s in self.stages.values() if s.write and s.draw]

    def check_resume(self, directory: str | Path) -> int:
        """Check, without changing anything, that the series in ``directory`` can be resumed.

        Every written output's collection must list only frames this flow writes (its own
        folder and names), at this flow's frame times.

        Returns
        -------
        int
            The number of frames complete in every series (before looking for a checkpoint).

        Raises
        ------
        SeriesError
            If a collection is malformed or lists files a resume must not touch.
        ValueError
            If its frame times differ from this flow's (another fps) or it has more frames.
        """
        directory = Path(directory)
        times = [float(t) for t in self.times]
        done = None
        for name in self.written_outputs():
            writer = SeriesWriter(directory / f"{name}.pvd", resume=True)
            for index, (t, _) in enumerate(writer.entries):
                if index >= len(times) or t != times[index]:
                    raise ValueError(
                        f"{writer.path} was written with other frame times ({t} s at frame "
                        f"{index}); run without resume, or with the same fps and at least as "
                        f"long a duration")
            done = len(writer) if done is None else min(done, len(writer))
        return done or 0

    @property
    def checkpoint_path(self) -> Path | None:
        """The checkpoint file of a run in folder ``DIR``, relative: ``NAME.checkpoint.npz``
        for the first output ``NAME`` (:mod:`pipeline.io.checkpoint`); ``None`` when the source
        keeps none (``SimulationSource(checkpoint=False)``)."""
        if not self.source.checkpoint:
            return None
        return Path(self._primary + CHECKPOINT_SUFFIX)

    def _usable_checkpoint(self, directory: Path, writers: dict[str, SeriesWriter],
                           done: int) -> Checkpoint | None:
        """The checkpoint beside the series, if it belongs to a frame on disk in every series."""
        relative = self.checkpoint_path
        path = directory / relative if relative is not None else None
        if path is None or not path.is_file():
            return None
        try:
            checkpoint = read_checkpoint(path)
        except CheckpointError as exc:
            warnings.warn(f"{exc}; resuming from an earlier point", RuntimeWarning, stacklevel=3)
            return None
        index = checkpoint.frame
        if index >= done or checkpoint.time != float(self.times[index]):
            return None
        if not set(writers) <= set(checkpoint.digests):
            return None
        for name, writer in writers.items():
            frame = writer.path.parent / writer.entries[index][1]
            if not frame.is_file() or file_digest(frame) != checkpoint.digests[name]:
                return None  # a checkpoint of other frames (another run in this folder)
        return checkpoint

    def _resume_point(self, directory: Path, writers: dict[str, SeriesWriter]) -> tuple[int, int]:
        """Restore the source for resuming; return ``(restart, done)``.

        ``done`` frames are complete in every series (the longer ones are cut to it); the
        source is left at frame ``restart - 1`` (or rewound when ``restart`` is 0), from where
        the frames ``restart .. done - 1`` are simulated again without being written.  The
        state comes from the checkpoint beside the series, or, for series written before
        checkpoints left the frames, from the ``state:*`` field data of the last frame.
        """
        done = min(len(w) for w in writers.values())
        times = [float(t) for t in self.times]
        for writer in writers.values():
            for index, (t, _) in enumerate(writer.entries[:done]):
                if index >= len(times) or t != times[index]:
                    raise ValueError(
                        f"the series on disk was written with other frame times ({t} s at frame "
                        f"{index}); run without resume, or with the same fps"
                    )
        for w in writers.values():
            w.truncate(done)
        if done == 0:
            return 0, 0
        checkpoint = self._usable_checkpoint(directory, writers, done)
        if checkpoint is not None:
            self.source.restore(checkpoint.state)
            return checkpoint.frame + 1, done
        # a series written when every frame carried the state (no checkpoint file beside it;
        # the first resume writes one): its last frame has one
        primary = writers.get(self._primary) or next(iter(writers.values()))
        last = read_frame(primary.path.parent / primary.entries[done - 1][1])
        if has_state(last):
            state = state_from_dataset(last)
            self.source.restore(state)
            if self.checkpoint_path is not None:
                self._save_checkpoint(directory, writers, done - 1, state)
            return done, done
        for w in writers.values():  # nothing to resume from: start again
            w.truncate(0)
        return 0, 0

    def _save_checkpoint(self, directory: Path, writers: dict[str, SeriesWriter], index: int,
                         state) -> None:
        digests = {name: file_digest(w.path.parent / w.entries[index][1])
                   for name, w in writers.items()}
        write_checkpoint(directory / self.checkpoint_path,
                         Checkpoint(state, index, float(self.times[index]), digests))

    @holds_folder("directory")  # one writer per folder (pipeline.io.folderlock)
    def run(self, directory: str | Path, *, resume: bool = False, progress: bool = True,
            on_frame: Callable[[int, float], object] | None = None, checkpoint_every: int = 10,
            checkpoint_seconds: float = 300.0) -> dict[str, Path]:
        """Run every frame and write each written output as a series in ``directory``.

        Parameters
        ----------
        directory : str or Path
            Output folder (created).  Output ``NAME`` goes to ``directory/NAME.pvd``.
        resume : bool
            Continue series already in ``directory``: from the checkpoint beside them
            (:attr:`checkpoint_path`), simulating again without writing the frames after it
            that are already on disk, or, for series written by earlier versions, from the
            state in their last frame.  The result is bitwise identical to a run that was never
            interrupted, wherever it stopped.
        progress : bool
            Show a tqdm progress bar over frames.
        on_frame : callable, optional
            Called as ``on_frame(index, time)`` after each frame is written (and its checkpoint,
            when it has one).
        checkpoint_every : int
            Keep a checkpoint of the simulation at frame 0, every ``checkpoint_every`` frames
            (>= 1), at the last frame, and at the last frame written when the run stops on an
            error or Ctrl-C; only the newest is kept, replaced atomically.
        checkpoint_seconds : float
            Also keep one after a frame when this much wall time (s, > 0) passed since the last.

        Returns
        -------
        dict of str to Path
            The collection file of every written output (the colliders, when the flow declares
            any, are in ``directory/colliders.vtp``).
        """
        directory = Path(directory)
        checkpoint_every = check_int("checkpoint_every", checkpoint_every, 1)
        checkpoint_seconds = check_range("checkpoint_seconds", checkpoint_seconds, 0.0,
                                         math.inf, low_inclusive=False)
        written = [s for s in self.stages.values() if s.write]
        if not written:
            raise ValueError("no output is marked to be written")
        directory.mkdir(parents=True, exist_ok=True)
        sweep_temporaries(directory)  # ours alone now (the lock): a killed run's leftovers go
        if self.colliders:
            write_colliders(self.colliders, directory / COLLIDERS_FILE)
        writers = {s.name: SeriesWriter(directory / f"{s.name}.pvd", resume=resume)
                   for s in written}
        keep = self.checkpoint_path
        restart, done = self._resume_point(directory, writers) if resume else (0, 0)
        if restart == 0:
            self.source.rewind()
            if keep is not None:  # a checkpoint of another run must never be resumed from
                (directory / keep).unlink(missing_ok=True)
        times = self.times
        bar = tqdm(total=len(times), initial=done, unit="frame", disable=not progress,
                   desc=f"{directory.name or 'run'}", leave=True)
        saved, saved_at = restart - 1, time.monotonic()
        index = restart - 1  # the last frame complete in every series
        try:
            for index in range(restart, len(times)):
                t = float(times[index])
                if index < done:  # on disk already: simulated again, not written
                    self._output(self._primary, t)
                else:
                    for stage in written:
                        writers[stage.name].write(self._output(stage.name, t), t)
                if keep is not None and (index % checkpoint_every == 0 or index == len(times) - 1
                                         or time.monotonic() - saved_at >= checkpoint_seconds):
                    self._save_checkpoint(directory, writers, index,
                                          self.source.simulation.get_state())
                    saved, saved_at = index, time.monotonic()
                if index >= done:
                    bar.update(1)
                    if on_frame is not None:
                        on_frame(index, t)
        except BaseException:
            # stopped (an error, Ctrl-C): keep a checkpoint of the last frame written, from the
            # state the source cached after making it, so that a resume starts there
            last = min(index, min(len(w) for w in writers.values()) - 1)
            if keep is not None and last > saved and last >= done - 1:
                state = self.source.state_at(float(times[last]))
                if state is not None:
                    try:
                        self._save_checkpoint(directory, writers, last, state)
                    except Exception as exc:  # noqa: BLE001 - the run's own error matters more
                        warnings.warn(f"no checkpoint kept at frame {last}: {exc}",
                                      RuntimeWarning, stacklevel=2)
            raise
        finally:
            bar.close()
        for stage in written:
            if stage.xdmf:
                export_xdmf(writers[stage.name].path)
        return {name: w.path for name, w in writers.items()}
