"""Files in and out: time series, exports, checkpoints and the checks of what is read.

- :mod:`~pipeline.io.series`: PVD and ``.series`` collections of VTP/VTU frames, written
  atomically and read back checked; :mod:`~pipeline.io.outfiles` the naming, ownership and
  atomic writes of frames; :mod:`~pipeline.io.folderlock` one writer per output folder;
- :mod:`~pipeline.io.xdmf` and :mod:`~pipeline.io.usd`: exports for ParaView/VisIt and for
  Blender/Houdini;
- :mod:`~pipeline.io.convert`: simulation frames to VTK datasets and back;
  :mod:`~pipeline.io.checkpoint` the state a run resumes from (``NAME.checkpoint.npz``);
  :mod:`~pipeline.io.colliders` the colliders beside a run;
- :mod:`~pipeline.io.xmlcheck` (a VTK XML file is checked before VTK reads it) and
  :mod:`~pipeline.io.volume_mesh` (tetrahedral meshes through meshio).
"""

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from .checkpoint import Checkpoint, CheckpointError, read_checkpoint, write_checkpoint
    from .series import (
        SeriesError,
        SeriesWriter,
        read_collection,
        read_frame,
        read_series,
        validate_series,
        write_frame,
    )
    from .usd import UsdUnavailableError, export_usd
    from .xdmf import export_xdmf

_EXPORTS = {
    **dict.fromkeys(["SeriesWriter", "SeriesError", "read_series", "read_collection",
                     "read_frame", "write_frame", "validate_series"], ".series"),
    "export_xdmf": ".xdmf", "export_usd": ".usd", "UsdUnavailableError": ".usd",
    **dict.fromkeys(["Checkpoint", "CheckpointError", "read_checkpoint", "write_checkpoint"],
                    ".checkpoint"),
}

__all__ = ["SeriesWriter", "SeriesError", "read_series", "read_collection", "read_frame",
           "write_frame", "validate_series", "export_xdmf", "export_usd", "UsdUnavailableError",
           "Checkpoint", "CheckpointError", "read_checkpoint", "write_checkpoint"]

__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)
