"""The VTK pieces of the renders: shadow passes, collider, smoke, glyph, label and colour-bar
actors (used by :class:`pipeline.render.renderer.Renderer`; looks from
:mod:`pipeline.render.looks`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pyvista as pv
from vtkmodules.vtkRenderingCore import vtkActor, vtkGlyph3DMapper, vtkPolyDataMapper, vtkTextActor
from vtkmodules.vtkRenderingOpenGL2 import vtkOpenGLPointGaussianMapper

from ..io.colliders import collider_mesh
from . import looks

if TYPE_CHECKING:
    from collections.abc import Sequence

    from pyvista import ColorLike
    from vtkmodules.vtkCommonCore import vtkScalarsToColors
    from vtkmodules.vtkCommonDataModel import vtkPolyData
    from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm
    from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor
    from vtkmodules.vtkRenderingCore import vtkRenderer
    from vtkmodules.vtkRenderingOpenGL2 import vtkCameraPass

    from ..io.colliders import Collider

__all__ = ["shadow_passes", "polydata_actor", "collider_actors", "smoke_actor", "glyph_actor",
           "label", "scalar_bar", "TEXT_COLOR"]

TEXT_COLOR = "#20262e"


def shadow_passes() -> vtkCameraPass:
    """Render passes of the opaque layer: bake the shadow maps of the key light, then draw the
    opaque geometry once, with shadows (VTK's ``vtkShadowMapBakerPass`` and
    ``vtkShadowMapPass``; PyVista's ``enable_shadows`` would draw it a third time first)."""
    from vtkmodules.vtkRenderingOpenGL2 import (
        vtkCameraPass,
        vtkLightsPass,
        vtkOpaquePass,
        vtkOverlayPass,
        vtkRenderPassCollection,
        vtkSequencePass,
        vtkShadowMapBakerPass,
        vtkShadowMapPass,
    )

    opaque = vtkSequencePass()
    steps = vtkRenderPassCollection()
    steps.AddItem(vtkLightsPass())
    steps.AddItem(vtkOpaquePass())
    opaque.SetPasses(steps)
    opaque_camera = vtkCameraPass()
    opaque_camera.SetDelegatePass(opaque)
    baker = vtkShadowMapBakerPass()
    baker.SetOpaqueSequence(opaque_camera)
    baker.SetResolution(looks.SHADOW_MAP_RESOLUTION)
    baker.SetExponentialConstant(looks.SHADOW_EXPONENT)
    shadows = vtkShadowMapPass()
    shadows.SetShadowMapBakerPass(baker)
    shadows.SetOpaqueSequence(opaque)
    sequence = vtkSequencePass()
    passes = vtkRenderPassCollection()
    passes.AddItem(baker)
    passes.AddItem(shadows)
    passes.AddItem(vtkOverlayPass())
    sequence.SetPasses(passes)
    camera = vtkCameraPass()
    camera.SetDelegatePass(sequence)
    return camera


def polydata_actor(algorithm_or_data: vtkAlgorithm | vtkPolyData, look: str, color: ColorLike,
                   layer: vtkRenderer) -> vtkActor:
    """An actor of ``algorithm_or_data`` (polydata or an algorithm giving it) in ``look``
    (:data:`pipeline.render.looks.MATERIALS`) and ``color``, added to the renderer ``layer``."""
    mapper = vtkPolyDataMapper()
    if hasattr(algorithm_or_data, "GetOutputPort"):
        mapper.SetInputConnection(algorithm_or_data.GetOutputPort())
    else:
        mapper.SetInputData(algorithm_or_data)
    mapper.ScalarVisibilityOff()
    actor = vtkActor()
    actor.SetMapper(mapper)
    prop = actor.GetProperty()
    prop.SetColor(pv.Color(color).float_rgb)
    looks.apply_material(prop, look)
    prop.SetInterpolationToPhong()
    layer.AddActor(actor)
    return actor


def collider_actors(collider: Collider, scene: vtkRenderer, over: vtkRenderer,
                    edge_radius: float) -> list[vtkActor]:
    """Actors drawing one collider: a solid in the neutral material in the opaque layer
    ``scene`` (it casts and receives shadows), a container as glass faces and dark edge tubes
    of ``edge_radius`` (m) in the top layer ``over``."""
    points, cells = collider_mesh(collider, resolution=32)
    faces = np.hstack([np.full((len(cells), 1), cells.shape[1]), cells]).ravel()
    mesh = pv.PolyData(np.asarray(points, dtype=np.float64), faces)
    if collider.role == "solid":
        mesh = mesh.compute_normals(cell_normals=False, auto_orient_normals=False,
                                    consistent_normals=True, split_vertices=False)
        return [polydata_actor(mesh, "collider", looks.COLLIDER, scene)]
    glass = polydata_actor(mesh, "glass", looks.GLASS, over)
    glass.GetProperty().BackfaceCullingOff()
    out = [glass]
    edges = mesh.extract_feature_edges(boundary_edges=True, feature_edges=True,
                                       manifold_edges=False, non_manifold_edges=False,
                                       feature_angle=30.0)
    if edges.n_cells:
        out.append(polydata_actor(edges.tube(radius=edge_radius, n_sides=8), "edge", looks.EDGE,
                                  over))
    return out


def smoke_actor(slot: vtkPolyData, rgba: str) -> vtkActor:
    """Soft sprites of the points of ``slot``: Gaussian splats of radius 4 times the point
    array ``size`` (m), coloured by the RGBA point array ``rgba``
    (:func:`pipeline.render.looks.smoke_colors`), drawn in the translucent pass."""
    mapper = vtkOpenGLPointGaussianMapper()
    mapper.SetInputData(slot)
    mapper.SetScaleArray("size")
    mapper.SetScaleFactor(4.0)  # wide, faint sprites overlap into a continuous plume
    mapper.SetEmissive(0)
    mapper.SetScalarModeToUsePointFieldData()
    mapper.SelectColorArray(rgba)
    mapper.SetColorModeToDirectScalars()
    mapper.ScalarVisibilityOn()
    mapper.SetSplatShaderCode(looks.SMOKE_SPLAT_SHADER)
    actor = vtkActor()
    actor.SetMapper(mapper)
    actor.GetProperty().SetOpacity(0.999)  # drawn in the translucent pass
    actor.GetProperty().SetAmbient(1.0)
    actor.GetProperty().SetDiffuse(0.0)
    return actor


def glyph_actor(slot: vtkPolyData, radius: float, color: ColorLike,
                lut: vtkScalarsToColors | None, scalars: str) -> vtkActor:
    """Spheres of ``radius`` (m) at the points of ``slot``, in ``color`` or coloured by the
    point array ``scalars`` through ``lut``.

    Instanced glyphs, not point-Gaussian sphere impostors: those break VTK's shadow-map shaders
    (measured: 'radiusMC' and calcShadow compile errors).
    """
    sphere = pv.Sphere(radius=radius, theta_resolution=12, phi_resolution=8)
    mapper = vtkGlyph3DMapper()
    mapper.SetInputData(slot)
    mapper.SetSourceData(sphere)
    mapper.ScalingOff()
    mapper.OrientOff()
    actor = vtkActor()
    actor.SetMapper(mapper)
    prop = actor.GetProperty()
    looks.apply_material(prop, "points")
    prop.SetInterpolationToPhong()
    if lut is not None:
        mapper.SetLookupTable(lut)
        mapper.SetScalarRange(*lut.scalar_range)
        mapper.SetScalarModeToUsePointFieldData()
        mapper.SelectColorArray(scalars)
        mapper.ScalarVisibilityOn()
    else:
        mapper.ScalarVisibilityOff()
        prop.SetColor(pv.Color(color).float_rgb)
    return actor


def label(inner: tuple[int, int], side: int, scale: float) -> vtkTextActor:
    """The text at the upper left of the image (``inner`` pixels cropped from a square window
    of ``side``, drawn ``scale`` times larger than the image)."""
    text = vtkTextActor()
    prop = text.GetTextProperty()
    prop.SetFontSize(int(round(10 * scale)))
    prop.SetColor(pv.Color(TEXT_COLOR).float_rgb)
    top = (side + inner[1]) // 2
    text.SetPosition((side - inner[0]) // 2 + int(6 * scale), top - int(18 * scale))
    return text


def scalar_bar(title: str, clim: Sequence[float], inner: tuple[int, int], side: int,
               scale: float) -> vtkScalarBarActor:
    """A vertical viridis colour bar of ``clim`` at the image's right edge."""
    from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor

    lut = pv.LookupTable(cmap="viridis")
    lut.scalar_range = tuple(clim)
    bar = vtkScalarBarActor()
    bar.SetLookupTable(lut)
    bar.SetTitle(title)
    bar.SetNumberOfLabels(5)
    for text in (bar.GetTitleTextProperty(), bar.GetLabelTextProperty()):
        text.SetColor(pv.Color(TEXT_COLOR).float_rgb)
        text.SetFontSize(int(round(11 * scale)))
        text.ItalicOff()
        text.ShadowOff()
    bar.UnconstrainedFontSizeOn()
    fx, fy = inner[0] / side, inner[1] / side
    bar.SetPosition(0.5 + fx * 0.36, 0.5 - fy * 0.35)
    bar.SetWidth(0.1 * fx)
    bar.SetHeight(0.7 * fy)
    return bar
