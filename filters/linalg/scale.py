"""Right-hand sides brought to unit size before a solve, so that tiny states solve like any other.

A linear system ``A x = b`` is solved as ``A (x / s) = b / s`` with ``s = max |b|``: conjugate
gradients square their vectors (``|r|^2``, ``r . z``, ``p . A p``), which underflow for entries
below ~1e-154 (a long undamped backward Euler run decays to ~1e-160 and lower), so that a
division by an underflowed zero raised, or a residual norm of 0 ended the solve with a wrong
``x``.  After scaling every vector is of order 1; the solution is scaled back, exactly for a
power-of-two ``s`` (the scale is rounded to one).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = ["unit_scale"]

#: Largest warm start kept, relative to ``max |b|``: beyond it its squares could overflow.
_WARM_LIMIT = 1e100


def unit_scale(b: np.ndarray,
               x0: np.ndarray | None = None) -> tuple[float, NDArray[np.float64],
                                                      NDArray[np.float64] | None]:
    """The scale of a right-hand side and the scaled problem.

    Parameters
    ----------
    b : float64 array
        Right-hand side (any shape).
    x0 : float64 array shaped like ``b``, optional
        Warm start.

    Returns
    -------
    s : float
        A power of two within a factor 2 of ``max |b|`` (so that scaling is exact), 0 when
        ``b`` is zero (the solution is then zero), or 1 when ``b`` has a value that is not
        finite (left to the solver, whose result is then not finite either: the integrators'
        instability checks report it).
    b_scaled : float64 array
        ``b / s`` (``b`` itself when ``s`` is 0 or 1).
    x_scaled : float64 array or None
        ``x0 / s``, or None when there is no warm start or it is over 1e100 times ``max |b|``
        (a warm start of another size than the solution is of no use, and its squares would
        overflow).
    """
    b = np.asarray(b, dtype=np.float64)
    top = float(np.abs(b).max()) if b.size else 0.0
    if not math.isfinite(top):
        return 1.0, b, None if x0 is None else np.asarray(x0, dtype=np.float64)
    if top == 0.0:
        return 0.0, b, None
    s = math.ldexp(1.0, math.frexp(top)[1])  # 2^e >= max |b|: exact scaling
    if s == 1.0:
        return 1.0, b, None if x0 is None else np.asarray(x0, dtype=np.float64)
    with np.errstate(over="ignore", under="ignore"):
        bs = b / s
        xs = None if x0 is None else np.asarray(x0, dtype=np.float64) / s
    if xs is not None and not float(np.abs(xs).max(initial=0.0)) <= _WARM_LIMIT:
        xs = None  # a warm start 1e100 times the right-hand side: squares would overflow
    return s, bs, xs
