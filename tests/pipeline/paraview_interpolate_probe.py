"""Run by Debian's ``pvpython`` (not by pytest): ParaView's TemporalInterpolator between frames.

Usage: pvpython paraview_interpolate_probe.py SERIES TIME  ->  one JSON line on stdout:
``{"time": TIME, "points": [[x, y, z], ...], "id": [...]}``, the interpolated particles at
TIME (between two frames of the series) in the order ParaView holds them.
"""

import json
import sys

from paraview import servermanager
from paraview.simple import OpenDataFile, TemporalInterpolator
from vtk.util.numpy_support import vtk_to_numpy

reader = OpenDataFile(sys.argv[1])
reader.UpdatePipelineInformation()
interpolator = TemporalInterpolator(Input=reader)
time = float(sys.argv[2])
interpolator.UpdatePipeline(time)
data = servermanager.Fetch(interpolator)
if data.IsA("vtkMultiBlockDataSet"):
    data = data.GetBlock(0)
points = vtk_to_numpy(data.GetPoints().GetData())
ids = vtk_to_numpy(data.GetPointData().GetArray("id"))
print("PROBE " + json.dumps({"time": time, "points": points.tolist(),
                             "id": [float(i) for i in ids]}))
