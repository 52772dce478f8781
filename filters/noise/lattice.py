"""Lattice primitives shared by the noise kernels (Perlin 2002): fade, lerp, gradients, the wrap.

Every function here is an ``@njit(inline="always")`` building block of the point kernels in
:mod:`filters.noise.perlin`; none allocates or branches on data, so the loops that call them
vectorise. :func:`wide_vectors` marks a Numba function for 512-bit vectors where the CPU has
them (see its notes).
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.extending import intrinsic

__all__ = ["WRAP_LIMIT", "fade", "dfade", "ddfade", "lerp", "lerp_with_gradient",
           "gradient_vector", "grad", "grad_select", "clamp_lattice", "wide_vectors"]

#: Lattice coordinates are clamped to +-2**60 before ``floor`` (see :func:`clamp_lattice`).
WRAP_LIMIT = float(2**60)


@njit(cache=True, inline="always")
def fade(t):
    """Perlin's quintic fade ``6 t^5 - 15 t^4 + 10 t^3``, in the reference's operation order."""
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


@njit(cache=True, inline="always")
def dfade(t):
    """d fade / dt = ``30 t^2 (t - 1)^2``."""
    return 30.0 * t * t * (t * (t - 2.0) + 1.0)


@njit(cache=True, inline="always")
def ddfade(t):
    """d^2 fade / dt^2 = ``60 t (2 t^2 - 3 t + 1)``."""
    return 60.0 * t * (t * (2.0 * t - 3.0) + 1.0)


@njit(cache=True, inline="always")
def lerp(t, a, b):
    """The reference's ``a + t (b - a)`` (two roundings; never fused into an FMA)."""
    return a + t * (b - a)


@njit(cache=True, inline="always")
def lerp_with_gradient(t, dt, a, b, dax, day, daz, dbx, dby, dbz, axis):
    """``lerp(t, a, b)`` and its gradient, where ``t`` depends on coordinate ``axis`` only
    (``dt`` = dt / d x_axis; ``da*``, ``db*`` the gradients of ``a`` and ``b``)."""
    val = a + t * (b - a)
    gx = dax + t * (dbx - dax)
    gy = day + t * (dby - day)
    gz = daz + t * (dbz - daz)
    if axis == 0:
        gx += dt * (b - a)
    elif axis == 1:
        gy += dt * (b - a)
    else:
        gz += dt * (b - a)
    return val, gx, gy, gz


@njit(cache=True, inline="always")
def gradient_vector(h):
    """The gradient vector (gx, gy, gz) encoded in bits 8-13 of a kernel-table entry."""
    c = h >> 8
    return (np.float64(c & 3) - 1.0, np.float64((c >> 2) & 3) - 1.0,
            np.float64((c >> 4) & 3) - 1.0)


@njit(cache=True, inline="always")
def grad(h, x, y, z):
    """Perlin's ``grad(hash, x, y, z)``: the dot product of gradient ``hash & 15`` with (x, y, z).

    Written as ``(gx x + gy y) + gz z`` with the gradient's entries (each 0 or +-1), which
    rounds exactly like the reference's ``(+-u) + (+-v)`` (multiplying by +-1 and adding a zero
    are exact) but has no data-dependent branch, so the loops over points vectorise.
    """
    gx, gy, gz = gradient_vector(h)
    return (gx * x + gy * y) + gz * z


@njit(cache=True, inline="always")
def grad_select(c, x, y, z):
    """Perlin's ``grad`` as the reference writes it, ``(+-u) + (+-v)``, from a select code ``c``.

    ``c`` holds the reference's decisions for ``h = hash & 15`` as bits: 1 ``u = y`` (``h >=
    8``, else ``x``), 2 ``v = y`` (``h < 4``), 4 ``v = x`` (``h`` 12 or 14; else ``v = z``), 8
    negate ``u`` (``h & 1``), 16 negate ``v`` (``h & 2``). The same two operands and the same
    addition as the reference, so the same bits; in a vectorised loop the choices are masked
    blends and sign flips (no conversions, no multiplications).
    """
    u = y if c & 1 else x
    v = y if c & 2 else (x if c & 4 else z)
    return (-u if c & 8 else u) + (-v if c & 16 else v)


@njit(cache=True, inline="always")
def clamp_lattice(x):
    """``x`` clamped to ``[-2**60, 2**60]``, which changes no noise value (see below).

    The reference wraps the lattice coordinate, ``floor(x) & 255``, i.e. ``floor(x) mod 256``.
    Every float64 with ``|x| >= 2**60`` is a multiple of 256 (the spacing of floats there is
    ``2**8``), so there ``floor(x) mod 256 = 0`` and the fractional part is 0, exactly as at
    ``+-2**60``: the clamp keeps the float-to-int64 conversion of ``floor(x)`` in range (an
    out-of-range conversion is undefined behaviour; it returned values of ~1e116 at 1e19 and NaN
    at 1e300) without changing any result, and it maps a coordinate that overflowed to +-inf
    (``frequency * x`` near the float64 limit) to the same limit. ``min``/``max`` compile to
    two vector instructions: the loops still vectorise (perlin3 on 1M points: +3 %, fbm3 and
    curl noise within the noise of the timing). NaN is not handled here: the public functions
    refuse it before any work.
    """
    return min(max(x, -WRAP_LIMIT), WRAP_LIMIT)


@intrinsic
def wide_vectors(typingctx):
    """Mark the Numba function that calls this for 512-bit vectors (emits no instruction).

    LLVM vectorises loops 256 bits wide on Intel CPUs with AVX-512 unless a function asks
    for more (its ``prefer-256-bit`` tuning, chosen against the clock drop of early AVX-512
    parts). Called inside a ``prange`` body it sets the function attribute
    ``"prefer-vector-width"="512"`` on the loop's outlined function, so that loop runs 8
    doubles wide; on CPUs without AVX-512 the attribute asks for nothing they cannot do and
    the loop stays as it was. Vector width changes no result (no reassociation, no FMA
    contraction without fastmath). Measured on ``perlin3``'s loop (1M points, one thread, the
    project's Sapphire Rapids machine, CPU time): 14.5 ms at 256 bits, 9.4 ms at 512; the
    whole against FastNoiseLite in ``benchmarks/bench_noise.py``.

    llvmlite's attribute set accepts only the attribute names it knows, so the string
    attribute is added to the underlying set; should a later llvmlite refuse it, the call is
    a no-op and the loop keeps LLVM's default width.
    """
    def codegen(context, builder, signature, args):
        try:
            set.add(builder.function.attributes, '"prefer-vector-width"="512"')
        except Exception:  # pragma: no cover - an llvmlite that changed its attribute set
            pass
        return context.get_dummy_value()

    return types.none(), codegen
