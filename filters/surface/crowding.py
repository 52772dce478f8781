"""Refuse point clouds so crowded that a surface reconstruction would run for hours.

Every stage of a surface reconstruction (the splat, the anisotropy, the feature smoothing, the
attribute interpolation) visits, for each particle or voxel, the particles within one kernel
support: its cost grows with the number of *pairs* of particles closer than the support.  A
liquid sampled at spacing ``2 r`` has about 34 neighbours within the ``4 r`` support of the
``sph`` kernel, so the work is linear in the particle count; a million identical points, or a
radius far larger than the spacing, make it quadratic (10^12 kernel evaluations: hours), without
anything looking wrong.

:func:`check_crowding` counts the pairs in cells one support wide (a counting pass, O(N log N))
and refuses a cloud whose particles have on average more than :data:`CROWDED_NEIGHBOURS`
neighbours *and* whose pairs exceed what this machine evaluates in :data:`WORK_SECONDS` (its
cores times :data:`PAIRS_PER_SECOND`): the message states the measure, the limit and why.
Clouds too small to exceed the work limit even if every pair were close are not counted.
"""

from __future__ import annotations

import os

import numpy as np

__all__ = ["CrowdingError", "check_crowding", "pair_work_limit", "CROWDED_NEIGHBOURS",
           "PAIRS_PER_SECOND", "WORK_SECONDS"]

#: Mean neighbours within one support above which a cloud is crowded: 30 times the ~34 of a
#: liquid sampled at spacing 2 r under the ``sph`` kernel's 4 r support.
CROWDED_NEIGHBOURS = 1000
#: Particle pairs one core gets through per second in a whole reconstruction of a crowded
#: cloud: measured 0.9e9 to 1.5e9 (50,000 and 100,000 points within 0.1 mm, radius 0.01 m,
#: one thread, default and plain options: 2.3 to 10.9 s); an order of magnitude.
PAIRS_PER_SECOND = 1e9
#: Seconds of pair work a crowded cloud may ask for before it is refused.
WORK_SECONDS = 60.0


class CrowdingError(ValueError):
    """The particles crowd the kernel supports so much that the work would be quadratic."""


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def pair_work_limit() -> float:
    """Particle pairs this machine evaluates in :data:`WORK_SECONDS`: its cores times
    :data:`PAIRS_PER_SECOND` times :data:`WORK_SECONDS`."""
    return _cores() * PAIRS_PER_SECOND * WORK_SECONDS


def check_crowding(positions: np.ndarray, support: float, what: str = "the particles") -> None:
    """Raise :class:`CrowdingError` if ``positions`` crowd kernel supports of ``support`` m.

    Parameters
    ----------
    positions : (N, 3) float64
        Finite particle positions (m).
    support : float
        Kernel support radius (m), > 0: ``support_r`` times the (largest) particle radius.
    what : str
        What the points are, for the message.

    Raises
    ------
    CrowdingError
        Naming the mean neighbour count, the estimated pairs and the time they would take on
        this machine, and the limits.
    """
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    n = positions.shape[0]
    limit = pair_work_limit()
    if float(n) * float(n) <= limit or not support > 0:
        return  # even if every pair were close, the work is within the limit
    cells = np.floor(positions / float(support))
    _, counts = np.unique(cells, axis=0, return_counts=True)
    counts = counts.astype(np.float64)
    pairs = float(np.dot(counts, counts))  # ordered pairs sharing a cell, self-pairs included
    neighbours = pairs / n
    if neighbours <= CROWDED_NEIGHBOURS or pairs <= limit:
        return
    seconds = pairs / (_cores() * PAIRS_PER_SECOND)
    raise CrowdingError(
        f"{what} are crowded: on average {neighbours:,.0f} of the {n:,} lie within one kernel "
        f"support ({support:g} m) of each other (a liquid sampled at twice its radius has about "
        f"34; more than {CROWDED_NEIGHBOURS} is refused), so the surface would take about "
        f"{pairs:.3g} kernel evaluations, {_duration(seconds)} on this machine's {_cores()} "
        f"core(s) (the limit is {WORK_SECONDS:g} s of such work, {limit:.3g}); check the "
        f"radius against the particle spacing, or remove duplicate points")


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"about {seconds:.0f} s"
    if seconds < 7200:
        return f"about {seconds / 60:.0f} minutes"
    return f"about {seconds / 3600:.3g} hours"
