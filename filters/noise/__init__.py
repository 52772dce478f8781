"""Procedural noise: Perlin's improved noise (Perlin 2002), its derivatives, fractal sums and
curl noise (Bridson, Hourihan & Nordenstam 2007), in Numba."""

from .perlin import (
    PERMUTATION,
    GRADIENTS,
    permutation_table,
    perlin3,
    perlin3_gradient,
    perlin3_hessian,
    fbm3,
    turbulence3,
    curl_noise,
    curl_noise_jacobian,
    CurlNoise,
    PlaneSDF,
    SphereSDF,
    InsideSphereSDF,
    pack_colliders,
    signed_distance,
    MAX_OCTAVES,
    check_top_frequency,
)

__all__ = [
    'PERMUTATION', 'GRADIENTS', 'permutation_table', 'perlin3', 'perlin3_gradient', 'perlin3_hessian', 'fbm3', 'turbulence3', 'curl_noise', 'curl_noise_jacobian', 'CurlNoise', 'PlaneSDF', 'SphereSDF', 'InsideSphereSDF', 'pack_colliders', 'signed_distance', 'MAX_OCTAVES', 'check_top_frequency',
]
