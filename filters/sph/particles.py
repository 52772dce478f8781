"""Particle-array kernels shared by the SPH solvers: re-ordering, list upkeep, time integration
and the containment checks (Numba, parallel where it helps, deterministic)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

__all__ = ["permute", "is_identity", "max_displacement2", "sort_rows", "integrate", "contain",
           "outside"]


@njit(parallel=True, cache=True, error_model="numpy")
def permute(x, v, ids, order, xo, vo, io):
    for k in prange(order.shape[0]):
        i = order[k]
        for c in range(3):
            xo[k, c] = x[i, c]
            vo[k, c] = v[i, c]
        io[k] = ids[i]


@njit(cache=True, error_model="numpy")
def is_identity(order):
    for k in range(order.shape[0]):
        if order[k] != k:
            return False
    return True


@njit(cache=True, error_model="numpy")
def max_displacement2(x, anchor):
    best = 0.0
    for i in range(x.shape[0]):
        dx = x[i, 0] - anchor[i, 0]
        dy = x[i, 1] - anchor[i, 1]
        dz = x[i, 2] - anchor[i, 2]
        best = max(best, dx * dx + dy * dy + dz * dz)
    return best


@njit(parallel=True, cache=True, error_model="numpy")
def sort_rows(tab, cnt):
    """Sort every row ``tab[i, :cnt[i]]`` ascending (insertion sort: rows are short)."""
    for i in prange(tab.shape[0]):
        for a in range(1, cnt[i]):
            v = tab[i, a]
            b = a - 1
            while b >= 0 and tab[i, b] > v:
                tab[i, b + 1] = tab[i, b]
                b -= 1
            tab[i, b + 1] = v


@njit(parallel=True, cache=True, error_model="numpy")
def integrate(x, v, a, dt):
    """Symplectic Euler; returns max ``|v|`` after the step."""
    n = x.shape[0]
    vmax = np.zeros(n)
    for i in prange(n):
        s = 0.0
        for c in range(3):
            v[i, c] += dt * a[i, c]
            s += v[i, c] * v[i, c]
        vmax[i] = s
    for i in prange(n):
        for c in range(3):
            x[i, c] += dt * v[i, c]
    return math.sqrt(vmax.max()) if n else 0.0


@njit(parallel=True, cache=True, error_model="numpy")
def contain(x, v, lo, hi):
    """Project particles outside the box [lo, hi] back onto it and zero the outward velocity
    component (an inelastic, frictionless wall); returns how many were corrected."""
    n = x.shape[0]
    hits = np.zeros(n, dtype=np.int64)
    for i in prange(n):
        for c in range(3):
            if x[i, c] < lo[c]:
                x[i, c] = lo[c]
                if v[i, c] < 0.0:
                    v[i, c] = 0.0
                hits[i] = 1
            elif x[i, c] > hi[c]:
                x[i, c] = hi[c]
                if v[i, c] > 0.0:
                    v[i, c] = 0.0
                hits[i] = 1
    return hits.sum()


@njit(parallel=True, cache=True, error_model="numpy")
def outside(x, lo, hi):
    """Index of a particle outside [lo, hi] (the smallest such index), or -1."""
    n = x.shape[0]
    bad = np.full(n, False)
    for i in prange(n):
        for c in range(3):
            if not (x[i, c] >= lo[c] and x[i, c] <= hi[c]):
                bad[i] = True
    for i in range(n):
        if bad[i]:
            return i
    return -1
