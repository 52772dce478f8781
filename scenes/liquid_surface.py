"""Shared by the liquid scenes: the reconstructed water surface, clipped to the tank."""

from __future__ import annotations

from filters.implicit import Box
from filters.validation import check_int
from pipeline import Flow
from pipeline.surface import surface_stages


def add_liquid_surface(flow: Flow, *, spacing: float, tank_lo, tank_hi,
                       smooth_iterations: int = 30) -> None:
    """Add a ``surface`` output: SPH-field splatting of the particles, contoured and smoothed.

    The particle radius is half the spacing (kernel support of two spacings, as splashsurf uses)
    and the field is intersected with the tank's inner box, so the surface is flat where the
    liquid touches a wall instead of bulging through it.
    """
    smooth_iterations = check_int("smooth_iterations", smooth_iterations, 0, 10000)
    flow.add("surface", *surface_stages(radius=0.5 * spacing, smooth_iterations=smooth_iterations,
                                        pass_band=0.01, implicit=Box(tank_lo, tank_hi),
                                        operation="intersection"), input="particles")
