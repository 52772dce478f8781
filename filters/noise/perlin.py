"""Perlin's improved noise, its derivatives, fractal sums and curl noise, in Numba.

What is here
------------
* :func:`perlin3` - Perlin's *improved noise* (Perlin 2002, "Improving Noise", SIGGRAPH), bit-exact
  to his reference Java implementation in float64: his published permutation, the quintic fade
  ``6 t^5 - 15 t^4 + 10 t^3`` and his 16-entry gradient set (the 12 cube-edge directions with four
  repeated), evaluated with the reference's order of floating-point operations so that
  ``perlin3(3.14, 42, 7) == 0.13691995878400012`` exactly.
* :func:`perlin3_gradient` and :func:`perlin3_hessian` - analytic first and second derivatives
  (the noise is C2: the fade's first and second derivatives vanish at the lattice).
* :func:`permutation_table` - other seeds by a deterministic Fisher-Yates shuffle (SplitMix64,
  Steele, Lea & Flood 2014) of the reference permutation; seed 0 *is* the reference.
* :func:`fbm3` / :func:`turbulence3` - fractional Brownian motion and Perlin's turbulence (sum of
  ``|noise|``) over octaves with lacunarity and gain (Perlin 1985; Musgrave in Ebert et al. 2003).
* :func:`curl_noise` / :class:`CurlNoise` - the divergence-free velocity of Bridson, Hourihan &
  Nordenstam (2007), "Curl-noise for procedural fluid flow": ``v = curl psi`` with three
  decorrelated fBm potentials (three differently shuffled permutations), analytic derivatives,
  and optionally the paper's boundary ramp ``psi' = a psi + (1 - a) n (n . psi)``,
  ``a = ramp(d / d0)``, which makes the velocity tangent to collider surfaces while keeping it
  exactly divergence-free.
* :class:`PlaneSDF`, :class:`SphereSDF`, :class:`InsideSphereSDF` - signed-distance primitives
  (with normals and Hessians) for that ramp, packed into plain arrays for the kernels.

Frequency and time
------------------
Every function takes ``frequency`` (1/m): noise is evaluated at ``frequency * x``, so one lattice
cell spans ``1 / frequency`` metres.  *Time-varying* noise is done by **drifting offsets**, not a
4th dimension: at time ``t`` (s) octave ``k`` of potential ``p`` is evaluated at
``lacunarity**k * frequency * x + shift_k + t * time_scale * D_p``, where ``shift_k`` is a fixed
non-integer shift per octave (0 for octave 0) and ``D_p`` a fixed unit direction per potential.
Because the drift is in noise units, octaves of different sizes move at different speeds in
metres, so a fractal field evolves rather than translating rigidly; and because the offset does
not depend on ``x`` every spatial derivative, hence the zero divergence of curl noise, holds at
every ``t``.  ``time_scale`` is in lattice cells per second.

Domain
------
Every function is defined for all finite inputs and returns values in its documented range: the
lattice coordinate wraps as in the reference, ``floor(x) mod 256``, computed exactly for any
float64 (clamping to ``+-2**60`` first, where every float is a multiple of 256, so no value
changes; see ``_clamp_lattice``). Wrapping rather than refusing large coordinates because the
result is well defined there (noise is periodic with period 256 lattice cells) and a clamp costs
nothing measurable. NaN or infinite points, times and parameters raise ValueError naming the
parameter before any work, as does a last octave whose frequency overflows.

Implementation notes
--------------------
Point-level kernels (``perlin_value``, ``perlin_value_grad``, ``perlin_value_grad_hess``,
``fbm_value``, ``fbm_value_grad``, ``fbm_value_grad_hess``, ``curl_point``,
``curl_jacobian_point``, ``sdf_point``) are ``@njit`` functions that other Numba kernels (fields,
SPH, springs) may call directly.  They take a *kernel table*: the doubled permutation in the low
8 bits of each int32 entry and, above them, the gradient Perlin's ``grad`` would pick for that
entry, so that a corner costs one lookup and no data-dependent branch.  The dot product with a
gradient is formed as ``(gx x + gy y) + gz z`` with entries in {0, +-1}, which rounds exactly
like the reference's ``(+-u) + (+-v)``; the noise stays bit-exact.

The array functions loop over points in ``prange`` loops that LLVM vectorises (AVX2/AVX-512
gathers): points are read through a flat view, outputs are written to contiguous arrays, and
fractal sums and curl noise are evaluated octave by octave over blocks of points rather than with
an inner octave loop.  Their results equal the point kernels' to the bit (tested).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numba import njit, prange

from ..validation import check_finite, check_finite_vector, check_int, check_points, check_range

__all__ = [
    "PERMUTATION",
    "GRADIENTS",
    "permutation_table",
    "perlin3",
    "perlin3_gradient",
    "perlin3_hessian",
    "fbm3",
    "turbulence3",
    "curl_noise",
    "curl_noise_jacobian",
    "CurlNoise",
    "PlaneSDF",
    "SphereSDF",
    "InsideSphereSDF",
    "pack_colliders",
    "signed_distance",
    "MAX_OCTAVES",
    "check_top_frequency",
]

#: Ken Perlin's published permutation of 0..255 (Perlin 2002, reference implementation).
PERMUTATION = np.array([
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225, 140, 36, 103, 30, 69,
    142, 8, 99, 37, 240, 21, 10, 23, 190, 6, 148, 247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219,
    203, 117, 35, 11, 32, 57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175,
    74, 165, 71, 134, 139, 48, 27, 166, 77, 146, 158, 231, 83, 111, 229, 122, 60, 211, 133, 230,
    220, 105, 92, 41, 55, 46, 245, 40, 244, 102, 143, 54, 65, 25, 63, 161, 1, 216, 80, 73, 209, 76,
    132, 187, 208, 89, 18, 169, 200, 196, 135, 130, 116, 188, 159, 86, 164, 100, 109, 198, 173,
    186, 3, 64, 52, 217, 226, 250, 124, 123, 5, 202, 38, 147, 118, 126, 255, 82, 85, 212, 207, 206,
    59, 227, 47, 16, 58, 17, 182, 189, 28, 42, 223, 183, 170, 213, 119, 248, 152, 2, 44, 154, 163,
    70, 221, 153, 101, 155, 167, 43, 172, 9, 129, 22, 39, 253, 19, 98, 108, 110, 79, 113, 224, 232,
    178, 185, 112, 104, 218, 246, 97, 228, 251, 34, 242, 193, 238, 210, 144, 12, 191, 179, 162,
    241, 81, 51, 145, 235, 249, 14, 239, 107, 49, 192, 214, 31, 181, 199, 106, 157, 184, 84, 204,
    176, 115, 121, 50, 45, 127, 4, 150, 254, 138, 236, 205, 93, 222, 114, 67, 29, 24, 72, 243, 141,
    128, 195, 78, 66, 215, 61, 156, 180,
], dtype=np.int32)
PERMUTATION.setflags(write=False)

#: The gradient vector selected by ``hash & 15`` in Perlin's ``grad``: the 12 cube-edge
#: directions, then rows 12-15 = (1,1,0), (0,-1,1), (-1,1,0), (0,-1,-1), repeats that come from
#: the reference's ``h == 12 || h == 14`` rule (padding 12 directions to 16).
GRADIENTS = np.array([
    [1, 1, 0], [-1, 1, 0], [1, -1, 0], [-1, -1, 0],
    [1, 0, 1], [-1, 0, 1], [1, 0, -1], [-1, 0, -1],
    [0, 1, 1], [0, -1, 1], [0, 1, -1], [0, -1, -1],
    [1, 1, 0], [0, -1, 1], [-1, 1, 0], [0, -1, -1],
], dtype=np.float64)
GRADIENTS.setflags(write=False)

#: Most octaves a fractal sum may have.
MAX_OCTAVES = 16

# Fixed per-octave shifts (noise units) so that octaves do not share the lattice zeros of
# octave 0; octave 0 is unshifted, so a one-octave fBm equals perlin3.
_OCTAVE_SHIFT = np.array(
    [[0.0, 0.0, 0.0]] + [[(k * 0.6180339887498949 * 37.0) % 97.0 + 0.31,
                          (k * 0.7548776662466927 * 41.0) % 89.0 + 0.47,
                          (k * 0.5698402909980532 * 43.0) % 83.0 + 0.13]
                         for k in range(1, MAX_OCTAVES)], dtype=np.float64)
_OCTAVE_SHIFT.setflags(write=False)

# Unit drift directions of the three potentials for time-varying noise.
#: Lattice coordinates are clamped to +-2**60 before ``floor`` (see :func:`_clamp_lattice`).
_WRAP_LIMIT = float(2**60)

_DRIFT = np.array([[0.0, 0.6, 0.8], [0.8, 0.0, 0.6], [0.6, 0.8, 0.0]], dtype=np.float64)
_DRIFT.setflags(write=False)


# ---------------------------------------------------------------------------------------------
# Permutations
# ---------------------------------------------------------------------------------------------
def _splitmix64(state: int) -> tuple[int, int]:
    """One SplitMix64 step (Steele, Lea & Flood 2014): returns (new_state, output)."""
    mask = (1 << 64) - 1
    state = (state + 0x9E3779B97F4A7C15) & mask
    z = state
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
    return state, z ^ (z >> 31)


@lru_cache(maxsize=256)
def _table(seed: int) -> np.ndarray:
    perm = [int(p) for p in PERMUTATION]
    if seed != 0:
        state = seed & ((1 << 64) - 1)
        for i in range(255, 0, -1):  # Fisher-Yates, unbiased by rejection
            bound = i + 1
            limit = (1 << 64) - ((1 << 64) % bound)
            while True:
                state, r = _splitmix64(state)
                if r < limit:
                    break
            j = r % bound
            perm[i], perm[j] = perm[j], perm[i]
    table = np.array(perm + perm, dtype=np.int32)
    table.setflags(write=False)
    return table


def permutation_table(seed: int = 0) -> np.ndarray:
    """The doubled permutation table ``p[0:512]`` of a seed.

    (The kernels index an encoded copy of it, see the module notes.)

    Parameters
    ----------
    seed : int
        0 gives Perlin's published permutation (the reference noise).  Any other integer in
        ``[-2**63, 2**64)`` shuffles that permutation with a Fisher-Yates shuffle driven by
        SplitMix64 seeded with ``seed``: deterministic on every platform and NumPy version.

    Returns
    -------
    (512,) int32 array, read-only
        ``p[i] == p[i + 256]``, a permutation of 0..255 in each half.
    """
    seed = check_int("seed", seed, -(1 << 63), (1 << 64) - 1)
    return _table(seed & ((1 << 64) - 1))


@lru_cache(maxsize=256)
def _hash_table(seed: int) -> np.ndarray:
    """The kernels' table: ``p[i] | code(p[i] & 15) << 8`` (512,) int32.

    The low 8 bits are the permutation; bits 8-13 encode the gradient that Perlin's ``grad``
    selects with ``p[i] & 15``, as ``(gx + 1) | (gy + 1) << 2 | (gz + 1) << 4``.  The kernels
    mask with 255 while hashing and decode the gradient from the last lookup, which saves the
    three gradient-table lookups per corner.
    """
    perm = _table(seed)
    g = GRADIENTS[perm & 15].astype(np.int32) + 1
    table = (perm | ((g[:, 0] | (g[:, 1] << 2) | (g[:, 2] << 4)) << 8)).astype(np.int32)
    table.setflags(write=False)
    return table


def _kernel_table(seed) -> np.ndarray:
    """Validated seed -> the kernels' (512,) table."""
    seed = check_int("seed", seed, -(1 << 63), (1 << 64) - 1)
    return _hash_table(seed & ((1 << 64) - 1))


def _tables(seed: int, count: int) -> np.ndarray:
    """``count`` decorrelated kernel tables for seeds ``seed, seed + 1, ...``: (count, 512).

    The potentials of curl noise use seeds ``seed``, ``seed + 1``, ``seed + 2``; seed 0's first
    table is the reference permutation, the others are shuffles.
    """
    return np.stack([_hash_table((seed + k) & ((1 << 64) - 1)) for k in range(count)])


# ---------------------------------------------------------------------------------------------
# Point kernels
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _fade(t):
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


@njit(cache=True, inline="always")
def _dfade(t):
    return 30.0 * t * t * (t * (t - 2.0) + 1.0)


@njit(cache=True, inline="always")
def _ddfade(t):
    return 60.0 * t * (t * (2.0 * t - 3.0) + 1.0)


@njit(cache=True, inline="always")
def _lerp(t, a, b):
    return a + t * (b - a)


@njit(cache=True, inline="always")
def _gvec(h):
    """The gradient vector (gx, gy, gz) encoded in bits 8-13 of a kernel-table entry."""
    c = h >> 8
    return (np.float64(c & 3) - 1.0, np.float64((c >> 2) & 3) - 1.0,
            np.float64((c >> 4) & 3) - 1.0)


@njit(cache=True, inline="always")
def _grad(h, x, y, z):
    """Perlin's ``grad(hash, x, y, z)``: the dot product of gradient ``hash & 15`` with (x, y, z).

    Written as ``(gx x + gy y) + gz z`` with the gradient's entries (each 0 or +-1), which
    rounds exactly like the reference's ``(+-u) + (+-v)`` (multiplying by +-1 and adding a zero
    are exact) but has no data-dependent branch, so the loops over points vectorise.
    """
    gx, gy, gz = _gvec(h)
    return (gx * x + gy * y) + gz * z


@njit(cache=True, inline="always")
def _clamp_lattice(x):
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
    return min(max(x, -_WRAP_LIMIT), _WRAP_LIMIT)


@njit(cache=True, inline="always")
def perlin_value(p, x, y, z):
    """Improved noise at (x, y, z), exactly as Perlin 2002.

    ``p`` is a kernel table (512,) int32 (permutation in the low 8 bits, gradient code above;
    see ``_hash_table``), e.g. a row of :attr:`CurlNoise.tables`.
    """
    x = _clamp_lattice(x)
    y = _clamp_lattice(y)
    z = _clamp_lattice(z)
    fx = math.floor(x)
    fy = math.floor(y)
    fz = math.floor(z)
    X = np.int64(fx) & 255
    Y = np.int64(fy) & 255
    Z = np.int64(fz) & 255
    x = x - fx
    y = y - fy
    z = z - fz
    u = _fade(x)
    v = _fade(y)
    w = _fade(z)
    A = (p[X] & 255) + Y
    AA = (p[A] & 255) + Z
    AB = (p[A + 1] & 255) + Z
    B = (p[X + 1] & 255) + Y
    BA = (p[B] & 255) + Z
    BB = (p[B + 1] & 255) + Z
    return _lerp(w, _lerp(v, _lerp(u, _grad(p[AA], x, y, z), _grad(p[BA], x - 1.0, y, z)),
                         _lerp(u, _grad(p[AB], x, y - 1.0, z), _grad(p[BB], x - 1.0, y - 1.0, z))),
                 _lerp(v, _lerp(u, _grad(p[AA + 1], x, y, z - 1.0),
                                _grad(p[BA + 1], x - 1.0, y, z - 1.0)),
                         _lerp(u, _grad(p[AB + 1], x, y - 1.0, z - 1.0),
                               _grad(p[BB + 1], x - 1.0, y - 1.0, z - 1.0))))


@njit(cache=True, inline="always")
def _lerp_d(t, dt, a, b, dax, day, daz, dbx, dby, dbz, axis):
    """lerp(t, a, b) and its gradient, where t depends on coordinate ``axis`` only."""
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
def perlin_value_grad(p, x, y, z):
    """Improved noise and its gradient at (x, y, z): returns (n, dn/dx, dn/dy, dn/dz).

    The value is computed with the reference's operations, so it equals :func:`perlin_value`
    to the bit.
    """
    x = _clamp_lattice(x)
    y = _clamp_lattice(y)
    z = _clamp_lattice(z)
    fx = math.floor(x)
    fy = math.floor(y)
    fz = math.floor(z)
    X = np.int64(fx) & 255
    Y = np.int64(fy) & 255
    Z = np.int64(fz) & 255
    x = x - fx
    y = y - fy
    z = z - fz
    u = _fade(x)
    v = _fade(y)
    w = _fade(z)
    du = _dfade(x)
    dv = _dfade(y)
    dw = _dfade(z)
    A = (p[X] & 255) + Y
    AA = (p[A] & 255) + Z
    AB = (p[A + 1] & 255) + Z
    B = (p[X + 1] & 255) + Y
    BA = (p[B] & 255) + Z
    BB = (p[B + 1] & 255) + Z
    h000 = p[AA]
    h100 = p[BA]
    h010 = p[AB]
    h110 = p[BB]
    h001 = p[AA + 1]
    h101 = p[BA + 1]
    h011 = p[AB + 1]
    h111 = p[BB + 1]
    n000 = _grad(h000, x, y, z)
    n100 = _grad(h100, x - 1.0, y, z)
    n010 = _grad(h010, x, y - 1.0, z)
    n110 = _grad(h110, x - 1.0, y - 1.0, z)
    n001 = _grad(h001, x, y, z - 1.0)
    n101 = _grad(h101, x - 1.0, y, z - 1.0)
    n011 = _grad(h011, x, y - 1.0, z - 1.0)
    n111 = _grad(h111, x - 1.0, y - 1.0, z - 1.0)
    g000x, g000y, g000z = _gvec(h000)
    g100x, g100y, g100z = _gvec(h100)
    g010x, g010y, g010z = _gvec(h010)
    g110x, g110y, g110z = _gvec(h110)
    g001x, g001y, g001z = _gvec(h001)
    g101x, g101y, g101z = _gvec(h101)
    g011x, g011y, g011z = _gvec(h011)
    g111x, g111y, g111z = _gvec(h111)
    a0, a0x, a0y, a0z = _lerp_d(u, du, n000, n100, g000x, g000y, g000z, g100x, g100y, g100z, 0)
    a1, a1x, a1y, a1z = _lerp_d(u, du, n010, n110, g010x, g010y, g010z, g110x, g110y, g110z, 0)
    a2, a2x, a2y, a2z = _lerp_d(u, du, n001, n101, g001x, g001y, g001z, g101x, g101y, g101z, 0)
    a3, a3x, a3y, a3z = _lerp_d(u, du, n011, n111, g011x, g011y, g011z, g111x, g111y, g111z, 0)
    b0, b0x, b0y, b0z = _lerp_d(v, dv, a0, a1, a0x, a0y, a0z, a1x, a1y, a1z, 1)
    b1, b1x, b1y, b1z = _lerp_d(v, dv, a2, a3, a2x, a2y, a2z, a3x, a3y, a3z, 1)
    return _lerp_d(w, dw, b0, b1, b0x, b0y, b0z, b1x, b1y, b1z, 2)


@njit(cache=True)
def perlin_value_grad_hess(p, x, y, z):
    """Improved noise, gradient and Hessian at (x, y, z).

    Returns
    -------
    tuple of 10 float
        ``n, nx, ny, nz, nxx, nyy, nzz, nxy, nxz, nyz``.  The value is the reference's; the
        derivatives come from writing the noise as a sum over the 8 cell corners of
        ``W(u) W(v) W(w) (g . d)``.
    """
    n, nx, ny, nz = perlin_value_grad(p, x, y, z)
    x = _clamp_lattice(x)
    y = _clamp_lattice(y)
    z = _clamp_lattice(z)
    fx = math.floor(x)
    fy = math.floor(y)
    fz = math.floor(z)
    X = np.int64(fx) & 255
    Y = np.int64(fy) & 255
    Z = np.int64(fz) & 255
    x = x - fx
    y = y - fy
    z = z - fz
    f0 = _fade(x)
    f1 = _fade(y)
    f2 = _fade(z)
    d0 = _dfade(x)
    d1 = _dfade(y)
    d2 = _dfade(z)
    e0 = _ddfade(x)
    e1 = _ddfade(y)
    e2 = _ddfade(z)
    hxx = 0.0
    hyy = 0.0
    hzz = 0.0
    hxy = 0.0
    hxz = 0.0
    hyz = 0.0
    for c in range(8):
        i = c & 1
        j = (c >> 1) & 1
        k = (c >> 2) & 1
        h = p[(p[(p[X + i] & 255) + Y + j] & 255) + Z + k]
        gx, gy, gz = _gvec(h)
        rx = x - i
        ry = y - j
        rz = z - k
        s = gx * rx + gy * ry + gz * rz
        if i == 1:
            wx, dwx, ewx = f0, d0, e0
        else:
            wx, dwx, ewx = 1.0 - f0, -d0, -e0
        if j == 1:
            wy, dwy, ewy = f1, d1, e1
        else:
            wy, dwy, ewy = 1.0 - f1, -d1, -e1
        if k == 1:
            wz, dwz, ewz = f2, d2, e2
        else:
            wz, dwz, ewz = 1.0 - f2, -d2, -e2
        Wx = dwx * wy * wz
        Wy = wx * dwy * wz
        Wz = wx * wy * dwz
        hxx += ewx * wy * wz * s + 2.0 * Wx * gx
        hyy += wx * ewy * wz * s + 2.0 * Wy * gy
        hzz += wx * wy * ewz * s + 2.0 * Wz * gz
        hxy += dwx * dwy * wz * s + Wx * gy + Wy * gx
        hxz += dwx * wy * dwz * s + Wx * gz + Wz * gx
        hyz += wx * dwy * dwz * s + Wy * gz + Wz * gy
    return n, nx, ny, nz, hxx, hyy, hzz, hxy, hxz, hyz


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
        n, nx, ny, nz = perlin_value_grad(p, f * x + _OCTAVE_SHIFT[k, 0] + ox,
                                          f * y + _OCTAVE_SHIFT[k, 1] + oy,
                                          f * z + _OCTAVE_SHIFT[k, 2] + oz)
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
        n = perlin_value(p, f * x + _OCTAVE_SHIFT[k, 0] + ox, f * y + _OCTAVE_SHIFT[k, 1] + oy,
                         f * z + _OCTAVE_SHIFT[k, 2] + oz)
        if turbulence and n < 0.0:
            n = -n
        val += amp * n
        amp *= gain
        f *= lacunarity
    return val


@njit(cache=True)
def fbm_value_grad_hess(p, x, y, z, frequency, octaves, lacunarity, gain, ox, oy, oz):
    """fBm value, gradient (1/m) and Hessian (1/m^2) at one point (no turbulence: |N| is not C1).

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
        r = perlin_value_grad_hess(p, f * x + _OCTAVE_SHIFT[k, 0] + ox,
                                   f * y + _OCTAVE_SHIFT[k, 1] + oy,
                                   f * z + _OCTAVE_SHIFT[k, 2] + oz)
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


# ---------------------------------------------------------------------------------------------
# Signed distances (for the curl-noise boundary ramp and particle push-out)
# ---------------------------------------------------------------------------------------------
_SDF_PLANE = 0
_SDF_SPHERE = 1
_SDF_INSIDE_SPHERE = 2


@njit(cache=True)
def sdf_point(colliders, x, y, z):
    """Signed distance to the union of packed colliders, with the nearest one's unit normal.

    Parameters
    ----------
    colliders : (C, 8) float64
        Rows ``[kind, a0, a1, a2, b0, b1, b2, r]`` from :func:`pack_colliders`.

    Returns
    -------
    d, nx, ny, nz, index
        Distance (m, negative inside), outward unit normal (the SDF gradient) and the row of the
        nearest collider (-1 and ``d = inf`` when there is none).
    """
    best = np.inf
    bx = 0.0
    by = 0.0
    bz = 1.0
    bi = -1
    for c in range(colliders.shape[0]):
        kind = np.int64(colliders[c, 0])
        if kind == _SDF_PLANE:
            nx = colliders[c, 4]
            ny = colliders[c, 5]
            nz = colliders[c, 6]
            d = (x - colliders[c, 1]) * nx + (y - colliders[c, 2]) * ny + (z - colliders[c, 3]) * nz
        else:
            rx = x - colliders[c, 1]
            ry = y - colliders[c, 2]
            rz = z - colliders[c, 3]
            r = math.sqrt(rx * rx + ry * ry + rz * rz)
            if r > 0.0:
                nx = rx / r
                ny = ry / r
                nz = rz / r
            else:
                nx = 0.0
                ny = 0.0
                nz = 1.0
            if kind == _SDF_SPHERE:
                d = r - colliders[c, 7]
            else:
                d = colliders[c, 7] - r
                nx = -nx
                ny = -ny
                nz = -nz
        if d < best:
            best = d
            bx = nx
            by = ny
            bz = nz
            bi = c
    return best, bx, by, bz, bi


@njit(cache=True, inline="always")
def _sdf_hessian(colliders, c, x, y, z, nx, ny, nz):
    """Hessian of collider ``c``'s SDF (= gradient of its unit normal), as 6 entries."""
    kind = np.int64(colliders[c, 0])
    if kind == _SDF_PLANE or c < 0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    rx = x - colliders[c, 1]
    ry = y - colliders[c, 2]
    rz = z - colliders[c, 3]
    r = math.sqrt(rx * rx + ry * ry + rz * rz)
    if r <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    s = 1.0 / r if kind == _SDF_SPHERE else -1.0 / r
    return (s * (1.0 - nx * nx), s * (1.0 - ny * ny), s * (1.0 - nz * nz),
            -s * nx * ny, -s * nx * nz, -s * ny * nz)


@dataclass(frozen=True)
class PlaneSDF:
    """Half-space collider: solid where ``(x - point) . normal < 0``.

    Parameters
    ----------
    point : sequence of 3 float
        A point on the plane (m).
    normal : sequence of 3 float
        Normal pointing out of the solid (into the free space); normalised here.
    """

    point: tuple = (0.0, 0.0, 0.0)
    normal: tuple = (0.0, 0.0, 1.0)

    def __post_init__(self):
        point = check_finite_vector("point", self.point, 3)
        normal = check_finite_vector("normal", self.normal, 3)
        length = float(np.linalg.norm(normal))
        if length == 0.0:
            raise ValueError("normal must be a non-zero vector")
        object.__setattr__(self, "point", tuple(point.tolist()))
        object.__setattr__(self, "normal", tuple((normal / length).tolist()))

    def pack(self) -> np.ndarray:
        """The collider as one row ``[kind, point, normal, 0]`` (8,) for the kernels."""
        return np.array([_SDF_PLANE, *self.point, *self.normal, 0.0])


@dataclass(frozen=True)
class _BallSDF:
    """Centre and radius of a spherical collider, validated once for both sides of a ball."""

    center: tuple = (0.0, 0.0, 0.0)
    radius: float = 1.0

    def __post_init__(self):
        center = check_finite_vector("center", self.center, 3)
        radius = check_finite("radius", self.radius, 0.0, math.inf, low_inclusive=False)
        object.__setattr__(self, "center", tuple(center.tolist()))
        object.__setattr__(self, "radius", radius)


@dataclass(frozen=True)
class SphereSDF(_BallSDF):
    """Solid ball collider: ``d = |x - center| - radius``.

    Parameters
    ----------
    center : sequence of 3 float
        Centre (m).
    radius : float
        Radius (m), > 0.
    """

    def pack(self) -> np.ndarray:
        """The collider as one row ``[kind, center, 0, 0, 0, radius]`` (8,)."""
        return np.array([_SDF_SPHERE, *self.center, 0.0, 0.0, 0.0, self.radius])


@dataclass(frozen=True)
class InsideSphereSDF(_BallSDF):
    """Spherical container: free inside the ball, ``d = radius - |x - center|``.

    Parameters
    ----------
    center : sequence of 3 float
        Centre (m).
    radius : float
        Radius (m), > 0.
    """

    def pack(self) -> np.ndarray:
        """The collider as one row ``[kind, center, 0, 0, 0, radius]`` (8,)."""
        return np.array([_SDF_INSIDE_SPHERE, *self.center, 0.0, 0.0, 0.0, self.radius])


_SDF_TYPES = (PlaneSDF, SphereSDF, InsideSphereSDF)


def _is_colliders_object(obj) -> bool:
    return all(hasattr(obj, name) for name in ("planes", "spheres", "boxes"))


def _rows_from_colliders_object(obj) -> list:
    """Rows for the planes and spheres of a :class:`filters.elastic.contact.Colliders`."""
    planes = np.asarray(obj.planes, dtype=np.float64).reshape(-1, 6)
    spheres = np.asarray(obj.spheres, dtype=np.float64).reshape(-1, 7)
    boxes = np.asarray(obj.boxes, dtype=np.float64).reshape(-1, 9)
    if boxes.shape[0]:
        raise ValueError(
            "colliders: boxes are not supported here (their signed distance has no continuous "
            "Hessian for the curl-noise ramp); use planes and spheres")
    rows = []
    for n0, n1, n2, offset, *_ in planes:  # n . x = offset, solid where n . x < offset
        rows.append(PlaneSDF((n0 * offset, n1 * offset, n2 * offset), (n0, n1, n2)).pack())
    for c0, c1, c2, radius, side, *_ in spheres:
        kind = SphereSDF if side > 0 else InsideSphereSDF
        rows.append(kind((c0, c1, c2), radius).pack())
    return rows


def pack_colliders(colliders) -> np.ndarray:
    """Pack collider primitives into the ``(C, 8) float64`` array the kernels read.

    Parameters
    ----------
    colliders : sequence, array or filters.elastic.contact.Colliders
        PlaneSDF, SphereSDF or InsideSphereSDF objects, or a
        :class:`filters.elastic.contact.Colliders` (its planes and spheres; anything with ``planes``
        (P, 6), ``spheres`` (S, 7) and ``boxes`` (B, 9) arrays in that module's layout), or a
        sequence mixing both, or an already packed ``(C, 8)`` array.  Boxes are refused: their
        signed distance has no continuous Hessian, which the curl-noise ramp differentiates.

    Returns
    -------
    (C, 8) float64 array, read-only
    """
    if isinstance(colliders, np.ndarray):
        if colliders.ndim != 2 or colliders.shape[1] != 8:
            raise ValueError(f"colliders array must have shape (C, 8), got {colliders.shape}")
        packed = np.ascontiguousarray(colliders, dtype=np.float64).copy()
    else:
        if _is_colliders_object(colliders):
            colliders = (colliders,)
        rows = []
        for i, c in enumerate(colliders):
            if isinstance(c, _SDF_TYPES):
                rows.append(c.pack())
            elif _is_colliders_object(c):
                rows.extend(_rows_from_colliders_object(c))
            else:
                raise TypeError(
                    f"colliders[{i}] must be a PlaneSDF, SphereSDF, InsideSphereSDF or a "
                    f"filters.elastic.contact.Colliders, got {type(c).__name__}")
        packed = np.array(rows, dtype=np.float64).reshape(-1, 8)
    packed.setflags(write=False)
    return packed


@njit(cache=True)
def _sdf_many(colliders, pts, d_out, n_out):
    for i in range(pts.shape[0]):
        d, nx, ny, nz, _ = sdf_point(colliders, pts[i, 0], pts[i, 1], pts[i, 2])
        d_out[i] = d
        n_out[i, 0] = nx
        n_out[i, 1] = ny
        n_out[i, 2] = nz


def signed_distance(points, colliders) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance (m) to the union of ``colliders`` and the nearest one's outward normal.

    Parameters
    ----------
    points : (N, 3) array_like
        Query points (m).
    colliders : sequence of SDF primitives or (C, 8) packed array

    Returns
    -------
    d : (N,) float64
        Signed distance (m), negative inside a solid; ``inf`` with no collider.
    normals : (N, 3) float64
        Unit normals (gradient of ``d``).
    """
    pts = check_points("points", points)
    packed = pack_colliders(colliders)
    d = np.empty(pts.shape[0])
    n = np.empty((pts.shape[0], 3))
    _sdf_many(packed, pts, d, n)
    return d, n


# ---------------------------------------------------------------------------------------------
# Curl noise (Bridson, Hourihan & Nordenstam 2007)
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _ramp(r):
    """Bridson et al.'s smooth ramp: 15/8 r - 10/8 r^3 + 3/8 r^5 on (-1, 1), sign(r) outside.

    Returns the ramp and its derivative.
    """
    if r >= 1.0:
        return 1.0, 0.0
    if r <= -1.0:
        return -1.0, 0.0
    r2 = r * r
    return r * (1.875 - r2 * (1.25 - 0.375 * r2)), 1.875 * (1.0 - r2) * (1.0 - r2)


@njit(cache=True, inline="always")
def _curl_from_potentials(colliders, x, y, z, ramp_distance, bx, by, bz, p0, p0x, p0y, p0z,
                          p1, p1x, p1y, p1z, p2, p2x, p2y, p2z):
    """Velocity from the scaled noise potentials and their gradients: base flow, ramp, curl."""
    if bx != 0.0 or by != 0.0 or bz != 0.0:
        # potential of the uniform flow b: psi = (b x x) / 2, curl psi = b
        p0 += 0.5 * (by * z - bz * y)
        p0y -= 0.5 * bz
        p0z += 0.5 * by
        p1 += 0.5 * (bz * x - bx * z)
        p1x += 0.5 * bz
        p1z -= 0.5 * bx
        p2 += 0.5 * (bx * y - by * x)
        p2x -= 0.5 * by
        p2y += 0.5 * bx
    if ramp_distance > 0.0 and colliders.shape[0] > 0:
        d, nx, ny, nz, c = sdf_point(colliders, x, y, z)
        if d < ramp_distance:
            a, da = _ramp(d / ramp_distance)
            da /= ramp_distance
            hxx, hyy, hzz, hxy, hxz, hyz = _sdf_hessian(colliders, c, x, y, z, nx, ny, nz)
            q = nx * p0 + ny * p1 + nz * p2
            # dq/dx_j = sum_k H_kj psi_k + n_k dpsi_k/dx_j
            qx = hxx * p0 + hxy * p1 + hxz * p2 + nx * p0x + ny * p1x + nz * p2x
            qy = hxy * p0 + hyy * p1 + hyz * p2 + nx * p0y + ny * p1y + nz * p2y
            qz = hxz * p0 + hyz * p1 + hzz * p2 + nx * p0z + ny * p1z + nz * p2z
            b = 1.0 - a
            # d psi'_i / d x_j = da n_j psi_i + a dpsi_i/dx_j - da n_j n_i q
            #                    + (1 - a) (H_ij q + n_i dq/dx_j); only the off-diagonal
            # entries the curl needs are formed.
            d2y = da * ny * p2 + a * p2y - da * ny * nz * q + b * (hyz * q + nz * qy)
            d1z = da * nz * p1 + a * p1z - da * nz * ny * q + b * (hyz * q + ny * qz)
            d0z = da * nz * p0 + a * p0z - da * nz * nx * q + b * (hxz * q + nx * qz)
            d2x = da * nx * p2 + a * p2x - da * nx * nz * q + b * (hxz * q + nz * qx)
            d1x = da * nx * p1 + a * p1x - da * nx * ny * q + b * (hxy * q + ny * qx)
            d0y = da * ny * p0 + a * p0y - da * ny * nx * q + b * (hxy * q + nx * qy)
            return d2y - d1z, d0z - d2x, d1x - d0y
    return p2y - p1z, p0z - p2x, p1x - p0y


@njit(cache=True)
def curl_point(tables, colliders, x, y, z, t, amplitude, frequency, octaves, lacunarity, gain,
               time_scale, ramp_distance, bx, by, bz):
    """Curl-noise velocity (m/s) at one point.

    ``psi = (amplitude / frequency) * (N0, N1, N2) + (b x x) / 2`` with three fBm potentials from
    the first three rows of ``tables`` and the potential of the uniform base flow
    ``b = (bx, by, bz)`` (m/s); near colliders (when ``ramp_distance > 0`` and ``colliders`` has
    rows) the potential is ramped as in Bridson et al. (2007) so that the normal velocity
    vanishes on the surfaces (the base flow goes around them too).  Returns (vx, vy, vz).
    """
    s = t * time_scale
    p0, p0x, p0y, p0z = fbm_value_grad(tables[0], x, y, z, frequency, octaves, lacunarity, gain,
                                       s * _DRIFT[0, 0], s * _DRIFT[0, 1], s * _DRIFT[0, 2], False)
    p1, p1x, p1y, p1z = fbm_value_grad(tables[1], x, y, z, frequency, octaves, lacunarity, gain,
                                       s * _DRIFT[1, 0], s * _DRIFT[1, 1], s * _DRIFT[1, 2], False)
    p2, p2x, p2y, p2z = fbm_value_grad(tables[2], x, y, z, frequency, octaves, lacunarity, gain,
                                       s * _DRIFT[2, 0], s * _DRIFT[2, 1], s * _DRIFT[2, 2], False)
    scale = amplitude / frequency
    p0 *= scale
    p0x *= scale
    p0y *= scale
    p0z *= scale
    p1 *= scale
    p1x *= scale
    p1y *= scale
    p1z *= scale
    p2 *= scale
    p2x *= scale
    p2y *= scale
    p2z *= scale
    return _curl_from_potentials(colliders, x, y, z, ramp_distance, bx, by, bz, p0, p0x, p0y,
                                 p0z, p1, p1x, p1y, p1z, p2, p2x, p2y, p2z)


@njit(cache=True)
def curl_jacobian_point(tables, colliders, x, y, z, t, amplitude, frequency, octaves, lacunarity,
                        gain, time_scale, ramp_distance, bx, by, bz):
    """Velocity (3,) and its Jacobian ``J[i, j] = dv_i/dx_j`` (3, 3) of curl noise at one point.

    Analytic from the potentials' Hessians away from colliders; inside a collider's ramp band
    the Jacobian is the central difference of the analytic velocity (step ``1e-5 / frequency``).
    """
    J = np.empty((3, 3))
    vel = np.empty(3)
    near = False
    if ramp_distance > 0.0 and colliders.shape[0] > 0:
        d, _, _, _, _ = sdf_point(colliders, x, y, z)
        near = d < ramp_distance * (1.0 + 1e-3) + 2e-5 / frequency
    if near:
        vel[0], vel[1], vel[2] = curl_point(tables, colliders, x, y, z, t, amplitude, frequency,
                                            octaves, lacunarity, gain, time_scale, ramp_distance,
                                            bx, by, bz)
        h = 1e-5 / frequency
        for j in range(3):
            ex = h if j == 0 else 0.0
            ey = h if j == 1 else 0.0
            ez = h if j == 2 else 0.0
            a0, a1, a2 = curl_point(tables, colliders, x + ex, y + ey, z + ez, t, amplitude,
                                    frequency, octaves, lacunarity, gain, time_scale,
                                    ramp_distance, bx, by, bz)
            b0, b1, b2 = curl_point(tables, colliders, x - ex, y - ey, z - ez, t, amplitude,
                                    frequency, octaves, lacunarity, gain, time_scale,
                                    ramp_distance, bx, by, bz)
            J[0, j] = (a0 - b0) / (2.0 * h)
            J[1, j] = (a1 - b1) / (2.0 * h)
            J[2, j] = (a2 - b2) / (2.0 * h)
        return vel, J
    s = t * time_scale
    H = np.empty((3, 10))
    for q in range(3):
        r = fbm_value_grad_hess(tables[q], x, y, z, frequency, octaves, lacunarity, gain,
                                s * _DRIFT[q, 0], s * _DRIFT[q, 1], s * _DRIFT[q, 2])
        for m in range(10):
            H[q, m] = r[m]
    scale = amplitude / frequency
    # gradient entries 1..3, Hessian entries: xx 4, yy 5, zz 6, xy 7, xz 8, yz 9
    vel[0] = scale * (H[2, 2] - H[1, 3]) + bx
    vel[1] = scale * (H[0, 3] - H[2, 1]) + by
    vel[2] = scale * (H[1, 1] - H[0, 2]) + bz
    # v0 = d psi2/dy - d psi1/dz
    J[0, 0] = scale * (H[2, 7] - H[1, 8])
    J[0, 1] = scale * (H[2, 5] - H[1, 9])
    J[0, 2] = scale * (H[2, 9] - H[1, 6])
    # v1 = d psi0/dz - d psi2/dx
    J[1, 0] = scale * (H[0, 8] - H[2, 4])
    J[1, 1] = scale * (H[0, 9] - H[2, 7])
    J[1, 2] = scale * (H[0, 6] - H[2, 8])
    # v2 = d psi1/dx - d psi0/dy
    J[2, 0] = scale * (H[1, 4] - H[0, 7])
    J[2, 1] = scale * (H[1, 7] - H[0, 5])
    J[2, 2] = scale * (H[1, 8] - H[0, 9])
    return vel, J


# ---------------------------------------------------------------------------------------------
# Array kernels
# ---------------------------------------------------------------------------------------------
@njit(parallel=True, cache=True)
def _perlin_many(p, pts, frequency, out):
    flat = pts.reshape(pts.shape[0] * 3)  # flat indexing vectorises better
    for i in prange(pts.shape[0]):
        out[i] = perlin_value(p, frequency * flat[3 * i], frequency * flat[3 * i + 1],
                              frequency * flat[3 * i + 2])


@njit(parallel=True, cache=True)
def _perlin_grad_many(p, pts, frequency, out, gx_out, gy_out, gz_out):
    # Separate contiguous gradient outputs: with (N, 3) strided stores LLVM does not vectorise
    # this loop, with these it does (about 2x faster); _interleave3 then builds the (N, 3).
    flat = pts.reshape(pts.shape[0] * 3)  # flat indexing vectorises better
    for i in prange(pts.shape[0]):
        n, gx, gy, gz = perlin_value_grad(p, frequency * flat[3 * i], frequency * flat[3 * i + 1],
                                          frequency * flat[3 * i + 2])
        out[i] = n
        gx_out[i] = frequency * gx
        gy_out[i] = frequency * gy
        gz_out[i] = frequency * gz


@njit(cache=True)
def _interleave3(a, b, c, out):
    for i in range(a.shape[0]):
        out[i, 0] = a[i]
        out[i, 1] = b[i]
        out[i, 2] = c[i]


@njit(parallel=True, cache=True)
def _perlin_hess_many(p, pts, frequency, out, grad, hess):
    f2 = frequency * frequency
    flat = pts.reshape(pts.shape[0] * 3)  # flat indexing vectorises better
    for i in prange(pts.shape[0]):
        r = perlin_value_grad_hess(p, frequency * flat[3 * i], frequency * flat[3 * i + 1],
                                   frequency * flat[3 * i + 2])
        out[i] = r[0]
        grad[i, 0] = frequency * r[1]
        grad[i, 1] = frequency * r[2]
        grad[i, 2] = frequency * r[3]
        hess[i, 0, 0] = f2 * r[4]
        hess[i, 1, 1] = f2 * r[5]
        hess[i, 2, 2] = f2 * r[6]
        hess[i, 0, 1] = hess[i, 1, 0] = f2 * r[7]
        hess[i, 0, 2] = hess[i, 2, 0] = f2 * r[8]
        hess[i, 1, 2] = hess[i, 2, 1] = f2 * r[9]


@njit(parallel=True, cache=True)
def _octave_accumulate(p, flat, start, count, f, amp, sx, sy, sz, ox, oy, oz, first, turbulence,
                       v, gx, gy, gz):
    """Add one octave ``amp * N(f x + shift + o)`` and its gradient for points
    ``start .. start + count`` into contiguous accumulators (the loop vectorises), with the
    same operations, hence the same bits, as :func:`fbm_value_grad`."""
    a1 = amp * f
    for j in prange(count):
        i = start + j
        n, nx, ny, nz = perlin_value_grad(p, f * flat[3 * i] + sx + ox,
                                          f * flat[3 * i + 1] + sy + oy,
                                          f * flat[3 * i + 2] + sz + oz)
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
        i = start + j
        n = perlin_value(p, f * flat[3 * i] + sx + ox, f * flat[3 * i + 1] + sy + oy,
                         f * flat[3 * i + 2] + sz + oz)
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
    for start in range(0, n, _CURL_BLOCK):
        count = min(_CURL_BLOCK, n - start)
        stop = start + count
        f = frequency
        amp = 1.0
        for k in range(octaves):
            sx, sy, sz = _OCTAVE_SHIFT[k]
            if gradient:
                _octave_accumulate(table, flat, start, count, f, amp, sx, sy, sz, ox, oy, oz,
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
    _interleave3(soa[0], soa[1], soa[2], grad)
    return out, grad


@njit(parallel=True, cache=True)
def _curl_combine(colliders, flat, start, count, acc, scale, ramp_distance, bx, by, bz, out):
    """Velocities of points ``start .. start + count`` from accumulated potentials (12, B)."""
    for j in prange(count):
        i = start + j
        out[i, 0], out[i, 1], out[i, 2] = _curl_from_potentials(
            colliders, flat[3 * i], flat[3 * i + 1], flat[3 * i + 2], ramp_distance, bx, by, bz,
            acc[0, j] * scale, acc[1, j] * scale, acc[2, j] * scale, acc[3, j] * scale,
            acc[4, j] * scale, acc[5, j] * scale, acc[6, j] * scale, acc[7, j] * scale,
            acc[8, j] * scale, acc[9, j] * scale, acc[10, j] * scale, acc[11, j] * scale)


#: Points per block of the vectorised curl-noise evaluation (accumulators stay in cache).
_CURL_BLOCK = 32768


def _curl_array(tables, colliders, pts, t, amplitude, frequency, octaves, lacunarity, gain,
                time_scale, ramp_distance, bx, by, bz, out):
    """Curl noise on (N, 3) points, octave by octave over blocks so that the inner loops
    vectorise; bitwise equal to :func:`curl_point` at every point."""
    n = pts.shape[0]
    flat = pts.reshape(-1)
    block = min(_CURL_BLOCK, max(n, 1))
    acc = np.empty((12, block))
    s = t * time_scale
    scale = amplitude / frequency
    for start in range(0, n, block):
        count = min(block, n - start)
        for q in range(3):
            ox, oy, oz = s * _DRIFT[q, 0], s * _DRIFT[q, 1], s * _DRIFT[q, 2]
            f = frequency
            amp = 1.0
            for k in range(octaves):
                _octave_accumulate(tables[q], flat, start, count, f, amp, _OCTAVE_SHIFT[k, 0],
                                   _OCTAVE_SHIFT[k, 1], _OCTAVE_SHIFT[k, 2], ox, oy, oz, k == 0,
                                   False, acc[4 * q], acc[4 * q + 1], acc[4 * q + 2],
                                   acc[4 * q + 3])
                amp *= gain
                f *= lacunarity
        _curl_combine(colliders, flat, start, count, acc, scale, ramp_distance, bx, by, bz, out)


@njit(parallel=True, cache=True)
def _curl_jac_many(tables, colliders, pts, t, amplitude, frequency, octaves, lacunarity, gain,
                   time_scale, ramp_distance, bx, by, bz, vel, jac):
    flat = pts.reshape(pts.shape[0] * 3)  # flat indexing vectorises better
    for i in prange(pts.shape[0]):
        v, J = curl_jacobian_point(tables, colliders, flat[3 * i], flat[3 * i + 1],
                                   flat[3 * i + 2], t,
                                   amplitude, frequency, octaves, lacunarity, gain, time_scale,
                                   ramp_distance, bx, by, bz)
        for a in range(3):
            vel[i, a] = v[a]
            for b in range(3):
                jac[i, a, b] = J[a, b]


@njit(cache=True)
def _potential_many(tables, colliders, pts, t, amplitude, frequency, octaves, lacunarity, gain,
                    time_scale, ramp_distance, bx, by, bz, out):
    scale = amplitude / frequency
    s = t * time_scale
    flat = pts.reshape(pts.shape[0] * 3)  # flat indexing vectorises better
    for i in range(pts.shape[0]):
        x = flat[3 * i]
        y = flat[3 * i + 1]
        z = flat[3 * i + 2]
        psi = np.empty(3)
        for q in range(3):
            psi[q] = fbm_value(tables[q], x, y, z, frequency, octaves, lacunarity, gain,
                               s * _DRIFT[q, 0], s * _DRIFT[q, 1], s * _DRIFT[q, 2], False)
            psi[q] *= scale
        psi[0] += 0.5 * (by * z - bz * y)
        psi[1] += 0.5 * (bz * x - bx * z)
        psi[2] += 0.5 * (bx * y - by * x)
        if ramp_distance > 0.0 and colliders.shape[0] > 0:
            d, nx, ny, nz, _ = sdf_point(colliders, x, y, z)
            a, _ = _ramp(d / ramp_distance)
            proj = nx * psi[0] + ny * psi[1] + nz * psi[2]
            psi[0] = a * psi[0] + (1.0 - a) * nx * proj
            psi[1] = a * psi[1] + (1.0 - a) * ny * proj
            psi[2] = a * psi[2] + (1.0 - a) * nz * proj
        for k in range(3):
            out[i, k] = psi[k]


# ---------------------------------------------------------------------------------------------
# Public array API
# ---------------------------------------------------------------------------------------------
def _check_frequency(frequency) -> float:
    return check_finite("frequency", frequency, 0.0, math.inf, low_inclusive=False)


def _points_or_scalars(x, y, z):
    """Return ((N, 3) points, scalar?) from either an (N, 3) array or three scalars."""
    if y is None and z is None:
        return check_points("points", x), False
    if y is None or z is None:
        raise TypeError("give either points as an (N, 3) array or three scalars x, y, z")
    coords = []
    for name, value in (("x", x), ("y", y), ("z", z)):
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
        if not math.isfinite(value):
            raise ValueError(f"{name} must be finite, got {value!r}")
        coords.append(float(value))
    return np.array([coords], dtype=np.float64), True


def perlin3(x, y=None, z=None, *, seed: int = 0, frequency: float = 1.0):
    """Perlin's improved noise (Perlin 2002), exact to his reference in float64.

    Parameters
    ----------
    x : (N, 3) array_like or float
        Points (m), or the x coordinate when ``y`` and ``z`` are given.
    y, z : float, optional
        The other coordinates of a single point.
    seed : int
        0 for Perlin's permutation (the reference); others shuffle it (:func:`permutation_table`).
    frequency : float
        Lattice cells per metre (> 0): noise is evaluated at ``frequency * x``.

    Returns
    -------
    float or (N,) float64 array
        Noise values, in about [-1, 1]; exactly 0 at every integer lattice point.

    Notes
    -----
    Defined for every finite input: the lattice coordinate wraps as in the reference,
    ``floor(x) mod 256``, computed exactly for any float64 (beyond ``|x| = 2**52`` floats have
    no fractional part and beyond ``2**60`` they are multiples of 256, so the noise there is
    that at ``x mod 256``, an integer lattice coordinate). The reference's Java ``(int)`` cast
    agrees for ``|floor(x)| < 2**31`` and saturates beyond it; we keep the exact wrap rather
    than copy the saturation, so the noise stays periodic with period 256 for all inputs.
    NaN or infinite coordinates raise ValueError naming the argument.

    Examples
    --------
    >>> perlin3(3.14, 42, 7)
    0.13691995878400012
    """
    pts, scalar = _points_or_scalars(x, y, z)
    frequency = _check_frequency(frequency)
    table = _kernel_table(seed)
    out = np.empty(pts.shape[0])
    _perlin_many(table, pts, frequency, out)
    return float(out[0]) if scalar else out


def perlin3_gradient(points, *, seed: int = 0, frequency: float = 1.0):
    """Improved noise and its analytic gradient.

    Parameters
    ----------
    points : (N, 3) array_like
        Points (m).
    seed, frequency : see :func:`perlin3`.

    Returns
    -------
    values : (N,) float64
        Equal to :func:`perlin3` to the bit.
    gradients : (N, 3) float64
        d noise / d x (1/m), including the factor ``frequency``.
    """
    pts = check_points("points", points)
    frequency = _check_frequency(frequency)
    table = _kernel_table(seed)
    n = pts.shape[0]
    out = np.empty(n)
    soa = np.empty((3, n))
    _perlin_grad_many(table, pts, frequency, out, soa[0], soa[1], soa[2])
    grad = np.empty((n, 3))
    _interleave3(soa[0], soa[1], soa[2], grad)
    return out, grad


def perlin3_hessian(points, *, seed: int = 0, frequency: float = 1.0):
    """Improved noise with its analytic gradient and Hessian.

    Parameters
    ----------
    points : (N, 3) array_like
        Points (m).
    seed, frequency : see :func:`perlin3`.

    Returns
    -------
    values : (N,) float64
    gradients : (N, 3) float64
        First derivatives (1/m).
    hessians : (N, 3, 3) float64
        Second derivatives (1/m^2), symmetric; continuous across cell faces (the noise is C2).
    """
    pts = check_points("points", points)
    frequency = _check_frequency(frequency)
    table = _kernel_table(seed)
    n = pts.shape[0]
    out = np.empty(n)
    grad = np.empty((n, 3))
    hess = np.empty((n, 3, 3))
    _perlin_hess_many(table, pts, frequency, out, grad, hess)
    return out, grad, hess


def _check_fractal(octaves, lacunarity, gain, frequency=1.0):
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


def fbm3(points, *, octaves: int = 4, lacunarity: float = 2.0, gain: float = 0.5, seed: int = 0,
         frequency: float = 1.0, time: float = 0.0, time_scale: float = 0.0,
         turbulence: bool = False, gradient: bool = False):
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
    frequency = _check_frequency(frequency)
    octaves, lacunarity, gain = _check_fractal(octaves, lacunarity, gain, frequency)
    time = check_finite("time", time)
    time_scale = check_finite("time_scale", time_scale)
    table = _kernel_table(seed)
    s = time * time_scale
    ox, oy, oz = (s * _DRIFT[0]).tolist()
    return _fbm_array(table, pts, frequency, octaves, lacunarity, gain, ox, oy, oz,
                      bool(turbulence), bool(gradient))


def turbulence3(points, **kwargs):
    """Perlin's turbulence ``sum_k gain**k |N(...)|``: :func:`fbm3` with ``turbulence=True``."""
    return fbm3(points, turbulence=True, **kwargs)


@dataclass(frozen=True)
class CurlNoise:
    """Divergence-free curl-noise velocity field (Bridson, Hourihan & Nordenstam 2007).

    ``v = curl psi``, ``psi = (amplitude / frequency) (N0, N1, N2)`` where ``N0..N2`` are fBm of
    improved noise with the permutations of seeds ``seed``, ``seed + 1``, ``seed + 2``
    (decorrelated potentials).  With ``colliders`` and ``ramp_distance > 0`` the potential is
    modulated within ``ramp_distance`` of the nearest collider surface,
    ``psi' = a psi + (1 - a) n (n . psi)``, ``a = ramp(d / ramp_distance)``, which makes the
    velocity tangent to the surface there (the paper's Section 3.2); the field stays exactly
    divergence-free because it is still a curl.

    Parameters
    ----------
    amplitude : float
        Velocity scale (m/s), >= 0; typical speeds are ``~ amplitude``.
    frequency : float
        Lattice cells per metre of the first octave, > 0 (eddies ~ ``1 / frequency`` m).
    octaves, lacunarity, gain : int, float, float
        Fractal sum of the potentials (see :func:`fbm3`).
    seed : int
        Seed of the first potential.
    time_scale : float
        Drift of the potentials (lattice cells per second); 0 for a steady field.
    colliders : tuple of PlaneSDF / SphereSDF / InsideSphereSDF, or filters.elastic.contact.Colliders
        Surfaces the flow must not cross (see :func:`pack_colliders`).
    ramp_distance : float
        Width of the boundary ramp (m), >= 0; 0 disables the ramp.
    base_velocity : sequence of 3 float
        A uniform flow ``b`` (m/s) added through its potential ``(b x x) / 2`` before the ramp,
        so that it too goes around the colliders (Bridson et al. 2007).
    """

    amplitude: float = 1.0
    frequency: float = 1.0
    octaves: int = 1
    lacunarity: float = 2.0
    gain: float = 0.5
    seed: int = 0
    time_scale: float = 0.0
    colliders: tuple = ()
    ramp_distance: float = 0.0
    base_velocity: tuple = (0.0, 0.0, 0.0)
    _tables: np.ndarray = field(init=False, repr=False, compare=False)
    _packed: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        check_finite("amplitude", self.amplitude, 0.0, math.inf)
        _check_frequency(self.frequency)
        _check_fractal(self.octaves, self.lacunarity, self.gain, self.frequency)
        check_int("seed", self.seed, -(1 << 63), (1 << 64) - 3)
        check_finite("time_scale", self.time_scale)
        check_finite("ramp_distance", self.ramp_distance, 0.0, math.inf)
        object.__setattr__(self, "base_velocity", tuple(
            check_finite_vector("base_velocity", self.base_velocity, 3).tolist()))
        colliders = self.colliders
        colliders = (colliders,) if _is_colliders_object(colliders) else tuple(colliders)
        packed = pack_colliders(colliders)
        for name in ("amplitude", "frequency", "lacunarity", "gain", "time_scale",
                     "ramp_distance"):
            object.__setattr__(self, name, float(getattr(self, name)))
        object.__setattr__(self, "octaves", int(self.octaves))
        object.__setattr__(self, "colliders", colliders)
        tables = _tables(int(self.seed), 3)
        tables.setflags(write=False)
        object.__setattr__(self, "_tables", tables)
        object.__setattr__(self, "_packed", packed)

    @property
    def tables(self) -> np.ndarray:
        """(3, 512) int32 permutation tables of the three potentials."""
        return self._tables

    @property
    def packed_colliders(self) -> np.ndarray:
        """(C, 8) float64 collider rows (see :func:`pack_colliders`)."""
        return self._packed

    def _args(self, t):
        return (self.amplitude, self.frequency, self.octaves, self.lacunarity, self.gain,
                self.time_scale, self.ramp_distance, *self.base_velocity)

    def velocity(self, points, t: float = 0.0) -> np.ndarray:
        """Velocity (m/s) at ``points`` (N, 3) (m) and time ``t`` (s); returns (N, 3)."""
        pts = check_points("points", points)
        t = check_finite("t", t)
        out = np.empty((pts.shape[0], 3))
        _curl_array(self._tables, self._packed, pts, t, *self._args(t), out)
        return out

    def evaluate(self, points, t: float = 0.0, velocities=None) -> np.ndarray:
        """Same as :meth:`velocity` (the field protocol of :mod:`filters.fields`)."""
        return self.velocity(points, t)

    def jacobian(self, points, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Velocity (N, 3) (m/s) and its Jacobian ``dv_i/dx_j`` (N, 3, 3) (1/s)."""
        pts = check_points("points", points)
        t = check_finite("t", t)
        n = pts.shape[0]
        vel = np.empty((n, 3))
        jac = np.empty((n, 3, 3))
        _curl_jac_many(self._tables, self._packed, pts, t, *self._args(t), vel, jac)
        return vel, jac

    def potential(self, points, t: float = 0.0) -> np.ndarray:
        """The (ramped) vector potential psi (m^2/s) at ``points``; returns (N, 3)."""
        pts = check_points("points", points)
        t = check_finite("t", t)
        out = np.empty((pts.shape[0], 3))
        _potential_many(self._tables, self._packed, pts, t, *self._args(t), out)
        return out


def curl_noise(points, t: float = 0.0, **parameters) -> np.ndarray:
    """Curl-noise velocity (m/s) at ``points`` (N, 3) and time ``t`` (s).

    A shortcut for ``CurlNoise(**parameters).velocity(points, t)``; see :class:`CurlNoise` for the
    parameters (amplitude, frequency, octaves, lacunarity, gain, seed, time_scale, colliders,
    ramp_distance, base_velocity).
    """
    return CurlNoise(**parameters).velocity(points, t)


def curl_noise_jacobian(points, t: float = 0.0, **parameters):
    """Curl-noise velocity (N, 3) and Jacobian (N, 3, 3); see :meth:`CurlNoise.jacobian`."""
    return CurlNoise(**parameters).jacobian(points, t)
