"""Run by Debian's ``pvpython`` (not by pytest): two ``bouncing`` scene sources of blobflow's
plugin on one cache folder, which another writer holds when they start.

Usage: pvpython paraview_shared_probe.py STARTUP FOLDER -> one JSON line: what each source
showed at each time.
"""

import json
import sys

startup, folder = sys.argv[1], sys.argv[2]
ns = {"__file__": startup, "__name__": "__main__"}
exec(open(startup).read(), ns)  # noqa: S102 - ParaView's own startup for the plugin

from paraview import servermanager  # noqa: E402


def shown(source, t):
    source.UpdatePipeline(t)
    block = servermanager.Fetch(source).GetBlock(0)
    n = block.GetNumberOfPoints()
    return {"time": t, "points": n,
            "z_mean": sum(block.GetPoint(i)[2] for i in range(n)) / max(n, 1)}


settings = dict(Count=2, FPS=10.0, Duration=0.5, Folder=folder)
first = ns["blobflowbouncing"](**settings)
second = ns["blobflowbouncing"](**settings)
first.UpdatePipelineInformation()
second.UpdatePipelineInformation()
times = [float(t) for t in first.TimestepValues]
result = {"first": [shown(first, times[-1])],  # waits for the writer that holds the folder
          "second": [shown(second, t) for t in times]}
result["first"].append(shown(first, times[0]))
print("PROBE " + json.dumps(result))
