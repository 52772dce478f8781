"""Run by Debian's ``pvpython`` (not by pytest): open a series in ParaView, print what it sees.

Usage: pvpython paraview_probe.py SERIES  ->  one JSON line on stdout.
"""

import json
import sys

from paraview.simple import OpenDataFile, UpdatePipeline

source = OpenDataFile(sys.argv[1])
source.UpdatePipelineInformation()
times = [float(t) for t in source.TimestepValues]
result = {"reader": source.GetXMLName(), "times": times, "frames": []}
for t in times:
    UpdatePipeline(t, source)
    info = source.GetDataInformation()
    result["frames"].append({"time": t, "points": info.GetNumberOfPoints(),
                             "cells": info.GetNumberOfCells()})
point_data = source.PointData
result["point_arrays"] = sorted(point_data.GetArray(i).GetName() for i in range(len(point_data)))
cell_data = source.CellData
result["cell_arrays"] = sorted(cell_data.GetArray(i).GetName() for i in range(len(cell_data)))
print("PROBE " + json.dumps(result))
