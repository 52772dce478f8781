"""``dataset.blobflow``: blobflow's calls on any PyVista dataset.

Registered with :func:`pyvista.register_dataset_accessor` when this module is imported, and
declared as a ``pyvista.accessors`` entry point in ``pyproject.toml``, so that an installed
blobflow makes ``cloud.blobflow.surface(radius=0.005)`` work after a bare ``import pyvista``::

    import pyvista as pv
    cloud = pv.PolyData(points)                  # or any dataset read with pv.read
    surface = cloud.blobflow.surface(radius=0.005, kernel="sph", smooth_iterations=30)
"""

from __future__ import annotations

import pyvista as pv

__all__ = ["BlobflowAccessor"]


@pv.register_dataset_accessor("blobflow", pv.DataSet)
class BlobflowAccessor:
    """blobflow's filters on one dataset (its points are the particles).

    Parameters
    ----------
    dataset : pyvista.DataSet
        The dataset the accessor is attached to.
    """

    def __init__(self, dataset):
        self._dataset = dataset

    def surface(self, radius: float, **options) -> pv.PolyData:
        """The implicit surface of the dataset's points: :func:`pipeline.surface.reconstruct`.

        Parameters
        ----------
        radius : float
            Particle radius (m), > 0.
        **options
            Options of :func:`pipeline.surface.surface_stages` (``kernel``, ``anisotropic``,
            ``smooth_iterations``, ``feature_smoothing``, ``cell_size``, ``attributes``, ...).

        Returns
        -------
        pyvista.PolyData
            The triangle surface (m), bitwise the surface a :class:`pipeline.Flow` writes with
            the same options.
        """
        from .surface import reconstruct

        return reconstruct(self._dataset, radius, **options)
