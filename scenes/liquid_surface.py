"""Shared by the liquid scenes: the reconstructed water surface, cut at the tank's walls."""

from __future__ import annotations

from filters.validation import check_bool, check_int
from pipeline import Flow
from pipeline.surface import surface_stages
from pipeline.surface.options import liquid_surface_options


def add_liquid_surface(flow: Flow, *, spacing: float, tank_lo, tank_hi,
                       smooth_iterations: int = 30, feature_smoothing: int = 25,
                       anisotropic: bool = True) -> None:
    """Add a ``surface`` output: SPH-field splatting of the particles, contoured and smoothed.

    :func:`pipeline.surface.options.liquid_surface_options`: the particle radius is half the
    spacing; the particles near the tank's walls are mirrored across them and the surface is
    cut exactly at its inner box (:class:`pipeline.surface.liquid.ClipBox`); every closed piece
    of it encloses its particles' volume (:class:`pipeline.surface.liquid.VolumeCorrection`);
    the other stages are those of :data:`pipeline.surface.options.SURFACE_DEFAULTS`
    (``blobflow surface`` rebuilds the same surface from the particle series and the run
    record).

    Parameters
    ----------
    flow : Flow
        The scene's flow; gets a ``surface`` output fed by its ``particles``.
    spacing : float
        Particle spacing (m), > 0.
    tank_lo, tank_hi : (3,) float
        Inner corners of the tank (m).
    smooth_iterations : int
        Windowed-sinc iterations (0 to 1000).
    feature_smoothing : int
        Sweeps of feature-weighted Laplacian smoothing (Löschner et al. 2023,
        :mod:`filters.surface.smoothing`) before the windowed sinc (0 to 10000): flat water is
        smoothed fully, drops of a few particles and one-particle sheets are not moved.
    anisotropic : bool
        Splat anisotropic kernels (Yu & Turk 2013, :mod:`filters.surface.anisotropy`): flatter
        water (measured in ``benchmarks/results/surface_notes.md``).
    """
    smooth_iterations = check_int("smooth_iterations", smooth_iterations, 0, 1000)
    feature_smoothing = check_int("feature_smoothing", feature_smoothing, 0, 10000)
    anisotropic = check_bool("anisotropic", anisotropic)
    options = liquid_surface_options(spacing, tank_lo, tank_hi,
                                     smooth_iterations=smooth_iterations,
                                     feature_smoothing=feature_smoothing, anisotropic=anisotropic)
    flow.add("surface", *surface_stages(**options), input="particles")
