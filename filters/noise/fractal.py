"""Fractal sums of improved noise: fBm and turbulence, time-varying by drifting offsets.

* :func:`fbm3` / :func:`turbulence3` - fractional Brownian motion and Perlin's turbulence (sum of
  ``|noise|``) over octaves with lacunarity and gain (Perlin 1985; Musgrave in Ebert et al. 2003),
  with analytic gradients; :func:`fbm_value`, :func:`fbm_value_grad` and
  :func:`fbm_value_grad_hess` are the point kernels other Numba kernels call.

Frequency and time
------------------
Octave ``k`` of a sum is evaluated at ``lacunarity**k * frequency * x + shift_k + o`` where
``shift_k`` is a fixed non-integer shift per octave (:data:`OCTAVE_SHIFT`, 0 for octave 0, so a
one-octave fBm equals :func:`filters.noise.perlin.perlin3`). *Time-varying* noise is done by
**drifting offsets**, not a 4th dimension: at time ``t`` (s) potential ``p`` uses
``o = t * time_scale * D_p`` with a fixed unit direction :data:`DRIFT` ``[p]``. Because the
drift is in noise units, octaves of different sizes move at different speeds in metres, so a
fractal field evolves rather than translating rigidly; and because the offset does not depend
on ``x`` every spatial derivative, hence the zero divergence of curl noise, holds at every
``t``. ``time_scale`` is in lattice cells per second.

The array functions evaluate octave by octave over blocks of :data:`BLOCK` points rather than
with an inner octave loop, so that the inner loops vectorise; their results equal the point
kernels' to the bit (tested). A last octave whose frequency overflows float64 is refused.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..validation import check_finite, check_int, check_points, check_range
from .lattice import wide_vectors
from .perlin import (
    check_frequency,
    interleave3,
    kernel_table,
    perlin_value,
    perlin_value_grad,
    perlin_value_grad_hess,
)

if TYPE_CHECKING:
    from typing import Any

    from numpy.typing import ArrayLike, NDArray

__all__ = [
    "MAX_OCTAVES",
    "OCTAVE_SHIFT",
    "DRIFT",
    "BLOCK",
    "fbm_value",
    "fbm_value_grad",
    "fbm_value_grad_hess",
    "octave_accumulate",
    "check_fractal",
    "check_top_frequency",
    "fbm3",
    "turbulence3",
]

#: Most octaves a fractal sum may have.
MAX_OCTAVES = 16

#: Fixed per-octave shifts (noise units) so that octaves do not share the lattice zeros of
#: octave 0; octave 0 is unshifted, so a one-octave fBm equals perlin3.
OCTAVE_SHIFT = np.array(
    [[0.0, 0.0, 0.0]] + [[(k * 0.6180339887498949 * 37.0) % 97.0 + 0.31,
                          (k * 0.7548776662466927 * 41.0) % 89.0 + 0.47,
                          (k * 0.5698402909980532 * 43.0) % 83.0 + 0.13]
                         for k in range(1, MAX_OCTAVES)], dtype=np.float64)
OCTAVE_SHIFT.setflags(write=False)

#: Unit drift directions of three potentials (or components) for time-varying noise.
DRIFT = np.array([[0.0, 0.6, 0.8], [0.8, 0.0, 0.6], [0.6, 0.8, 0.0]], dtype=np.float64)
DRIFT.setflags(write=False)

#: Points per block of the vectorised array evaluations (accumulators stay in cache).
BLOCK = 32768


@njit(cache=True)
def fbm_value_grad(p, x, y, z, frequency, octaves, lacunarity, gain, ox, oy, oz, turbulence):
    """Fractal sum of improved noise and its gradient (world units) at one point.

    ``sum_k gain**k N(lacunarity**k * frequency * x + shift_k + o)`` (or of ``|N|`` when
    ``turbulence``); returns (value, d/dx, d/dy, d/dz) with d/dx in 1/m.
    """
    val = 0.0
    gx = 0.0
    gy = 0.0
    gz = 0.0
    amp = 1.0
    f = frequency
    for k in range(octaves):
        n, nx, ny, nz = perlin_value_grad(p, f * x + OCTAVE_SHIFT[k, 0] + ox,
                                          f * y + OCTAVE_SHIFT[k, 1] + oy,
                                          f * z + OCTAVE_SHIFT[k, 2] + oz)
        if turbulence and n < 0.0:
            n = -n
            nx = -nx
            ny = -ny
            nz = -nz
        val += amp * n
        gx += amp * f * nx
        gy += amp * f * ny
        gz += amp * f * nz
        amp *= gain
        f *= lacunarity
    return val, gx, gy, gz

@njit(cache=True)
def fbm_value(p, x, y, z, frequency, octaves, lacunarity, gain, ox, oy, oz, turbulence):
    """Fractal sum of improved noise at one point (value only); see :func:`fbm_value_grad`."""
    val = 0.0
    amp = 1.0
    f = frequency
    for k in range(octaves):
        n = perlin_value(p, f * x + OCTAVE_SHIFT[k, 0] + ox, f * y + OCTAVE_SHIFT[k, 1] + oy,
                         f * z + OCTAVE_SHIFT[k, 2] + oz)
        if turbulence and n < 0.0:
            n = -n
        val += amp * n
        amp *= gain
        f *= lacunarity
    return val

@njit(cache=True)
def fbm_value_grad_hess(p, x, y, z, frequency, octaves, lacunarity, gain, ox, oy, oz):
    """fBm value, gradient (1/m) and Hessian (1/m^2) at one point (no turbulence: ``|N|`` is
    not C1).

    Returns the 10-tuple ``v, gx, gy, gz, hxx, hyy, hzz, hxy, hxz, hyz``.
    """
    v = 0.0
    gx = 0.0
    gy = 0.0
    gz = 0.0
    hxx = 0.0
    hyy = 0.0
    hzz = 0.0
    hxy = 0.0
    hxz = 0.0
    hyz = 0.0
    amp = 1.0
    f = frequency
    for k in range(octaves):
        r = perlin_value_grad_hess(p, f * x + OCTAVE_SHIFT[k, 0] + ox,
                                   f * y + OCTAVE_SHIFT[k, 1] + oy,
                                   f * z + OCTAVE_SHIFT[k, 2] + oz)
        a1 = amp * f
        a2 = a1 * f
        v += amp * r[0]
        gx += a1 * r[1]
        gy += a1 * r[2]
        gz += a1 * r[3]
        hxx += a2 * r[4]
        hyy += a2 * r[5]
        hzz += a2 * r[6]
        hxy += a2 * r[7]
        hxz += a2 * r[8]
        hyz += a2 * r[9]
        amp *= gain
        f *= lacunarity
    return v, gx, gy, gz, hxx, hyy, hzz, hxy, hxz, hyz


@njit(parallel=True, cache=True)
def octave_accumulate(p, flat, start, count, f, amp, sx, sy, sz, ox, oy, oz, first, turbulence,
                       v, gx, gy, gz):
    """Add one octave ``amp * N(f x + shift + o)`` and its gradient for points
    ``start .. start + count`` into contiguous accumulators (the loop vectorises), with the
    same operations, hence the same bits, as :func:`fbm_value_grad`."""
    a1 = amp * f
    for j in prange(count):
        wide_vectors()  # 8 doubles a vector where the CPU has AVX-512
        k = np.uint64(3 * (start + j))  # unsigned: interleaved loads, not gathers
        n, nx, ny, nz = perlin_value_grad(p, f * flat[k] + sx + ox,
                                          f * flat[k + np.uint64(1)] + sy + oy,
                                          f * flat[k + np.uint64(2)] + sz + oz)
        if turbulence and n < 0.0:
            n = -n
            nx = -nx
            ny = -ny
            nz = -nz
        if first:
            v[j] = 0.0 + amp * n
            gx[j] = 0.0 + a1 * nx
            gy[j] = 0.0 + a1 * ny
            gz[j] = 0.0 + a1 * nz
        else:
            v[j] += amp * n
            gx[j] += a1 * nx
            gy[j] += a1 * ny
            gz[j] += a1 * nz


@njit(parallel=True, cache=True)
def _octave_value_accumulate(p, flat, start, count, f, amp, sx, sy, sz, ox, oy, oz, first,
                             turbulence, v):
    """Value-only :func:`_octave_accumulate` (same bits as :func:`fbm_value`)."""
    for j in prange(count):
        wide_vectors()
        k = np.uint64(3 * (start + j))
        n = perlin_value(p, f * flat[k] + sx + ox, f * flat[k + np.uint64(1)] + sy + oy,
                         f * flat[k + np.uint64(2)] + sz + oz)
        if turbulence and n < 0.0:
            n = -n
        if first:
            v[j] = 0.0 + amp * n
        else:
            v[j] += amp * n

def _fbm_array(table, pts, frequency, octaves, lacunarity, gain, ox, oy, oz, turbulence,
               gradient):
    """fBm over (N, 3) points, octave by octave over blocks (vectorised inner loops)."""
    n = pts.shape[0]
    flat = pts.reshape(-1)
    out = np.empty(n)
    soa = np.empty((3, n)) if gradient else None
    for start in range(0, n, BLOCK):
        count = min(BLOCK, n - start)
        stop = start + count
        f = frequency
        amp = 1.0
        for k in range(octaves):
            sx, sy, sz = OCTAVE_SHIFT[k]
            if gradient:
                octave_accumulate(table, flat, start, count, f, amp, sx, sy, sz, ox, oy, oz,
                                   k == 0, turbulence, out[start:stop], soa[0, start:stop],
                                   soa[1, start:stop], soa[2, start:stop])
            else:
                _octave_value_accumulate(table, flat, start, count, f, amp, sx, sy, sz, ox, oy,
                                         oz, k == 0, turbulence, out[start:stop])
            amp *= gain
            f *= lacunarity
    if not gradient:
        return out
    grad = np.empty((n, 3))
    interleave3(soa[0], soa[1], soa[2], grad)
    return out, grad


def check_fractal(octaves: int, lacunarity: float, gain: float,
                  frequency: float = 1.0) -> tuple[int, float, float]:
    """Validate the octaves (1 to :data:`MAX_OCTAVES`), lacunarity ([1, 16]) and gain ([0, 1])
    of a fractal sum, and that its last octave's frequency is finite; returns them."""
    octaves = check_int("octaves", octaves, 1, MAX_OCTAVES)
    lacunarity = check_range("lacunarity", lacunarity, 1.0, 16.0)
    gain = check_range("gain", gain, 0.0, 1.0)
    check_top_frequency(frequency, octaves, lacunarity)
    return octaves, lacunarity, gain


def check_top_frequency(frequency: float, octaves: int, lacunarity: float) -> None:
    """Refuse a last octave whose frequency ``frequency * lacunarity**(octaves - 1)`` overflows
    float64 (its coordinates and gradients would be inf or NaN)."""
    top = float(frequency) * float(lacunarity) ** (int(octaves) - 1)
    if not math.isfinite(top):
        raise ValueError(
            f"frequency * lacunarity**(octaves - 1) (the last octave's frequency) must be finite, "
            f"got frequency = {frequency!r}, lacunarity = {lacunarity!r}, octaves = {octaves}")

def fbm3(points: ArrayLike, *, octaves: int = 4, lacunarity: float = 2.0, gain: float = 0.5,
         seed: int = 0, frequency: float = 1.0, time: float = 0.0, time_scale: float = 0.0,
         turbulence: bool = False,
         gradient: bool = False) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Fractional Brownian motion of improved noise (or Perlin's turbulence).

    ``f(x, t) = sum_{k < octaves} gain**k * N(lacunarity**k * frequency * x + shift_k + o(t))``
    with ``o(t) = time * time_scale * D`` (time-varying noise by drifting offsets, see the module
    docstring); with ``turbulence`` the sum is of ``|N|`` (Perlin 1985).

    Parameters
    ----------
    points : (N, 3) array_like
        Points (m).
    octaves : int
        Number of octaves, 1 to 16.
    lacunarity : float
        Frequency ratio between octaves, in [1, 16].
    gain : float
        Amplitude ratio between octaves, in [0, 1].
    seed : int
        Permutation seed (0 = Perlin's).
    frequency : float
        Lattice cells per metre of octave 0, > 0.
    time : float
        Time (s).
    time_scale : float
        Drift speed of the noise (lattice cells per second).
    turbulence : bool
        Sum ``|N|`` instead of ``N``.
    gradient : bool
        Also return the gradient.

    Returns
    -------
    values : (N,) float64
    gradients : (N, 3) float64, only when ``gradient``
        Derivatives (1/m); for turbulence, ``sign(N) grad N`` per octave (undefined on N = 0).
    """
    pts = check_points("points", points)
    frequency = check_frequency(frequency)
    octaves, lacunarity, gain = check_fractal(octaves, lacunarity, gain, frequency)
    time = check_finite("time", time)
    time_scale = check_finite("time_scale", time_scale)
    table = kernel_table(seed)
    s = time * time_scale
    ox, oy, oz = (s * DRIFT[0]).tolist()
    return _fbm_array(table, pts, frequency, octaves, lacunarity, gain, ox, oy, oz,
                      bool(turbulence), bool(gradient))

def turbulence3(points: ArrayLike,
                **kwargs: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Perlin's turbulence ``sum_k gain**k |N(...)|``: :func:`fbm3` with ``turbulence=True``."""
    return fbm3(points, turbulence=True, **kwargs)
