"""Input validation shared by all filters: clear errors naming the parameter and its valid range."""

from __future__ import annotations

import math
import numbers
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Collection

    from numpy.typing import ArrayLike

__all__ = ["check_range", "check_finite", "check_int", "check_bool", "check_finite_vector",
           "check_points", "check_choice", "check_radii"]


def check_range(name: str, value: object, low: float = -math.inf, high: float = math.inf, *,
                low_inclusive: bool = True, high_inclusive: bool = True) -> float:
    """Return ``value`` as a float if it is a real number within the given range.

    Raises
    ------
    TypeError
        If ``value`` is not a real number.
    ValueError
        If it is NaN or outside ``[low, high]`` (or the open ends asked for), naming ``name``.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__} {value!r}")
    value = float(value)
    ok = not math.isnan(value)
    ok = ok and (value >= low if low_inclusive else value > low)
    ok = ok and (value <= high if high_inclusive else value < high)
    if not ok:
        left = "[" if low_inclusive else "("
        right = "]" if high_inclusive else ")"
        raise ValueError(f"{name} must be in {left}{low:g}, {high:g}{right}, got {value!r}")
    return value


def check_finite(name: str, value: object, low: float = -math.inf, high: float = math.inf, *,
                 low_inclusive: bool = True, high_inclusive: bool = True) -> float:
    """Like :func:`check_range`, but +-inf is refused too (even where the range is unbounded).

    Raises
    ------
    TypeError
        If ``value`` is not a real number.
    ValueError
        If it is NaN, infinite or outside the range, naming ``name``.
    """
    value = check_range(name, value, low, high, low_inclusive=low_inclusive,
                        high_inclusive=high_inclusive)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return value


def check_int(name: str, value: object, low: int | None = None, high: int | None = None) -> int:
    """Return ``value`` as an int if it is an integer within ``[low, high]``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__} {value!r}")
    value = int(value)
    if (low is not None and value < low) or (high is not None and value > high):
        lo = "-inf" if low is None else low
        hi = "inf" if high is None else high
        raise ValueError(f"{name} must be an integer in [{lo}, {hi}], got {value}")
    return value


def check_finite_vector(name: str, value: ArrayLike, size: int) -> np.ndarray:
    """Return ``value`` as a finite float64 vector of length ``size``."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a sequence of {size} numbers, got {value!r}") from None
    if array.shape != (size,):
        raise ValueError(f"{name} must have {size} components, got shape {array.shape}")
    if not np.isfinite(array).all():
        raise ValueError(f"{name} must be finite, got {array.tolist()}")
    return array


def check_points(name: str, value: ArrayLike) -> np.ndarray:
    """Return ``value`` as a C-contiguous finite ``(N, 3) float64`` array."""
    try:
        array = np.ascontiguousarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be an (N, 3) array of numbers") from None
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {array.shape}")
    if not np.isfinite(array).all():
        raise ValueError(f"{name} contains NaN or infinite values")
    return array


def check_choice(name: str, value: object, choices: Collection[str]) -> str:
    """Return ``value`` if it is one of ``choices``; the error lists the options."""
    if value not in choices:
        options = ", ".join(repr(c) for c in choices)
        raise ValueError(f"{name} must be one of {options}; got {value!r}")
    return value


def check_bool(name: str, value: object) -> bool:
    """Return ``value`` as a bool if it is True or False (NumPy's too); anything else, such as
    the string ``"false"`` that ``bool()`` would take for True, raises TypeError."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise TypeError(f"{name} must be True or False, got {value!r}")


def check_radii(name: str, radius: ArrayLike, n: int) -> np.ndarray:
    """Return per-point radii as a finite, positive ``(n,) float64`` array.

    ``radius`` is one positive finite number (broadcast) or an array of ``n`` of them; anything
    else raises ``TypeError`` or ``ValueError`` naming ``name``.
    """
    if isinstance(radius, numbers.Real) and not isinstance(radius, bool):
        r = check_range(name, radius, 0.0, math.inf, low_inclusive=False)
        if not math.isfinite(r):
            raise ValueError(f"{name} must be finite, got {radius!r}")
        return np.full(n, r)
    try:
        radii = np.ascontiguousarray(radius, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a positive number or an (N,) array") from None
    if radii.shape != (n,):
        raise ValueError(f"{name} must be a number or have shape ({n},), got {radii.shape}")
    if n and not (np.isfinite(radii).all() and radii.min() > 0):
        raise ValueError(f"{name} must be finite and > 0 for every particle")
    return radii
