"""Perlin's improved noise and its derivatives, bit-exact to his reference, in Numba.

* :func:`perlin3` - Perlin's *improved noise* (Perlin 2002, "Improving Noise", SIGGRAPH), bit-exact
  to his reference Java implementation in float64: his published permutation, the quintic fade
  ``6 t^5 - 15 t^4 + 10 t^3`` and his 16-entry gradient set (the 12 cube-edge directions with four
  repeated), evaluated with the reference's order of floating-point operations so that
  ``perlin3(3.14, 42, 7) == 0.13691995878400012`` exactly.
* :func:`perlin3_gradient` and :func:`perlin3_hessian` - analytic first and second derivatives
  (the noise is C2: the fade's first and second derivatives vanish at the lattice).
* :func:`permutation_table` - other seeds by a deterministic Fisher-Yates shuffle (SplitMix64,
  Steele, Lea & Flood 2014) of the reference permutation; seed 0 *is* the reference.

Every function takes ``frequency`` (1/m): noise is evaluated at ``frequency * x``, so one
lattice cell spans ``1 / frequency`` metres.

Domain
------
Every function is defined for all finite inputs and returns values in its documented range: the
lattice coordinate wraps as in the reference, ``floor(x) mod 256``, computed exactly for any
float64 (clamping to ``+-2**60`` first, where every float is a multiple of 256, so no value
changes; see ``_clamp_lattice``). Wrapping rather than refusing large coordinates because the
result is well defined there (noise is periodic with period 256 lattice cells) and a clamp costs
nothing measurable. NaN or infinite points and parameters raise ValueError naming the parameter
before any work.

Implementation notes
--------------------
The point kernels (:func:`perlin_value`, :func:`perlin_value_grad`,
:func:`perlin_value_grad_hess`) are ``@njit`` functions that other Numba kernels (fractal sums,
curl noise, fields) call directly. They take a *kernel table* (:func:`kernel_table`): the doubled
permutation in the low 8 bits of each int32 entry and, above them, the gradient Perlin's
``grad`` would pick for that entry, so that a corner costs one lookup and no data-dependent
branch. The dot product with a gradient is formed as ``(gx x + gy y) + gz z`` with entries in
{0, +-1}, which rounds exactly like the reference's ``(+-u) + (+-v)``; the noise stays bit-exact.
The array functions loop over points in ``prange`` loops that LLVM vectorises (AVX2/AVX-512
gathers); outputs are written to contiguous arrays. :func:`perlin3`'s loop runs 8 doubles wide
where the CPU has AVX-512 (:func:`filters.noise.lattice.wide_vectors`), reads the points as
three interleaved streams and hashes through a table of entry pairs (``_pair_table``: 7 lookups
a point, not 14), ``grad`` as the reference's own choices made by selects: one thread makes
1.78x FastNoiseLite's rate, 1.03x before (``benchmarks/bench_noise.py``). No ``fastmath``: its
FMA contraction changes 78 % of the values (up to 2.4e-15) and gained nothing measurable.
Results equal the point kernels' and a transcription of the reference's to the bit (tested).
"""

from __future__ import annotations

import math
import numbers
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..validation import check_finite, check_int, check_points
from .lattice import clamp_lattice as _clamp_lattice
from .lattice import ddfade as _ddfade
from .lattice import dfade as _dfade
from .lattice import fade as _fade
from .lattice import grad as _grad
from .lattice import grad_select as _grad_select
from .lattice import gradient_vector as _gvec
from .lattice import lerp as _lerp
from .lattice import lerp_with_gradient as _lerp_d
from .lattice import wide_vectors as _wide_vectors

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = [
    "PERMUTATION",
    "GRADIENTS",
    "permutation_table",
    "kernel_table",
    "kernel_tables",
    "perlin_value",
    "perlin_value_grad",
    "perlin_value_grad_hess",
    "perlin3",
    "perlin3_gradient",
    "perlin3_hessian",
    "check_frequency",
    "interleave3",
]

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

GRADIENTS = np.array([
    [1, 1, 0], [-1, 1, 0], [1, -1, 0], [-1, -1, 0],
    [1, 0, 1], [-1, 0, 1], [1, 0, -1], [-1, 0, -1],
    [0, 1, 1], [0, -1, 1], [0, 1, -1], [0, -1, -1],
    [1, 1, 0], [0, -1, 1], [-1, 1, 0], [0, -1, -1],
], dtype=np.float64)



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


@lru_cache(maxsize=256)
def _pair_table(seed: int) -> np.ndarray:
    """The value loop's table: entry ``i`` holds entries ``i`` and ``i + 1``, (512,) int64.

    Each 32-bit half is ``p[j] | select(p[j] & 15) << 8`` (``select``: the reference's
    choices in ``grad``, see :func:`filters.noise.lattice.grad_select`), low half ``j = i``,
    high half ``j = i + 1`` (mod 512). Perlin's hash reads ``p[A]`` and ``p[A + 1]`` (and
    ``p[AA]``, ``p[AA + 1]``, ...) together: one 64-bit lookup serves both, 7 lookups a point
    instead of 14.
    """
    perm = _table(seed).astype(np.int64)
    h = perm & 15
    select = ((h >= 8) * 1 | (h < 4) * 2 | ((h == 12) | (h == 14)) * 4 | (h & 1) * 8
              | (h & 2) * 8)
    entry = perm | (select << 8)
    table = entry | (np.roll(entry, -1) << 32)
    table.setflags(write=False)
    return table


def kernel_table(seed: int) -> np.ndarray:
    """The kernels' (512,) int32 table of a seed (validated as in :func:`permutation_table`):
    the permutation in the low 8 bits, the gradient code above (see ``_hash_table``)."""
    seed = check_int("seed", seed, -(1 << 63), (1 << 64) - 1)
    return _hash_table(seed & ((1 << 64) - 1))


def kernel_tables(seed: int, count: int) -> np.ndarray:
    """``count`` decorrelated kernel tables for seeds ``seed, seed + 1, ...``: (count, 512).

    The potentials of curl noise use seeds ``seed``, ``seed + 1``, ``seed + 2``; seed 0's first
    table is the reference permutation, the others are shuffles.
    """
    return np.stack([_hash_table((seed + k) & ((1 << 64) - 1)) for k in range(count)])


# ---------------------------------------------------------------------------------------------
# Point kernels
# ---------------------------------------------------------------------------------------------
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


# ---------------------------------------------------------------------------------------------
# Array kernels and the public array API
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _perlin_value_pairs(q, x, y, z):
    """:func:`perlin_value` with a pair table ``q`` (``_pair_table``): 7 lookups instead of 14
    and the reference's ``grad`` as selects; the same operations on the same operands, so the
    same bits (tested against :func:`perlin_value` and a transcription of the reference)."""
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
    qx = q[X]  # p[X], p[X + 1]
    A = (qx & 255) + Y
    B = ((qx >> 32) & 255) + Y
    qa = q[A]  # p[A], p[A + 1]
    qb = q[B]
    AA = (qa & 255) + Z
    AB = ((qa >> 32) & 255) + Z
    BA = (qb & 255) + Z
    BB = ((qb >> 32) & 255) + Z
    haa = q[AA]  # p[AA] in the low half, p[AA + 1] in the high half
    hab = q[AB]
    hba = q[BA]
    hbb = q[BB]
    x1 = x - 1.0
    y1 = y - 1.0
    z1 = z - 1.0
    return _lerp(w, _lerp(v, _lerp(u, _grad_select(haa >> 8, x, y, z),
                                   _grad_select(hba >> 8, x1, y, z)),
                          _lerp(u, _grad_select(hab >> 8, x, y1, z),
                                _grad_select(hbb >> 8, x1, y1, z))),
                 _lerp(v, _lerp(u, _grad_select(haa >> 40, x, y, z1),
                                _grad_select(hba >> 40, x1, y, z1)),
                       _lerp(u, _grad_select(hab >> 40, x, y1, z1),
                             _grad_select(hbb >> 40, x1, y1, z1))))


@njit(parallel=True, cache=True)
def _perlin_many(q, pts, frequency, out):
    flat = pts.reshape(pts.shape[0] * 3)
    for i in prange(pts.shape[0]):
        _wide_vectors()  # 8 doubles a vector where the CPU has AVX-512
        # unsigned indices: no negative-index wrap, so LLVM sees three interleaved streams and
        # loads them with shuffles rather than gathers (8.8 -> 7.4 ms on 1M points)
        j = np.uint64(3 * i)
        out[i] = _perlin_value_pairs(q, frequency * flat[j], frequency * flat[j + np.uint64(1)],
                                     frequency * flat[j + np.uint64(2)])

@njit(parallel=True, cache=True)
def _perlin_grad_many(p, pts, frequency, out, gx_out, gy_out, gz_out):
    # Separate contiguous gradient outputs: with (N, 3) strided stores LLVM does not vectorise
    # this loop, with these it does (about 2x faster); _interleave3 then builds the (N, 3).
    flat = pts.reshape(pts.shape[0] * 3)
    for i in prange(pts.shape[0]):
        _wide_vectors()  # as in _perlin_many: 18.2 -> 11.6 ms on 1M points, one thread
        j = np.uint64(3 * i)
        n, gx, gy, gz = perlin_value_grad(p, frequency * flat[j],
                                          frequency * flat[j + np.uint64(1)],
                                          frequency * flat[j + np.uint64(2)])
        out[i] = n
        gx_out[i] = frequency * gx
        gy_out[i] = frequency * gy
        gz_out[i] = frequency * gz


@njit(cache=True)
def interleave3(a, b, c, out):
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


def check_frequency(frequency: float) -> float:
    """``frequency`` (1/m) as a finite float > 0, else ValueError naming it."""
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

def perlin3(x: ArrayLike, y: float | None = None, z: float | None = None, *, seed: int = 0,
            frequency: float = 1.0) -> NDArray[np.float64]:
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
    frequency = check_frequency(frequency)
    seed = check_int("seed", seed, -(1 << 63), (1 << 64) - 1)
    out = np.empty(pts.shape[0])
    _perlin_many(_pair_table(seed & ((1 << 64) - 1)), pts, frequency, out)
    return float(out[0]) if scalar else out

def perlin3_gradient(points: ArrayLike, *, seed: int = 0,
                     frequency: float = 1.0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
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
    frequency = check_frequency(frequency)
    table = kernel_table(seed)
    n = pts.shape[0]
    out = np.empty(n)
    soa = np.empty((3, n))
    _perlin_grad_many(table, pts, frequency, out, soa[0], soa[1], soa[2])
    grad = np.empty((n, 3))
    interleave3(soa[0], soa[1], soa[2], grad)
    return out, grad

def perlin3_hessian(points: ArrayLike, *, seed: int = 0,
                    frequency: float = 1.0) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                                     NDArray[np.float64]]:
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
    frequency = check_frequency(frequency)
    table = kernel_table(seed)
    n = pts.shape[0]
    out = np.empty(n)
    grad = np.empty((n, 3))
    hess = np.empty((n, 3, 3))
    _perlin_hess_many(table, pts, frequency, out, grad, hess)
    return out, grad, hess
