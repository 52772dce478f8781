"""The fixed parameters of an SPH liquid (:class:`SPHModel`) and the default support radius."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..validation import check_finite_vector

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy.typing import ArrayLike

    from .boundary import BoundaryParticles

__all__ = ["SPHModel", "default_support_factor", "check_boxes", "as_field"]


def default_support_factor(kernel: str) -> float:
    """Default support radius over particle spacing for ``kernel``: 2 (cubic), 2.5 (wendland)."""
    return 2.5 if kernel == "wendland" else 2.0


@dataclass(frozen=True)
class SPHModel:
    """Fixed parameters of :class:`SPHLiquid` (SI units).

    Attributes
    ----------
    spacing : float
        Initial particle spacing (m).
    support : float
        Kernel support radius ``h`` (m).
    kernel : str
        Smoothing kernel name.
    rest_density : float
        ``rho0`` (kg/m^3).
    mass : float
        Particle mass (kg): ``rho0 * lattice_volume(spacing, h)``.
    speed_of_sound : float
        ``c`` (m/s).
    gamma : float
        Tait exponent.
    viscosity : float
        Artificial viscosity ``alpha``.
    boundary_viscosity : float
        ``alpha`` against boundary particles (wall friction).
    xsph : float
        XSPH factor ``epsilon`` in [0, 1).
    surface_tension : float
        Akinci et al. (2013) coefficient ``gamma_st`` (1/s^2 scale; 0 disables).
    gravity : tuple of 3 float
        (m/s^2).
    cfl : float
        Courant number.
    max_dt : float
        Largest step (s).
    density_error_limit : float
        Largest tolerated relative compression ``max (rho - rho0) / rho0``.
    domain : tuple of two tuples of 3 float or None
        Box that particles must stay in (m), or None.
    container : tuple of two tuples of 3 float or None
        Inner walls of a box tank (m) that particles are projected back into, or None.
    boundary_pressure : {"adami", "mirror"}
        How boundary particles get a pressure.
    boundary_points, boundary_volumes : read-only arrays
        The boundary particles the liquid was built with, (M, 3) m and (M,) m^3 (where they
        are now: :attr:`SPHLiquid.boundary`).
    solver : {"wcsph", "dfsph"}
        Pressure solver.
    max_density_error, max_divergence_error : float
        DFSPH tolerances (fractions of ``rho0``; the second per step).
    max_iterations : int
        Most iterations of each DFSPH solve.
    """

    spacing: float
    support: float
    kernel: str
    rest_density: float
    mass: float
    speed_of_sound: float
    gamma: float
    viscosity: float
    boundary_viscosity: float
    xsph: float
    surface_tension: float
    gravity: tuple
    cfl: float
    max_dt: float
    density_error_limit: float
    domain: tuple | None
    container: tuple | None
    boundary_pressure: str
    boundary_points: np.ndarray
    boundary_volumes: np.ndarray
    solver: str = "wcsph"
    max_density_error: float = 1e-3
    max_divergence_error: float = 1e-2
    max_iterations: int = 100


def check_boxes(x: np.ndarray, domain: tuple[ArrayLike, ArrayLike] | None,
                container: tuple[ArrayLike, ArrayLike] | None,
                boundary: BoundaryParticles | None) -> tuple[tuple[tuple, tuple] | None,
                                                             tuple[tuple, tuple] | None]:
    """Validate ``domain`` and ``container`` (``(lower, upper)`` boxes, m) against the positions
    ``x`` (N, 3); the domain defaults to the boundary particles' bounding box.  Returns both as
    tuples of tuples (or None)."""
    if domain is not None:
        lo = check_finite_vector("domain[0]", domain[0], 3)
        hi = check_finite_vector("domain[1]", domain[1], 3)
        if not (hi > lo).all():
            raise ValueError("domain upper corner must exceed the lower corner")
        domain = (tuple(lo), tuple(hi))
    elif boundary is not None and boundary.n_points:
        domain = (tuple(boundary.points.min(axis=0)), tuple(boundary.points.max(axis=0)))
    if container is not None:
        clo = check_finite_vector("container[0]", container[0], 3)
        chi = check_finite_vector("container[1]", container[1], 3)
        if not (chi > clo).all():
            raise ValueError("container upper corner must exceed the lower corner")
        if ((x < clo) | (x > chi)).any():
            raise ValueError(f"positions must lie inside the container {container}")
        container = (tuple(clo), tuple(chi))
    if domain is not None:
        lo, hi = np.array(domain[0]), np.array(domain[1])
        if ((x < lo) | (x > hi)).any():
            raise ValueError(f"positions must lie inside the domain {domain}")
    return domain, container


def as_field(external: object | None) -> Callable[[np.ndarray, np.ndarray, float],
                                                  np.ndarray] | None:
    """The external acceleration as a callable ``field(positions, velocities, time)``."""
    if external is None:
        return None
    if hasattr(external, "acceleration") and callable(external.acceleration):
        return external.acceleration
    if callable(external):
        return external
    raise TypeError("external must be None, a callable field(positions, velocities, time) "
                    "-> (N, 3) "
                    f"or an object with such an acceleration method; got {type(external).__name__}")
