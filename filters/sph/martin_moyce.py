"""The collapse of a liquid column against Martin & Moyce (1952): their data and how to measure a
simulated dam break against it.

Martin, J. C. & Moyce, W. J. (1952), "Part IV. An experimental study of the collapse of liquid
columns on a rigid horizontal plane", Phil. Trans. R. Soc. Lond. A 244, 312-324: a water column
of width ``a`` and height ``n^2 a`` released at ``t = 0`` on a horizontal plane.  For ``n^2 = 2``
and ``a = 2.25 in`` their Table 2 gives the time ``T = n t sqrt(g / a) = t sqrt(2 g / a)`` at
which the surge front reaches ``Z = x / a``, and their Table 6 the residual height of the
column at the wall, ``H = eta / (n^2 a)``, against ``tau = t sqrt(g / a)``.  The values below
are those tables as reproduced in SPH and MPS validation work (Koshizuka & Oka 1996, "Moving
particle semi-implicit method for fragmentation of incompressible fluid", Nucl. Sci. Eng. 123;
the same front points appear in PySPH's dam-break example data, digitised from Martin &
Moyce's Fig. 3): the original paper was not at hand.  Martin & Moyce's ``Z`` are whole
half-inches over ``a`` (1.11 = 2.5 in / 2.25 in).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["FRONT_T", "FRONT_Z", "HEIGHT_TAU", "HEIGHT_H", "surge_front", "column_height",
           "compare", "release_delay"]

#: Table 2 (n^2 = 2, a = 2.25 in): ``T = t sqrt(2 g / a)`` at which the front reaches ``Z``.
FRONT_T = np.array([0.41, 0.84, 1.19, 1.43, 1.63, 1.83, 1.98, 2.20, 2.32, 2.51, 2.65, 2.83,
                    2.98, 3.11, 3.33])
#: Table 2: the front position ``Z = x / a``.
FRONT_Z = np.array([1.11, 1.22, 1.44, 1.67, 1.89, 2.11, 2.33, 2.56, 2.78, 3.00, 3.22, 3.44,
                    3.67, 3.89, 4.11])
#: Table 6 (n^2 = 2, a = 2.25 in): ``tau = t sqrt(g / a)``.
HEIGHT_TAU = np.array([0.56, 0.77, 0.93, 1.08, 1.28, 1.46, 1.66, 1.84, 2.00, 2.21, 2.45, 2.70,
                       3.06, 3.44, 4.20, 5.25])
#: Table 6: the residual column height ``H = eta / (n^2 a)``.
HEIGHT_H = np.array([0.94, 0.89, 0.83, 0.78, 0.72, 0.67, 0.61, 0.56, 0.50, 0.44, 0.39, 0.33,
                     0.28, 0.22, 0.17, 0.11])


def _kth_largest(values, k):
    k = max(1, min(int(k), values.shape[0]))
    return float(np.partition(values, values.shape[0] - k)[values.shape[0] - k])


def surge_front(positions: ArrayLike, spacing: float, depth: float) -> float:
    """Leading edge of the surge (m from the column's wall at x = 0): the particle centre of
    the ``round(depth / spacing)``-th largest ``x`` (one particle per column across the tank's
    depth may run ahead as spray) plus half a spacing (a particle stands for a cube of side
    ``spacing``; at t = 0 this gives ``a``)."""
    x = np.asarray(positions, dtype=np.float64)[:, 0]
    return _kth_largest(x, round(depth / spacing)) + 0.5 * spacing


def column_height(positions: ArrayLike, spacing: float, depth: float) -> float:
    """Height (m) of the liquid at the column's wall: among the particles within one spacing of
    x = 0, the ``round(depth / spacing)``-th largest ``z`` plus half a spacing (at t = 0 the
    column's height)."""
    x = np.asarray(positions, dtype=np.float64)
    near = x[x[:, 0] < spacing, 2]
    if near.size == 0:
        return 0.0
    return _kth_largest(near, round(depth / spacing)) + 0.5 * spacing


def compare(times: ArrayLike, fronts: ArrayLike, heights: ArrayLike, a: float, g: float = 9.81,
            t_range: tuple[float, float] = (0.8, 3.0)) -> dict:
    """Relative errors of a simulated collapse against the tables.

    Parameters
    ----------
    times : (K,) array_like
        Sample times (s), increasing, covering the table points to compare.
    fronts, heights : (K,) array_like
        :func:`surge_front` and :func:`column_height` at those times (m).
    a : float
        Column width (m); the column is ``2 a`` high.
    g : float
        Gravity (m/s^2).
    t_range : (float, float)
        The ``T`` range of the front comparison.

    Returns
    -------
    dict
        ``front_errors`` (signed relative errors at the table points within ``t_range``),
        ``front_mean_abs`` and ``front_mean`` (mean absolute and signed), ``height_errors``,
        ``height_mean_abs``, ``height_mean`` likewise at the height points with ``T <=
        t_range[1]``, and the table points used.
    """
    t = np.asarray(times, dtype=np.float64)
    T = t * math.sqrt(2.0 * g / a)
    tau = t * math.sqrt(g / a)
    use = (FRONT_T >= t_range[0]) & (FRONT_T <= t_range[1]) & (FRONT_T <= T.max())
    z = np.interp(FRONT_T[use], T, np.asarray(fronts) / a)
    fe = z / FRONT_Z[use] - 1.0
    hu = (HEIGHT_TAU * math.sqrt(2.0) <= t_range[1]) & (HEIGHT_TAU <= tau.max())
    hh = np.interp(HEIGHT_TAU[hu], tau, np.asarray(heights) / (2.0 * a))
    he = hh / HEIGHT_H[hu] - 1.0
    return {"front_T": FRONT_T[use].tolist(), "front_errors": fe.tolist(),
            "front_mean_abs": float(np.abs(fe).mean()) if fe.size else math.nan,
            "front_mean": float(fe.mean()) if fe.size else math.nan,
            "height_tau": HEIGHT_TAU[hu].tolist(), "height_errors": he.tolist(),
            "height_mean_abs": float(np.abs(he).mean()) if he.size else math.nan,
            "height_mean": float(he.mean()) if he.size else math.nan}


def release_delay(times: ArrayLike, fronts: ArrayLike, a: float, g: float = 9.81,
                  t_range: tuple[float, float] = (0.8, 3.0), largest: float = 0.5,
                  step: float = 0.01) -> tuple[float, float]:
    """The delay ``dT`` (in ``T = t sqrt(2 g / a)``) by which the simulated front, started
    ``dT`` later, best matches Table 2, and its mean absolute relative error then.

    A front that runs at the experiment's speed but leaves earlier (a column released at once,
    where the experiment's release took some time) is matched by a delay with a small error.
    A front a little too fast everywhere is matched fairly well too (10 % faster: 1.9 % after
    the best delay), so read the delay with the front's late speed.  Delays from 0 to
    ``largest`` are tried every ``step``; the smallest of equal errors is returned.

    Parameters
    ----------
    times, fronts : (K,) array_like
        Sample times (s), increasing, and :func:`surge_front` at them (m).
    a, g : float
        Column width (m) and gravity (m/s^2).
    t_range : (float, float)
        The ``T`` range of Table 2 compared (after the delay).

    Returns
    -------
    (float, float)
        ``dT`` and the mean absolute relative front error with it.
    """
    T = np.asarray(times, dtype=np.float64) * math.sqrt(2.0 * g / a)
    z = np.asarray(fronts, dtype=np.float64) / a
    use = (FRONT_T >= t_range[0]) & (FRONT_T <= t_range[1])
    best = (0.0, math.inf)
    for delay in np.arange(0.0, largest + 0.5 * step, step):
        shifted = FRONT_T[use] - delay
        if shifted.min() < T[0] or shifted.max() > T[-1]:
            continue  # the samples do not cover the delayed table
        err = float(np.abs(np.interp(shifted, T, z) / FRONT_Z[use] - 1.0).mean())
        if err < best[1] - 1e-12:
            best = (float(delay), err)
    return best
