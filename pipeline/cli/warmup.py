"""First runs compile on two cores: the liquid surface's kernels in a second process.

Numba compiles one kernel at a time, on one core. A liquid scene's first run (an empty Numba
cache) compiles about 30 s of surface kernels and 17 s of solver kernels one after the other
while the second core idles. :func:`compile_surface_in_background` starts a process that runs
the scene's surface stages once on a small made-up block of particles, so that its kernels go
to Numba's on-disk cache while the run compiles and steps its simulation;
:func:`simulate_while` keeps the simulation going until that process is done, then the run
loads the surface kernels from the cache. The frames are the same, bit for bit: the
simulated states are the source's cached ones (:class:`pipeline.sources.SimulationSource`).
A warm cache starts no process.
"""

from __future__ import annotations

import multiprocessing
import os
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from filters.simulation import OutputSpec

    from ..sources import SimulationSource

__all__ = ["surface_cache_is_warm", "compile_surface_in_background", "simulate_while"]

#: Most frames simulated ahead of the run while the surface kernels compile (each frame's state
#: is kept in memory until the run writes it).
MAX_FRAMES_AHEAD = 12


def _usable_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def surface_cache_is_warm() -> bool:
    """Whether the surface's largest kernels are in Numba's cache already (index files exist)."""
    try:
        from filters.surface.anisotropy import _anisotropy_cells
        from filters.surface.ellipsoids import _evaluate_blocks

        return all(os.path.exists(kernel._cache._cache_file._index_path)
                   for kernel in (_anisotropy_cells, _evaluate_blocks))
    except Exception:  # a Numba without these internals: assume warm, start nothing
        return True


def _block(spacing: float, lower, spec, upper=None):
    """A frame of a jittered block of particles in a tank's corner and a few loose drops, with
    the point arrays of ``spec`` (float64, ``id`` int64): walls, flat water, a corner, drops of
    one and of a few particles, every path of the surface stages (kept inside ``upper``)."""
    from filters.simulation import Frame

    rng = np.random.default_rng(0)
    g = np.stack(np.meshgrid(*[np.arange(8)] * 3, indexing="ij"), -1).reshape(-1, 3)
    points = (g + 0.5) * spacing + 0.05 * spacing * rng.standard_normal(g.shape)
    drops = np.array([[14.0, 4.0, 14.0], [15.0, 4.0, 14.0], [14.5, 4.8, 14.0],
                      [14.5, 4.3, 14.8], [4.0, 4.0, 18.0]]) * spacing
    points = np.asarray(lower, dtype=np.float64) + np.concatenate([points, drops])
    if upper is not None:
        points = np.minimum(points, np.asarray(upper, dtype=np.float64) - 0.5 * spacing)
    n = points.shape[0]
    data = {}
    for name, width in spec.point_arrays:
        if name == "id":
            data[name] = np.arange(n, dtype=np.int64)
        else:
            shape = (n,) if width == 1 else (n, width)
            data[name] = rng.standard_normal(shape)
    return Frame(time=0.0, points=points, point_data=data)


def _compile_surface(options: dict, spec) -> None:  # runs in the child process
    from ..algorithm import run_chain
    from ..io.convert import frame_to_vtk
    from ..surface.stages import surface_stages

    box = options.get("implicit")
    frame = _block(2.0 * options["radius"], getattr(box, "lower", (0.0, 0.0, 0.0)), spec,
                   getattr(box, "upper", None))
    run_chain(surface_stages(**options), frame_to_vtk(frame, spec, "polydata"))


def compile_surface_in_background(options: dict,
                                  spec: OutputSpec) -> multiprocessing.Process | None:
    """Start compiling the surface stages of ``options`` in another process, when that helps.

    Parameters
    ----------
    options : dict
        Options of :func:`pipeline.surface.surface_stages` (with ``radius``), e.g. from
        :func:`pipeline.surface.options.surface_options_from_record`.
    spec : filters.simulation.OutputSpec
        The point arrays of the particles the surface is made from.

    Returns
    -------
    multiprocessing.Process or None
        The running process; None with a warm cache, one usable core, or no options.
    """
    if not options or _usable_cores() < 2 or surface_cache_is_warm():
        return None
    context = multiprocessing.get_context("spawn")  # no forked copy of VTK/Numba state
    worker = context.Process(target=_compile_surface, args=(options, spec), daemon=True,
                             name="blobflow-surface-compile")
    try:
        worker.start()
    except OSError:  # no process to be had (limits, sandbox): the run compiles as it goes
        return None
    return worker


def simulate_while(worker: multiprocessing.Process, source: SimulationSource,
                   limit: int = MAX_FRAMES_AHEAD) -> int:
    """Step ``source`` (a :class:`pipeline.sources.SimulationSource`) through its next frames
    while ``worker`` runs, at most ``limit`` frames and its cache's size; then wait for it.

    A simulation error stops the look-ahead silently: the run meets it again at the same frame
    (the solvers are deterministic) after writing the frames before it.

    Returns
    -------
    int
        The number of frames simulated ahead.
    """
    import numba

    from filters.simulation import SimulationError

    ahead = 0
    limit = min(limit, source.cache_size)
    threads = numba.get_num_threads()
    # one core for the compiling process, the others for the simulation: a thread more than
    # the cores would stall the simulation's parallel loops (and the results do not depend on
    # the number of threads)
    numba.set_num_threads(max(1, min(threads, _usable_cores() - 1)))
    try:
        for t in source.times[1:limit + 1]:
            if not worker.is_alive():
                break
            source.go_to(float(t))
            ahead += 1
    except SimulationError:
        pass
    finally:
        numba.set_num_threads(threads)
        worker.join()
    return ahead
