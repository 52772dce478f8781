"""The ``blobflow`` command: :func:`main` (:mod:`~pipeline.cli.app`: ``list``, ``run``,
``render``, ``info``), with the ``surface`` command in :mod:`~pipeline.cli.surface`, the
``gallery``, ``export`` and ``paraview`` commands in :mod:`~pipeline.cli.tools`, the options
shared by several commands in :mod:`~pipeline.cli.common`, and the compilation of the surface
kernels while a scene runs in :mod:`~pipeline.cli.warmup`.
"""

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from .app import main

_EXPORTS = {"main": ".app"}

__all__ = ["main"]

__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)
