"""blobflow in ParaView.

:file:`plugin.py` (this folder) is a ParaView Python plugin and :file:`startup.py` loads it
from ``paraview --script`` or a ``pvpython`` prompt; both run in ParaView's own Python and import
nothing of blobflow. They talk to :mod:`~pipeline.paraview.bridge`, run in blobflow's own
environment (``python -m pipeline.paraview.bridge``), through VTK XML files.
"""

__all__: list[str] = []
