"""Make ``docs/paraview_plugin.png`` with ParaView itself and blobflow's plugin.

``xvfb-run -a pvbatch docs/paraview_screenshot.py [FOLDER]`` (Debian's ParaView needs an X
server to render; FOLDER keeps the scene's frames, default a temporary folder). The ``drop``
scene runs as a plugin source (particles only), *blobflow Particle Surface* reconstructs its
surface in ParaView, coloured by speed, beside the particles.
"""

import os
import sys
import tempfile

here = os.path.dirname(os.path.abspath(__file__))
startup = os.path.join(here, "..", "pipeline", "paraview", "startup.py")
ns = {"__file__": startup, "__name__": "__main__"}
exec(open(startup).read(), ns)  # noqa: S102 - loads the plugin

from paraview.simple import (ColorBy, GetActiveViewOrCreate, GetColorTransferFunction,  # noqa
                             GetScalarBar, Outline, Render, SaveScreenshot, Show, Transform)

folder = sys.argv[1] if len(sys.argv) > 1 else tempfile.mkdtemp(prefix="blobflow-shot-")
t = round(7 / 30, 9)  # the drop hits the pool
drop = ns["blobflowdrop"](Surface=0, Duration=0.25, Folder=folder)
surface = ns["blobflowParticleSurface"](Input=drop, Radius=0.006)
view = GetActiveViewOrCreate("RenderView")
view.ViewSize = [1200, 620]
view.ViewTime = t
view.OrientationAxesVisibility = 0
view.Background = [1.0, 1.0, 1.0]
try:
    view.UseColorPaletteForBackground = 0
except AttributeError:
    pass

shifted = Transform(Input=drop)  # the particles beside the surface
shifted.Transform.Translate = [0.3, 0.0, 0.0]
particles = Show(shifted, view)
particles.SetRepresentationType("Points")
particles.PointSize = 3
ColorBy(particles, ("POINTS", "velocity", "Magnitude"))
shown = Show(surface, view)
ColorBy(shown, ("POINTS", "velocity", "Magnitude"))
lut = GetColorTransferFunction("velocity")
lut.ApplyPreset("Cool to Warm", True)
lut.RescaleTransferFunction(0.0, 1.0)
lut.AutomaticRescaleRangeMode = "Never"
shown.SetScalarBarVisibility(view, True)
bar = GetScalarBar(lut, view)
bar.Title, bar.ComponentTitle = "speed (m/s)", ""
bar.TitleColor = bar.LabelColor = [0.0, 0.0, 0.0]
for source in (drop, shifted):
    box = Show(Outline(Input=source), view)
    box.DiffuseColor = [0.3, 0.3, 0.3]
    box.AmbientColor = [0.3, 0.3, 0.3]

Render(view)  # the first render resets the camera: place it after
view.CameraFocalPoint = [0.27, 0.12, 0.04]
view.CameraPosition = [0.27, -0.50, 0.38]
view.CameraViewUp = [0.0, 0.0, 1.0]
view.ResetCamera(False)  # fit both, looking from there
view.GetActiveCamera().Dolly(1.35)
Render(view)
out = os.path.join(here, "paraview_plugin.png")
SaveScreenshot(out, view, ImageResolution=[1200, 620])
print("wrote", out)
