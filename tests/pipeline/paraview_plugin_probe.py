"""Appended by the test to the README's pvpython recipe (``exec(open(".../paraview/startup.py")
.read())``), in a script run by Debian's ``pvpython`` from another folder: use the plugin the
recipe loaded into this script's namespace.

Usage: pvpython SCRIPT PARTICLES.pvd RADIUS OUT_DIR -> one JSON line. The surface filter runs
on the particle series at its first two time steps (each surface is written to OUT_DIR for the
test to compare); the ``bouncing`` scene source runs into OUT_DIR/run.
"""

import json
import sys
import time

particles, radius, out = sys.argv[1], float(sys.argv[2]), sys.argv[3]
ns = globals()

from paraview import servermanager  # noqa: E402
from paraview.simple import OpenDataFile  # noqa: E402
from vtkmodules.vtkFiltersCore import vtkFeatureEdges  # noqa: E402
from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter  # noqa: E402

result = {"proxies": sorted(n for n in ns if n.startswith("blobflow"))}
reader = OpenDataFile(particles)
reader.UpdatePipelineInformation()
surface = ns["blobflowParticleSurface"](Input=reader, Radius=radius, FeatureSmoothing=5,
                                        SmoothIterations=10)
surface.Kernel = "sph"
result["panel"] = {name: str(surface.GetPropertyValue(name)) for name in (
    "Radius", "Kernel", "Anisotropic", "FeatureSmoothing", "SmoothIterations", "PassBand",
    "Normals", "Attributes", "Liquid", "VolumeCorrection")}
result["surfaces"] = []
for index, t in enumerate(list(reader.TimestepValues)[:2]):
    start = time.perf_counter()
    surface.UpdatePipeline(t)
    seconds = time.perf_counter() - start
    mesh = servermanager.Fetch(surface)
    edges = vtkFeatureEdges()
    edges.SetInputData(mesh)
    edges.BoundaryEdgesOn()
    edges.NonManifoldEdgesOn()
    edges.FeatureEdgesOff()
    edges.ManifoldEdgesOff()
    edges.Update()
    writer = vtkXMLPolyDataWriter()
    writer.SetInputData(mesh)
    writer.SetFileName(f"{out}/plugin_surface_{index}.vtp")
    writer.Write()
    kind = mesh.GetFieldData().GetAbstractArray("blobflow_kind")
    result["surfaces"].append({"time": t, "points": mesh.GetNumberOfPoints(),
                               "kind": kind.GetValue(0) if kind is not None else None,
                               "triangles": mesh.GetNumberOfPolys(),
                               "open_edges": edges.GetOutput().GetNumberOfLines(),
                               "seconds": seconds})

liquid = ns["blobflowParticleSurface"](Input=reader, Radius=radius, FeatureSmoothing=5,
                                       SmoothIterations=10, Liquid=1)
liquid.UpdatePipeline(list(reader.TimestepValues)[0])
writer = vtkXMLPolyDataWriter()
writer.SetInputData(servermanager.Fetch(liquid))
writer.SetFileName(f"{out}/plugin_liquid_0.vtp")
writer.Write()

scene = ns["blobflowbouncing"](Count=2, FPS=10.0, Duration=0.3, Folder=f"{out}/run")
scene.UpdatePipelineInformation()
result["scene_times"] = [float(t) for t in scene.TimestepValues]
result["scene_frames"] = []
for t in result["scene_times"]:
    scene.UpdatePipeline(t)
    data = servermanager.Fetch(scene)
    block = data.GetBlock(0)
    result["scene_frames"].append({"time": t, "blocks": data.GetNumberOfBlocks(),
                                   "name": data.GetMetaData(0).Get(data.NAME()),
                                   "points": block.GetNumberOfPoints(),
                                   "z_mean": sum(block.GetPoint(i)[2] for i in range(
                                       block.GetNumberOfPoints())) / block.GetNumberOfPoints()})
print("PROBE " + json.dumps(result))
