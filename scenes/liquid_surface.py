"""Shared by the liquid scenes: the reconstructed water surface, clipped to the tank."""

from __future__ import annotations

from filters.geometry import Box
from filters.validation import check_int
from pipeline import Flow
from pipeline.surface import surface_stages


def add_liquid_surface(flow: Flow, *, spacing: float, tank_lo, tank_hi,
                       smooth_iterations: int = 30, feature_smoothing: int = 25,
                       anisotropic: bool = True) -> None:
    """Add a ``surface`` output: SPH-field splatting of the particles, contoured and smoothed.

    The particle radius is half the spacing (kernel support of two spacings, as splashsurf uses)
    and the field is intersected with the tank's inner box, so the surface is flat where the
    liquid touches a wall instead of bulging through it.

    Parameters
    ----------
    flow : Flow
        The scene's flow; gets a ``surface`` output fed by its ``particles``.
    spacing : float
        Particle spacing (m).
    tank_lo, tank_hi : (3,) float
        Inner corners of the tank (m).
    smooth_iterations : int
        Windowed-sinc iterations (0 to 10000).
    feature_smoothing : int
        Sweeps of feature-weighted Laplacian smoothing (Löschner et al. 2023,
        :mod:`filters.surface.smoothing`) before the windowed sinc (0 to 10000): flat water is
        smoothed fully, drops of a few particles and one-particle sheets are not moved.
    anisotropic : bool
        Splat anisotropic kernels (Yu & Turk 2013, :mod:`filters.surface.anisotropy`), 1.35x the
        reconstruction time of isotropic ones. On by default: through this function the flat
        top of a pool lies 0.011 / 0.020 / 0.021 spacings RMS from the true plane (jittered
        lattice / pools settled by ``SPHLiquid``, 20x20x8 and 40x40x10 particles), against
        0.023 / 0.026 / 0.020 with isotropic kernels and 0.026 / 0.027 / 0.021 for pysplashsurf's
        smoothed surface (without ``feature_smoothing`` 0.039 / 0.043 / 0.031 with isotropic
        kernels). Lattice balls of radius 4 and 6 spacings end within -1 % and -2.2 % of the
        particles' volume; drops of radius 2-3 spacings come out 15-21 % larger (isotropic:
        within 1.2 %, pysplashsurf smoothed 5-11 % smaller; ``bench_surface.py --flatness``).
    """
    smooth_iterations = check_int("smooth_iterations", smooth_iterations, 0, 10000)
    feature_smoothing = check_int("feature_smoothing", feature_smoothing, 0, 10000)
    flow.add("surface", *surface_stages(radius=0.5 * spacing, smooth_iterations=smooth_iterations,
                                        pass_band=0.01, feature_smoothing=feature_smoothing,
                                        implicit=Box(tank_lo, tank_hi),
                                        operation="intersection",
                                        anisotropic=anisotropic), input="particles")
