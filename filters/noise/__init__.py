"""Procedural noise in Numba: Perlin's improved noise and its derivatives
(:mod:`filters.noise.perlin`), fractal sums (:mod:`filters.noise.fractal`), curl-noise kernels
(:mod:`filters.noise.curl`; the field is :class:`filters.fields.CurlNoise`) and per-particle
variation (:mod:`filters.noise.variation`)."""

from .fractal import MAX_OCTAVES, check_top_frequency, fbm3, turbulence3
from .perlin import (
    GRADIENTS,
    PERMUTATION,
    perlin3,
    perlin3_gradient,
    perlin3_hessian,
    permutation_table,
)
from .variation import noise_variation

__all__ = [
    "PERMUTATION",
    "GRADIENTS",
    "permutation_table",
    "perlin3",
    "perlin3_gradient",
    "perlin3_hessian",
    "fbm3",
    "turbulence3",
    "MAX_OCTAVES",
    "check_top_frequency",
    "noise_variation",
]
