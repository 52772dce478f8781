"""Shared by the liquid scenes: the solver-specific options of :class:`filters.sph.SPHLiquid`."""

from __future__ import annotations

import math

from filters.validation import check_choice, check_range


def solver_options(solver: str, max_density_error: float, max_iterations: int,
                   speed_of_sound: float, kinematic_viscosity: float = 0.0) -> dict:
    """Keyword arguments for ``SPHLiquid`` that only one solver takes.

    ``max_density_error``, ``max_iterations`` and ``kinematic_viscosity`` (m^2/s, in [0, 1]; 0:
    from the artificial viscosity ``viscosity``) go to DFSPH; ``speed_of_sound`` to WCSPH (0
    for its automatic value).  Every scene parameter is validated either way, so a bad value is
    refused whichever solver is chosen.
    """
    check_choice("solver", solver, ("dfsph", "wcsph"))
    speed_of_sound = check_range("speed_of_sound", speed_of_sound, 0.0, 1e5)
    if not math.isfinite(speed_of_sound):
        raise ValueError(f"speed_of_sound must be finite (m/s), got {speed_of_sound!r}")
    kinematic_viscosity = check_range("kinematic_viscosity", kinematic_viscosity, 0.0, 1.0)
    if solver == "dfsph":
        options = {"max_density_error": max_density_error, "max_iterations": max_iterations}
        if kinematic_viscosity > 0.0:
            options["kinematic_viscosity"] = kinematic_viscosity
        return options
    return {"speed_of_sound": speed_of_sound or None}
