"""Validation of :class:`filters.sph.SPHLiquid`'s parameters, before any work."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numba

from ..validation import check_choice, check_finite_vector, check_int, check_range
from .boundary import BoundaryParticles
from .model import default_support_factor

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["check_liquid_parameters"]

DFSPH_MAX_DT = 0.005  # s, default largest DFSPH step


def check_liquid_parameters(*, spacing: float, boundary: BoundaryParticles | None,
                            rest_density: float, kernel: str, support_factor: float | None,
                            speed_of_sound: float | None, gamma: float, viscosity: float,
                            boundary_viscosity: float | None, xsph: float, surface_tension: float,
                            gravity: ArrayLike, cfl: float, max_dt: float | None,
                            density_error_limit: float, boundary_pressure: str, skin: float,
                            threads: int | None, solver: str, max_density_error: float,
                            max_divergence_error: float, max_iterations: int,
                            kinematic_viscosity: float | None) -> tuple:
    """Check every scalar parameter of :class:`~filters.sph.SPHLiquid` and fill its defaults.

    Returns
    -------
    tuple
        ``(spacing, rest_density, support_factor, speed_of_sound, gamma, viscosity,
        boundary_viscosity, xsph, surface_tension, gravity, cfl, max_dt, density_error_limit,
        skin, threads, max_density_error, max_divergence_error, max_iterations,
        kinematic_viscosity)`` as floats / ints / tuples with their defaults resolved
        (``speed_of_sound`` stays None when not given: its default depends on the particles).

    Raises
    ------
    ValueError, TypeError
        Naming the parameter and its valid range or choices.
    """
    spacing = check_range("spacing", spacing, 0.0, math.inf, low_inclusive=False)
    if not math.isfinite(spacing):
        raise ValueError(f"spacing must be finite (m), got {spacing!r}")
    rest_density = check_range("rest_density", rest_density, 0.0, 1e6, low_inclusive=False)
    check_choice("kernel", kernel, ("cubic", "wendland"))
    if support_factor is None:
        support_factor = default_support_factor(kernel)
    support_factor = check_range("support_factor", support_factor, 1.5, 4.0)
    if speed_of_sound is not None:
        speed_of_sound = check_range("speed_of_sound", speed_of_sound, 0.0, 1e5,
                                     low_inclusive=False)
    gamma = check_range("gamma", gamma, 1.0, 10.0)
    viscosity = check_range("viscosity", viscosity, 0.0, 1.0)
    if boundary_viscosity is None:
        boundary_viscosity = viscosity
    boundary_viscosity = check_range("boundary_viscosity", boundary_viscosity, 0.0, 1.0)
    xsph = check_range("xsph", xsph, 0.0, 1.0, high_inclusive=False)
    surface_tension = check_range("surface_tension", surface_tension, 0.0, 100.0)
    gravity = check_finite_vector("gravity", gravity, 3)
    cfl = check_range("cfl", cfl, 0.0, 1.0, low_inclusive=False)
    check_choice("solver", solver, ("wcsph", "dfsph"))
    if max_dt is None:
        max_dt = DFSPH_MAX_DT if solver == "dfsph" else 1.0 / 240.0
    max_dt = check_range("max_dt", max_dt, 0.0, 1.0, low_inclusive=False)
    max_density_error = check_range("max_density_error", max_density_error, 1e-6, 0.1)
    max_divergence_error = check_range("max_divergence_error", max_divergence_error,
                                       1e-6, 1.0)
    max_iterations = check_int("max_iterations", max_iterations, 2, 10000)
    if kinematic_viscosity is not None:
        kinematic_viscosity = check_range("kinematic_viscosity", kinematic_viscosity, 0.0, 1.0)
        if solver != "dfsph":
            raise ValueError("kinematic_viscosity needs solver='dfsph' (WCSPH uses viscosity)")
    density_error_limit = check_range("density_error_limit", density_error_limit, 0.0, 1.0,
                                      low_inclusive=False)
    check_choice("boundary_pressure", boundary_pressure, ("adami", "mirror"))
    skin = check_range("skin", skin, 0.0, 1.0)
    if threads is not None:
        threads = check_int("threads", threads, 1, numba.config.NUMBA_NUM_THREADS)
    if boundary is not None and not isinstance(boundary, BoundaryParticles):
        raise TypeError("boundary must be BoundaryParticles or None, "
                        f"got {type(boundary).__name__}")
    return (spacing, rest_density, support_factor, speed_of_sound, gamma, viscosity,
            boundary_viscosity, xsph, surface_tension, gravity, cfl, max_dt, density_error_limit,
            skin, threads, max_density_error, max_divergence_error, max_iterations,
            kinematic_viscosity)
