"""Run by Debian's ``pvpython`` (not by pytest): open a series in ParaView, print what it sees.

Usage: pvpython paraview_probe.py SERIES  ->  one JSON line on stdout.

Each step is updated with ``proxy.UpdatePipeline(t)``: ParaView 5.11's
``paraview.simple.UpdatePipeline(t, proxy)`` drops a time of 0 (``if time:``) and updates with
no time at all, which XDMF readers answer with an empty dataset.
"""

import json
import sys

from paraview.simple import OpenDataFile

source = OpenDataFile(sys.argv[1])
source.UpdatePipelineInformation()
times = [float(t) for t in source.TimestepValues]
result = {"reader": source.GetXMLName(), "times": times, "frames": []}
for t in times:
    source.UpdatePipeline(t)
    info = source.GetDataInformation()
    result["frames"].append({"time": t, "points": info.GetNumberOfPoints(),
                             "cells": info.GetNumberOfCells()})
point_data = source.PointData
result["point_arrays"] = sorted(point_data.GetArray(i).GetName() for i in range(len(point_data)))
cell_data = source.CellData
result["cell_arrays"] = sorted(cell_data.GetArray(i).GetName() for i in range(len(cell_data)))
print("PROBE " + json.dumps(result))
