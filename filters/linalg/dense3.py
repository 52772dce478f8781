"""Dense 3x3 blocks: inverses and the one per-particle implicit step, inlined into kernels.

Per-particle systems of the package are 3x3: the diagonal blocks of the spring operator (their
inverses precondition conjugate gradients) and the linearised backward Euler step of a particle
in a velocity field (Baraff & Witkin 1998), ``(I - h J) dx = h v``, solved by Cramer's rule
with the adjugate.
"""

from __future__ import annotations

from numba import njit

__all__ = ["implicit_step3", "invert3_into"]


@njit(cache=True, inline="always")
def implicit_step3(J, h, x, y, z, v0, v1, v2):
    """One linearised backward Euler step of a particle: ``x + dx`` with ``(I - h J) dx = h v``,
    solved by Cramer's rule (the adjugate).

    Parameters
    ----------
    J : (3, 3) float64
        Velocity gradient ``dv_p / dx_q`` (1/s).
    h : float
        Time step (s).
    x, y, z : float
        Position (m).
    v0, v1, v2 : float
        Velocity (m/s).

    Returns
    -------
    x1, y1, z1 : float
        The new position (m); meaningless (the old one) when ``|det| <= 1e-12``.
    det : float
        ``det(I - h J)``: the caller decides what a singular step means.
    """
    m00 = 1.0 - h * J[0, 0]
    m01 = -h * J[0, 1]
    m02 = -h * J[0, 2]
    m10 = -h * J[1, 0]
    m11 = 1.0 - h * J[1, 1]
    m12 = -h * J[1, 2]
    m20 = -h * J[2, 0]
    m21 = -h * J[2, 1]
    m22 = 1.0 - h * J[2, 2]
    c00 = m11 * m22 - m12 * m21
    c01 = m02 * m21 - m01 * m22
    c02 = m01 * m12 - m02 * m11
    c10 = m12 * m20 - m10 * m22
    c11 = m00 * m22 - m02 * m20
    c12 = m02 * m10 - m00 * m12
    c20 = m10 * m21 - m11 * m20
    c21 = m01 * m20 - m00 * m21
    c22 = m00 * m11 - m01 * m10
    det = m00 * c00 + m01 * c10 + m02 * c20
    if not (abs(det) > 1e-12):
        return x, y, z, det
    r0 = h * v0 / det
    r1 = h * v1 / det
    r2 = h * v2 / det
    return (x + c00 * r0 + c01 * r1 + c02 * r2, y + c10 * r0 + c11 * r1 + c12 * r2,
            z + c20 * r0 + c21 * r1 + c22 * r2, det)


@njit(cache=True, inline="always")
def invert3_into(a, out, i):
    """``out[i] = a^-1`` for a 3x3 SPD block ``a`` (its diagonal's inverse if ``a`` is not
    positive definite: ``det <= 0``)."""
    c00 = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    c01 = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    c02 = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    det = a[0, 0] * c00 + a[0, 1] * c01 + a[0, 2] * c02
    if not det > 0.0:
        for r in range(3):
            for q in range(3):
                out[i, r, q] = 0.0
            out[i, r, r] = 1.0 / a[r, r] if a[r, r] > 0.0 else 1.0
        return
    d = 1.0 / det
    out[i, 0, 0] = c00 * d
    out[i, 1, 0] = c01 * d
    out[i, 2, 0] = c02 * d
    out[i, 0, 1] = (a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]) * d
    out[i, 1, 1] = (a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]) * d
    out[i, 2, 1] = (a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]) * d
    out[i, 0, 2] = (a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]) * d
    out[i, 1, 2] = (a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]) * d
    out[i, 2, 2] = (a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]) * d
