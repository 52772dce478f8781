"""A small builder that chains stages into named outputs and runs them over all frames."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from tqdm.auto import tqdm
from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm

from filters.validation import check_bool

from .algorithm import connect_chain, update
from .colliders import COLLIDERS_FILE, Collider, write_colliders
from .convert import has_state, state_from_dataset
from .folderlock import holds_folder
from .series import SeriesWriter, read_frame
from .xdmf import export_xdmf
from .sources import SimulationSource

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
        raise ValueError(f"an output name must be a Python identifier such as 'surface', got {name!r}")
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
    def times(self):
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
            :func:`pipeline.xdmf.export_xdmf`).
        draw : bool
            Whether the renders of a run draw this output.

        Returns
        -------
        vtkAlgorithm
            The last algorithm of the chain.
        """
        _check_name(name)
        if name in self.stages:
            raise ValueError(f"an output named {name!r} exists already; names: {sorted(self.stages)}")
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

    def add_collider(self, name: str, shape, role: str = "solid", *, size: float = 2.0) -> Collider:
        """Declare a floor, container or solid collider of the scene, written as ``colliders.vtp``.

        :meth:`run` writes every declared collider beside the series
        (:mod:`pipeline.colliders`); the renderer draws them.  Declare the shapes the simulation
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
        pipeline.colliders.Collider
        """
        collider = Collider(name, shape, role, size)
        if any(c.name == collider.name for c in self.colliders):
            raise ValueError(f"a collider named {name!r} exists already; names: "
                             f"{[c.name for c in self.colliders]}")
        self.colliders.append(collider)
        return collider

    def output(self, name: str, time: float):
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

    def frames(self, name: str):
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

    def check_resume(self, directory) -> int:
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

    def _resume_point(self, writers: dict[str, SeriesWriter]) -> int:
        """Frames already complete in every series, after restoring the source to the last one."""
        done = min(len(w) for w in writers.values())
        times = list(self.times)
        while done > 0:
            primary = writers.get(self._primary)
            candidates = [primary] if primary is not None else list(writers.values())
            for writer in candidates:
                t, name = writer.entries[done - 1]
                if done - 1 >= len(times) or t != times[done - 1]:
                    raise ValueError(
                        f"the series on disk was written with other frame times ({t} s at frame "
                        f"{done - 1}); run without resume, or with the same fps"
                    )
                data = read_frame(writer.path.parent / name)
                if has_state(data):
                    self.source.restore(state_from_dataset(data))
                    for w in writers.values():
                        w.truncate(done)
                    return done
            done -= 1  # no checkpoint in that frame: cannot resume from it
        for w in writers.values():
            w.truncate(0)
        return 0

    @holds_folder("directory")  # one writer per folder (pipeline.folderlock)
    def run(self, directory, *, resume: bool = False, progress: bool = True,
            on_frame=None) -> dict[str, Path]:
        """Run every frame and write each written output as a series in ``directory``.

        Parameters
        ----------
        directory : str or Path
            Output folder (created).  Output ``NAME`` goes to ``directory/NAME.pvd``.
        resume : bool
            Continue series already in ``directory`` from their last complete frame, restoring
            the simulation from the checkpoint stored in it.  The result is bitwise identical to
            a run that was never interrupted.
        progress : bool
            Show a tqdm progress bar over frames.
        on_frame : callable, optional
            Called as ``on_frame(index, time)`` after each frame is written.

        Returns
        -------
        dict of str to Path
            The collection file of every written output (the colliders, when the flow declares
            any, are in ``directory/colliders.vtp``).
        """
        directory = Path(directory)
        directory.mkdir(parents=True, exist_ok=True)
        written = [s for s in self.stages.values() if s.write]
        if not written:
            raise ValueError("no output is marked to be written")
        if self.colliders:
            write_colliders(self.colliders, directory / COLLIDERS_FILE)
        writers = {s.name: SeriesWriter(directory / f"{s.name}.pvd", resume=resume) for s in written}
        start = self._resume_point(writers) if resume else 0
        if start == 0:
            self.source.rewind()
        times = self.times
        bar = tqdm(total=len(times), initial=start, unit="frame", disable=not progress,
                   desc=f"{directory.name or 'run'}", leave=True)
        try:
            for index in range(start, len(times)):
                t = float(times[index])
                for stage in written:
                    writers[stage.name].write(self._output(stage.name, t), t)
                bar.update(1)
                if on_frame is not None:
                    on_frame(index, t)
        finally:
            bar.close()
        for stage in written:
            if stage.xdmf:
                export_xdmf(writers[stage.name].path)
        return {name: w.path for name, w in writers.items()}
