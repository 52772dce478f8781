"""Ballistic particles under constant gravity bouncing on a floor plane.

The simplest real simulation: every step is integrated *exactly* (the trajectory between contacts
is the parabola ``x(t) = x0 + v0 t + g t^2 / 2``), contacts with the floor are found by solving
that quadratic, and the normal velocity is reversed and scaled by the coefficient of restitution.
It exists to exercise the pipeline against an analytic answer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from .simulation import OutputSpec, Simulation, State
from .validation import check_finite_vector, check_range

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["BallisticModel", "BallisticParticles"]

_MAX_CONTACTS_PER_STEP = 64


@dataclass(frozen=True)
class BallisticModel:
    """Fixed parameters of :class:`BallisticParticles`.

    Parameters
    ----------
    gravity : tuple of 3 float
        Acceleration (m/s^2).
    floor : float
        Height of the floor plane ``z = floor`` (m).
    restitution : float
        Ratio of normal speeds after and before a contact, in [0, 1].
    rest_speed : float
        A rebound slower than this (m/s) leaves the particle resting on the floor; this ends the
        infinite sequence of ever smaller bounces in finite time.
    """

    gravity: tuple = (0.0, 0.0, -9.81)
    floor: float = 0.0
    restitution: float = 0.7
    rest_speed: float = 1e-3


@njit(cache=True, inline="always")
def _first_contact(height, vz, gz, horizon):
    """Earliest t in (0, horizon] with height + vz t + gz t^2 / 2 == 0, or -1 if none."""
    disc = vz * vz - 2.0 * gz * height
    if disc < 0.0:
        return -1.0
    root = math.sqrt(disc)
    # The two algebraically equal forms below avoid cancellation for either sign of vz.
    if vz <= 0.0:
        denominator = root - vz
        if denominator <= 0.0:
            return -1.0
        t = 2.0 * height / denominator
    else:
        if gz >= 0.0:
            return -1.0
        t = (vz + root) / (-gz)
    if t <= horizon:
        return t
    return -1.0


@njit(parallel=True, cache=True)
def _ballistic_step(x, v, g, floor, restitution, rest_speed, dt):
    """Advance positions ``x`` and velocities ``v`` (N, 3) by ``dt`` in place, exactly."""
    for i in prange(x.shape[0]):
        t_left = dt
        for _ in range(_MAX_CONTACTS_PER_STEP):
            height = x[i, 2] - floor
            resting = height <= 0.0 and v[i, 2] <= 0.0 and g[2] <= 0.0
            t_hit = -1.0 if resting else _first_contact(height, v[i, 2], g[2], t_left)
            t = t_left if t_hit < 0.0 else t_hit
            for k in range(2):
                x[i, k] += v[i, k] * t + 0.5 * g[k] * t * t
                v[i, k] += g[k] * t
            if resting:
                x[i, 2] = floor
                v[i, 2] = 0.0
                break
            if t_hit < 0.0:
                x[i, 2] += v[i, 2] * t + 0.5 * g[2] * t * t
                v[i, 2] += g[2] * t
                break
            impact = v[i, 2] + g[2] * t
            x[i, 2] = floor
            v[i, 2] = -restitution * impact
            if v[i, 2] < rest_speed:
                v[i, 2] = 0.0
            t_left -= t
            if t_left <= 0.0:
                break


class BallisticParticles(Simulation):
    """Particles in free flight under gravity, bouncing on the floor ``z = floor``.

    Parameters
    ----------
    positions : (N, 3) array_like
        Initial positions (m), all at or above the floor.
    velocities : (N, 3) array_like, optional
        Initial velocities (m/s); zeros when omitted.
    gravity : sequence of 3 float
        Acceleration (m/s^2), default ``(0, 0, -9.81)``.
    floor : float
        Height of the floor (m).
    restitution : float
        Coefficient of restitution in [0, 1].
    max_dt : float
        Largest step (s) :meth:`advance_to` takes; the integration is exact for any step, so this
        only sets how often contacts are resolved per frame.

    Notes
    -----
    Between contacts the motion is integrated in closed form, so the trajectory before the first
    bounce agrees with ``x0 + v0 t + g t^2 / 2`` to round-off.  Horizontal velocity is kept at a
    contact (a frictionless floor).
    """

    def __init__(self, positions: ArrayLike, velocities: ArrayLike | None = None, *,
                 gravity: ArrayLike = (0.0, 0.0, -9.81), floor: float = 0.0,
                 restitution: float = 0.7, max_dt: float = 1.0 / 120.0):
        gravity = check_finite_vector("gravity", gravity, 3)
        check_range("restitution", restitution, 0.0, 1.0)
        check_range("floor", floor, -math.inf, math.inf)
        check_range("max_dt", max_dt, 0.0, math.inf, low_inclusive=False)
        state = State(positions, velocities)
        if state.n_points and state.positions[:, 2].min() < floor:
            raise ValueError(
                f"positions must be at or above the floor z = {floor}; lowest is "
                f"{state.positions[:, 2].min():.6g}"
            )
        self.model = BallisticModel(tuple(gravity), float(floor), float(restitution))
        self.state = state
        self.max_dt = float(max_dt)
        self._gravity = np.array(gravity, dtype=np.float64)

    @property
    def output_spec(self) -> OutputSpec:
        return OutputSpec(point_arrays=(("velocity", 3), ("id", 1)), topology="vertices")

    def _step(self, dt: float) -> None:
        m = self.model
        _ballistic_step(self.state.positions, self.state.velocities, self._gravity, m.floor,
                        m.restitution, m.rest_speed, dt)
