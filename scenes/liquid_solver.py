"""Shared by the liquid scenes: the solver-specific options of :class:`filters.sph.SPHLiquid`."""

from __future__ import annotations

import math

from filters.validation import check_choice, check_range


def solver_options(solver: str, max_density_error: float, max_iterations: int,
                   speed_of_sound: float) -> dict:
    """Keyword arguments for ``SPHLiquid`` that only one solver takes.

    ``max_density_error`` and ``max_iterations`` go to DFSPH; ``speed_of_sound`` to WCSPH (0
    for its automatic value).  Every scene parameter is validated either way, so a bad value is
    refused whichever solver is chosen.
    """
    check_choice("solver", solver, ("dfsph", "wcsph"))
    speed_of_sound = check_range("speed_of_sound", speed_of_sound, 0.0, 1e5)
    if not math.isfinite(speed_of_sound):
        raise ValueError(f"speed_of_sound must be finite (m/s), got {speed_of_sound!r}")
    if solver == "dfsph":
        return {"max_density_error": max_density_error, "max_iterations": max_iterations}
    return {"speed_of_sound": speed_of_sound or None}
