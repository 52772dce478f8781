"""``dataset.blobflow``: blobflow's calls on PyVista datasets and multiblocks.

Registered with :func:`pyvista.register_dataset_accessor` when this module is imported, and
declared as a ``pyvista.accessors`` entry point in ``pyproject.toml``, so that an installed
blobflow makes ``cloud.blobflow.surface(radius=0.005)`` work after a bare ``import pyvista``::

    import pyvista as pv
    cloud = pv.PolyData(points)                  # or any dataset read with pv.read
    surface = cloud.blobflow.surface(radius=0.005, kernel="sph", smooth_iterations=30)

On a :class:`pyvista.MultiBlock` (what ``pv.read("particles.pvd")`` returns: the blocks of one
time step) it gives every block's surface, as a multiblock of the same layout; a multiblock of
the frames of a whole series gives each frame's surface, which ``write_series`` writes as a
series::

    from pipeline import read_series
    times, frames = read_series("outputs/drop/particles.pvd")
    surfaces = pv.MultiBlock(frames).blobflow.surface(radius=0.006, liquid=True)
    surfaces.blobflow.write_series("outputs/drop_surfaces/surface.pvd")   # frame times kept
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import pyvista as pv

__all__ = ["BlobflowAccessor", "BlobflowMultiBlockAccessor"]


def _options_of_reconstruct(method: Callable) -> Callable:
    """Give ``method(self, radius, **options)`` the signature of
    :func:`pipeline.surface.reconstruct` (without its first argument), so that ``help()`` and
    ``inspect.signature`` list every option."""
    from .surface.stages import reconstruct

    parameters = list(inspect.signature(reconstruct).parameters.values())[1:]
    self_parameter = inspect.Parameter("self", inspect.Parameter.POSITIONAL_OR_KEYWORD)
    method.__signature__ = inspect.Signature(
        [self_parameter, *parameters],
        return_annotation=inspect.signature(method).return_annotation)
    return method


@pv.register_dataset_accessor("blobflow", pv.DataSet)
class BlobflowAccessor:
    """blobflow's filters on one dataset (its points are the particles).

    Parameters
    ----------
    dataset : pyvista.DataSet
        The dataset the accessor is attached to.
    """

    def __init__(self, dataset: pv.DataSet):
        self._dataset = dataset

    @_options_of_reconstruct
    def surface(self, radius: float, **options: Any) -> pv.PolyData:
        """The implicit surface of the dataset's points: :func:`pipeline.surface.reconstruct`.

        Parameters
        ----------
        radius : float
            Particle radius (m), > 0.
        **options
            The keyword options of :func:`pipeline.surface.reconstruct` (``kernel``,
            ``anisotropic``, ``smooth_iterations``, ``liquid``, ``attributes``,
            ``progress_bar``, ...), with its defaults.

        Returns
        -------
        pyvista.PolyData
            The triangle surface (m), bitwise the surface a :class:`pipeline.Flow` writes with
            the same options.
        """
        from .surface.stages import reconstruct

        return reconstruct(self._dataset, radius, **options)


def _leaves(block) -> int:
    if isinstance(block, pv.MultiBlock):
        return sum(_leaves(b) for b in block)
    return 0 if block is None else 1


@pv.register_dataset_accessor("blobflow", pv.MultiBlock)
class BlobflowMultiBlockAccessor:
    """blobflow's filters on a multiblock: the blocks of one time step, or the frames of a
    series (one block each).

    Parameters
    ----------
    multiblock : pyvista.MultiBlock
        The multiblock the accessor is attached to.
    """

    def __init__(self, multiblock: pv.MultiBlock):
        self._multiblock = multiblock

    @_options_of_reconstruct
    def surface(self, radius: float, **options: Any) -> pv.MultiBlock:
        """Every block's surface (:func:`pipeline.surface.reconstruct` on its points), as a
        multiblock of the same layout: nested multiblocks block by block, the blocks' names
        kept, an empty block left as None, each surface carrying its block's field data
        (``TimeValue`` for the frames of a series).

        Parameters
        ----------
        radius : float
            Particle radius (m), > 0.
        **options
            The keyword options of :func:`pipeline.surface.reconstruct`; ``progress_bar`` shows
            one bar over the blocks.

        Returns
        -------
        pyvista.MultiBlock
        """
        from .surface.stages import reconstruct, surface_stages

        progress_bar = bool(options.pop("progress_bar", False))
        surface_stages(radius, **options)  # every option checked before the first block
        bar = None
        if progress_bar:
            from tqdm.auto import tqdm

            bar = tqdm(total=_leaves(self._multiblock), desc="surfaces", unit="block")

        def each(block):
            if block is None:
                return None
            if isinstance(block, pv.MultiBlock):
                out = pv.MultiBlock()
                for name, child in zip(block.keys(), block, strict=False):
                    out.append(each(child), name)
                return out
            surface = reconstruct(block, radius, **options)
            for name in block.field_data.keys():
                if name not in surface.field_data and not name.startswith("state:"):
                    surface.field_data[name] = block.field_data[name]
            if bar is not None:
                bar.update(1)
            return surface

        try:
            return each(self._multiblock)
        finally:
            if bar is not None:
                bar.close()

    def write_series(self, path: str | Path, times: Sequence[float] | None = None) -> Path:
        """Write the blocks as the frames of a series (:class:`pipeline.SeriesWriter`: a
        ``.pvd`` collection, frames in ``NAME/``, a ParaView ``.series`` file beside it).

        Parameters
        ----------
        path : str or Path
            The collection, ``DIR/NAME.pvd``.
        times : sequence of float, optional
            One time (s) per block, increasing; default each block's ``TimeValue`` field data
            (the frames of a series carry theirs).

        Returns
        -------
        Path
            ``path``.

        Raises
        ------
        ValueError
            If ``times`` has another length than the blocks, or is omitted while a block has no
            ``TimeValue``; if the times do not increase.
        TypeError
            If a block is a multiblock or a type a frame cannot be.
        """
        from .io.series import SeriesWriter

        blocks = list(self._multiblock)
        if times is None:
            missing = [i for i, b in enumerate(blocks)
                       if b is None or "TimeValue" not in b.field_data.keys()]
            if missing:
                raise ValueError(f"times: block {missing[0]} has no TimeValue field data; pass "
                                 f"one time per block")
            times = [float(b.field_data["TimeValue"][0]) for b in blocks]
        elif len(times) != len(blocks):
            raise ValueError(f"times must hold one time per block ({len(blocks)}), got "
                             f"{len(times)}")
        for i, block in enumerate(blocks):
            if block is None or isinstance(block, pv.MultiBlock):
                raise TypeError(f"block {i} is {'empty' if block is None else 'a multiblock'}: "
                                f"a series frame is one dataset")
        writer = SeriesWriter(path)
        for block, t in zip(blocks, times, strict=False):
            writer.write(block, float(t))
        return Path(path)
