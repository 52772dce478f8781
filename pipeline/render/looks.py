"""How the offscreen renders look: materials, lights, the floor, glass containers and smoke.

The renderer (:mod:`pipeline.render`) draws in two layers that share one depth buffer: the
opaque scene (floor, solid colliders, water, cloth, jello, hair, particles), lit by a key
spotlight that casts shadows through VTK's shadow-map pass (Williams 1978, "Casting curved
shadows on curved surfaces"; ``vtkShadowMapPass``, exponential shadow maps, Annen et al. 2008)
and a headlight fill; then what must neither cast shadows nor hide the scene behind it: the
glass of containers with their edges, and smoke as soft sprites.  Smoke sprites are
point-Gaussian splats (``vtkPointGaussianMapper``) whose alpha is a Gaussian of the distance to
the particle, times a fade with the particle's age; all sprites share one hue, so the result of
"over" blending does not depend on their order and needs no sorting.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import ArrayLike
    from vtkmodules.vtkCommonDataModel import vtkDataObject
    from vtkmodules.vtkRenderingCore import vtkProperty

__all__ = ["WATER", "SOLID", "HAIR", "POINTS", "SMOKE", "COLLIDER", "GLASS", "EDGE", "FLOOR",
           "BACKGROUND", "MATERIALS", "apply_material", "grid_texture_image", "smoke_colors",
           "SMOKE_SPLAT_SHADER", "key_light", "KEY_AZIMUTH", "KEY_ELEVATION",
           "SHADOW_MAP_RESOLUTION", "SHADOW_EXPONENT", "is_liquid_surface", "is_particle_surface"]

WATER = "#2f86d6"
SOLID = "#d9774f"
HAIR = "#6b4226"
POINTS = "#3b8fd9"
SMOKE = (0.46, 0.49, 0.53)  # RGB of the smoke, darker than the background it rises against
COLLIDER = "#b9bec6"        # neutral grey of solid colliders (sphere, head, ball)
GLASS = "#d6e6f2"           # container faces
EDGE = "#2e3640"            # container edges
FLOOR = "#eef0f2"
BACKGROUND = ("#f4f6f9", "#c9d3de")  # top, bottom gradient

#: Dihedral angle (degrees) above which the drawn copy of a liquid surface gets split normals:
#: the flat faces where a surface is cut at its tank's walls meet the free surface at about
#: 90 degrees, and normals averaged across those edges shade the long cap triangles in diagonal
#: streaks; the curved free surface (dihedral angles well under this) stays smooth.
WATER_FEATURE_ANGLE = 60.0
#: Direction of the key light from the scene's centre, relative to the camera: azimuth
#: (degrees, negative to the camera's left as it looks at the scene) and elevation (degrees).
KEY_AZIMUTH = -60.0
KEY_ELEVATION = 60.0
#: Side of the square shadow map (texels).
SHADOW_MAP_RESOLUTION = 2048
#: Constant ``c`` of the exponential shadow map, ``exp(c (d_occluder - d_receiver))`` with depths
#: scaled to [0, 1] over the light's range (Annen et al. 2008): VTK's default 11 leaves the
#: floor right by a resting body nearly unshadowed (light bleeds where the two depths are
#: close); 80 keeps the contact shadow dark and stays within float32 (exp(88) overflows).
SHADOW_EXPONENT = 80.0

#: Surface properties per look: water shiny, elastic bodies and colliders matte.
MATERIALS = {
    "water": dict(ambient=0.12, diffuse=0.75, specular=0.9, specular_power=80.0),
    "solid": dict(ambient=0.18, diffuse=0.85, specular=0.04, specular_power=5.0),
    "lines": dict(ambient=0.2, diffuse=0.8, specular=0.15, specular_power=20.0),
    "points": dict(ambient=0.15, diffuse=0.8, specular=0.3, specular_power=30.0),
    "collider": dict(ambient=0.2, diffuse=0.8, specular=0.12, specular_power=15.0),
    "floor": dict(ambient=0.35, diffuse=0.75, specular=0.0, specular_power=1.0),
    "glass": dict(ambient=0.3, diffuse=0.3, specular=0.6, specular_power=90.0, opacity=0.1),
    "edge": dict(ambient=0.6, diffuse=0.4, specular=0.0, specular_power=1.0),
}


def is_liquid_surface(name: str, data: vtkDataObject) -> bool:
    """Whether a frame is a liquid's surface, drawn as water (and measured by its area).

    What the frame says it is decides: ``blobflow_kind`` = ``liquid_surface`` in its field data
    (written by the surface stages, :class:`pipeline.surface.liquid.SurfaceKind`), whatever its
    series is called. A frame without the tag (series written before it existed) is one when it is
    polygonal data and its series' name starts with ``surface``.

    Parameters
    ----------
    name : str
        The series' name (``surface`` for ``surface.pvd``).
    data : vtkDataObject
        One frame.
    """
    from ..surface.liquid import LIQUID_SURFACE, dataset_kind

    kind = dataset_kind(data)
    if kind is not None:
        return kind == LIQUID_SURFACE
    return hasattr(data, "GetPolys") and name.startswith("surface")


def is_particle_surface(name: str, data: vtkDataObject) -> bool:
    """Whether a frame is a surface contoured around particles (a liquid's or any other, e.g.
    smoke's metaballs): tagged by the surface stages, or, untagged, a liquid's surface by its
    name (:func:`is_liquid_surface`)."""
    from ..surface.liquid import dataset_kind

    return dataset_kind(data) is not None or is_liquid_surface(name, data)


def apply_material(prop: vtkProperty, look: str) -> None:
    """Set a ``vtkProperty``'s lighting coefficients to those of ``look`` (:data:`MATERIALS`)."""
    m = MATERIALS[look]
    prop.SetAmbient(m["ambient"])
    prop.SetDiffuse(m["diffuse"])
    prop.SetSpecular(m["specular"])
    prop.SetSpecularPower(m["specular_power"])
    if "opacity" in m:
        prop.SetOpacity(m["opacity"])


def grid_texture_image(cells: int = 16, size: int = 512) -> np.ndarray:
    """(size, size, 3) uint8 image of a light floor with a subtle grid of ``cells`` lines."""
    image = np.full((size, size, 3), 240, dtype=np.uint8)
    step = size // cells
    for k in range(0, size, step):
        image[k:k + 2, :, :] = 224
        image[:, k:k + 2, :] = 224
    return image


#: Fragment code of the smoke sprites: Gaussian alpha over the splat, cut at its radius.
SMOKE_SPLAT_SHADER = (
    "//VTK::Color::Impl\n"
    "float dist2 = dot(offsetVCVSOutput.xy, offsetVCVSOutput.xy);\n"
    "if (dist2 > 1.0) { discard; }\n"
    "opacity = opacity * exp(-4.0 * dist2);\n"
)


def smoke_colors(points: np.ndarray, age: np.ndarray | None, age_scale: float, *,
                 opacity: float = 0.18,
                 zrange: tuple[float, float] = (0.0, 1.0)) -> np.ndarray:
    """RGBA (uint8) of smoke sprites: one hue, lighter with height, alpha fading with age.

    Parameters
    ----------
    points : (N, 3) float
        Particle positions (m).
    age : (N,) float or None
        Particle ages (s); None draws every sprite at full ``opacity``.
    age_scale : float
        Age (s) at which a sprite has faded out, > 0 (the oldest particles' age).
    opacity : float
        Peak alpha of one sprite at its centre, in (0, 1].
    zrange : (float, float)
        Heights (m) from the darkest to the lightest smoke.

    Returns
    -------
    (N, 4) uint8
        Colours: alpha ``opacity * (1 - age / age_scale)^1.5`` (young smoke dense, old smoke
        thin), RGB from :data:`SMOKE` towards white with height.
    """
    n = len(points)
    if age is None:
        fade = np.ones(n)
    else:
        fade = np.clip(1.0 - np.asarray(age, dtype=np.float64) / max(age_scale, 1e-12), 0.0, 1.0)
        fade = fade ** 1.5
    lo, hi = zrange
    z = np.asarray(points, dtype=np.float64).reshape(-1, 3)[:, 2]
    h = np.clip((z - lo) / max(hi - lo, 1e-12), 0.0, 1.0)
    rgb = np.asarray(SMOKE)[None, :] * (1.0 - 0.35 * h[:, None]) + 0.35 * h[:, None]
    rgba = np.empty((n, 4), dtype=np.uint8)
    rgba[:, :3] = np.round(255.0 * rgb).astype(np.uint8)
    rgba[:, 3] = np.round(255.0 * opacity * fade).astype(np.uint8)
    return rgba


def key_light(center: ArrayLike, radius: float, azimuth: float, floor_z: float,
              floor_half: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Where the shadow-casting key light stands for a camera at ``azimuth`` degrees.

    The light follows the camera (a turntable's object turns under fixed studio lights, so it is
    lit the same way in every frame): :data:`KEY_AZIMUTH` degrees about the vertical from the
    camera (to its left: the faces seen are lit and the shadows fall to the right of the bodies,
    onto floor the camera sees) and :data:`KEY_ELEVATION` degrees up, at twenty times the scene's
    radius (nearly parallel light: even on the whole floor); its cone just covers the floor.

    Parameters
    ----------
    center : (3,) float
        Centre of the framed bounds (m).
    radius : float
        Half their diagonal (m).
    azimuth : float
        Camera azimuth (degrees) as in :meth:`pipeline.render.Renderer.render`.
    floor_z, floor_half : float
        Height of the floor (m) and half its side (m), centred under ``center``.

    Returns
    -------
    position, focal_point : (3,) float
        Of the spotlight (m).
    cone_angle : float
        Half-angle of its cone (degrees), < 90 so that it casts shadows.
    """
    az = math.radians(azimuth - 55.0 + KEY_AZIMUTH)
    el = math.radians(KEY_ELEVATION)
    center = np.asarray(center, dtype=np.float64)
    focal = np.array([center[0], center[1], floor_z])
    position = focal + 20.0 * radius * np.array([math.cos(el) * math.cos(az),
                                                math.cos(el) * math.sin(az), math.sin(el)])
    axis = (focal - position) / np.linalg.norm(focal - position)
    corners = np.array([[sx * floor_half, sy * floor_half, 0.0] for sx in (-1, 1)
                        for sy in (-1, 1)]) + focal
    rays = corners - position
    cosines = rays @ axis / np.linalg.norm(rays, axis=1)
    cone = math.degrees(math.acos(float(np.clip(cosines.min(), -1.0, 1.0)))) + 2.0
    return position, focal, min(cone, 85.0)
