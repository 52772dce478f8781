"""Load blobflow's ParaView plugin: ``paraview --script=THIS_FILE``, or run it in pvpython.

Debian's ParaView 5.11 runs on Python 3.11, from which ``inspect.getargspec`` was removed, and
its Python-plugin loader (``paraview.detail.pythonalgorithm``) still imports it, so *every*
Python plugin fails to load there ("Failed to import paraview.detail.pythonalgorithm"). This
script puts back the one thing the loader uses (``getargspec(f).args``, which
``inspect.getfullargspec`` provides) when it is missing, then loads ``paraview_plugin.py`` from
this file's folder. Never imported by blobflow; ``blobflow paraview`` prints its path.
"""

import inspect
import os

if not hasattr(inspect, "getargspec"):
    inspect.getargspec = inspect.getfullargspec

from paraview.simple import LoadPlugin  # noqa: E402

_here = os.path.dirname(os.path.abspath(__file__ if "__file__" in globals() else
                                        os.environ.get("BLOBFLOW_PARAVIEW_STARTUP", ".")))
LoadPlugin(os.path.join(_here, "paraview_plugin.py"), ns=globals())
