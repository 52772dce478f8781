"""Conjugate gradients preconditioned by block SSOR with Eisenstat's trick, in Numba.

The preconditioner is ``M = P D'^-1 P^T`` with ``P = D/omega + L`` (symmetric successive
over-relaxation on the 3x3 particle blocks of a :class:`filters.linalg.operator.BlockOperator`);
CG runs on ``S^-1 H S^-T`` (``M = S S^T``), whose product costs one backward and one forward
sweep over the pairs and no separate product with ``H`` (Eisenstat 1981, "Efficient
implementation of a class of preconditioned conjugate gradient methods", SIAM J. Sci. Stat.
Comput.). With ``omega`` near its optimum the preconditioned condition number is
``O(sqrt(kappa))`` on model problems (Axelsson 1994, "Iterative solution methods"). The scratch
arrays belong to an :class:`SSORWorkspace`, which a solver keeps between solves so that a solve
allocates nothing.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .operator import apply_pair_block, block_matvec, start_norm

__all__ = ["pcg_ssor", "SSORWorkspace", "DEFAULT_OMEGA"]

#: Over-relaxation factor of the SSOR preconditioner.
DEFAULT_OMEGA = 1.6


class SSORWorkspace:
    """Scratch arrays of :func:`pcg_ssor` for an operator of ``n`` particles and ``s`` pairs,
    reallocated only when the sizes change.

    Attributes
    ----------
    arrays : tuple of float64 arrays
        ``(D' (n, 3, 3), D'^-1 (n, 3, 3), pair blocks in upper order (s, 6), 8 vectors (n, 3),
        (n, 6))``.
    """

    def __init__(self):
        self.arrays = None

    def get(self, n: int, s: int) -> tuple[np.ndarray, ...]:
        """The arrays for ``n`` particles and ``s`` pairs (new ones if the sizes changed)."""
        work = self.arrays
        if work is None or work[0].shape[0] != n or work[2].shape[0] != s:
            work = (np.empty((n, 3, 3)), np.empty((n, 3, 3)), np.empty((s, 6)),
                    *(np.empty((n, 3)) for _ in range(8)), np.empty((n, 6)))
            self.arrays = work
        return work


@njit(cache=True)
def _ssor_setup(free, blocks, diag, up_ptr, up_spring, up_other, omega, dsc, dinv, ublk,
                gather, acc):
    """Scaled particle blocks ``D'_i = D_i / omega`` (``dsc``) and their inverses (``dinv``);
    with ``gather``, the spring blocks copied into upper-incidence order (``ublk``).

    One pass in particle order: the blocks of particle ``i``'s upper springs are summed in
    registers and pushed to the other end (``acc``, (N, 6) scratch), so that ``D_i`` is complete
    when ``i`` is reached (its lower springs were pushed before).
    """
    n = diag.shape[0]
    for i in range(n):
        for k in range(6):
            acc[i, k] = 0.0
    for i in range(n):
        s0 = acc[i, 0]
        s1 = acc[i, 1]
        s2 = acc[i, 2]
        s3 = acc[i, 3]
        s4 = acc[i, 4]
        s5 = acc[i, 5]
        for p in range(up_ptr[i], up_ptr[i + 1]):
            sp = up_spring[p]
            j = up_other[p]
            b0 = blocks[sp, 0]
            b1 = blocks[sp, 1]
            b2 = blocks[sp, 2]
            b3 = blocks[sp, 3]
            b4 = blocks[sp, 4]
            b5 = blocks[sp, 5]
            if gather:
                ublk[p, 0] = b0
                ublk[p, 1] = b1
                ublk[p, 2] = b2
                ublk[p, 3] = b3
                ublk[p, 4] = b4
                ublk[p, 5] = b5
            s0 += b0
            s1 += b1
            s2 += b2
            s3 += b3
            s4 += b4
            s5 += b5
            acc[j, 0] += b0
            acc[j, 1] += b1
            acc[j, 2] += b2
            acc[j, 3] += b3
            acc[j, 4] += b4
            acc[j, 5] += b5
        w = 1.0 / omega
        if free[i] == 0.0:  # identity row, not relaxed and not coupled
            w = 1.0
            s0 = 0.0
            s1 = 0.0
            s2 = 0.0
            s3 = 0.0
            s4 = 0.0
            s5 = 0.0
        m00 = (diag[i, 0, 0] + s0) * w
        m01 = (diag[i, 0, 1] + s1) * w
        m02 = (diag[i, 0, 2] + s2) * w
        m10 = (diag[i, 1, 0] + s1) * w
        m11 = (diag[i, 1, 1] + s3) * w
        m12 = (diag[i, 1, 2] + s4) * w
        m20 = (diag[i, 2, 0] + s2) * w
        m21 = (diag[i, 2, 1] + s4) * w
        m22 = (diag[i, 2, 2] + s5) * w
        dsc[i, 0, 0] = m00
        dsc[i, 0, 1] = m01
        dsc[i, 0, 2] = m02
        dsc[i, 1, 0] = m10
        dsc[i, 1, 1] = m11
        dsc[i, 1, 2] = m12
        dsc[i, 2, 0] = m20
        dsc[i, 2, 1] = m21
        dsc[i, 2, 2] = m22
        c00 = m11 * m22 - m12 * m21
        c01 = m12 * m20 - m10 * m22
        c02 = m10 * m21 - m11 * m20
        det = m00 * c00 + m01 * c01 + m02 * c02
        if not det > 0.0:  # not positive definite: diagonal inverse (never for H)
            for r in range(3):
                for q in range(3):
                    dinv[i, r, q] = 0.0
            dinv[i, 0, 0] = 1.0 / m00 if m00 > 0.0 else 1.0
            dinv[i, 1, 1] = 1.0 / m11 if m11 > 0.0 else 1.0
            dinv[i, 2, 2] = 1.0 / m22 if m22 > 0.0 else 1.0
            continue
        d = 1.0 / det
        dinv[i, 0, 0] = c00 * d
        dinv[i, 1, 0] = c01 * d
        dinv[i, 2, 0] = c02 * d
        dinv[i, 0, 1] = (m02 * m21 - m01 * m22) * d
        dinv[i, 1, 1] = (m00 * m22 - m02 * m20) * d
        dinv[i, 2, 1] = (m01 * m20 - m00 * m21) * d
        dinv[i, 0, 2] = (m01 * m12 - m02 * m11) * d
        dinv[i, 1, 2] = (m02 * m10 - m00 * m12) * d
        dinv[i, 2, 2] = (m00 * m11 - m01 * m10) * d


@njit(cache=True, inline="always")
def _pull(up_ptr, up_other, ublk, t, i):
    """``sum_j U_ij t_j`` over the springs stored with particle ``i`` (gather form)."""
    q0 = 0.0
    q1 = 0.0
    q2 = 0.0
    for p in range(up_ptr[i], up_ptr[i + 1]):
        j = up_other[p]
        k0, k1, k2 = apply_pair_block(ublk, p, t[j, 0], t[j, 1], t[j, 2])
        q0 += k0
        q1 += k1
        q2 += k2
    return q0, q1, q2


@njit(cache=True, inline="always")
def _push(up_ptr, up_other, ublk, i, y0, y1, y2, sign, acc):
    """``acc_j += sign U_ji y`` for the springs stored with particle ``i`` (scatter form;
    ``sign`` is +1 or -1, so the sums are the same floating-point operations as ``+=`` / ``-=``)."""
    for p in range(up_ptr[i], up_ptr[i + 1]):
        j = up_other[p]
        k0, k1, k2 = apply_pair_block(ublk, p, y0, y1, y2)
        acc[j, 0] += sign * k0
        acc[j, 1] += sign * k1
        acc[j, 2] += sign * k2


@njit(cache=True, inline="always")
def _mul3(m, i, a0, a1, a2):
    return (m[i, 0, 0] * a0 + m[i, 0, 1] * a1 + m[i, 0, 2] * a2,
            m[i, 1, 0] * a0 + m[i, 1, 1] * a1 + m[i, 1, 2] * a2,
            m[i, 2, 0] * a0 + m[i, 2, 1] * a1 + m[i, 2, 2] * a2)


@njit(cache=True)
def _ssor_apply(up_ptr, up_other, ublk, dinv, free, omega, r, beta, a, t, q, acc, w):
    """CG direction update ``a = r + beta a`` fused with the product ``w = S^-1 A S^-T a`` of
    Eisenstat's trick in the ``a = C x_hat`` coordinates.

    With ``P = D' + L`` (``D' = D / omega``, ``L`` the strictly lower spring blocks) and
    ``A = P + P^T - (2 - omega) D'``: backward solve ``P^T t = a`` (``q_i = sum_{j>i} K_ij t_j``),
    then forward solve ``P y = s`` with ``s = (omega - 1) a - (2 - omega) q``, pushing
    ``acc_j += K_ij y_i``; ``w = D'(t + y) = omega a + (omega - 1) q + acc``.  Each spring is
    visited twice; returns ``a . (t + y) = a . D'^-1 w`` (the CG curvature in the inner product
    ``u . D'^-1 v`` of these coordinates).  Pinned particles (``free`` 0) are decoupled: their
    ``t``, ``y`` and ``w`` are zero, whatever the sweeps push into their slots.
    """
    n = a.shape[0]
    for i in range(n - 1, -1, -1):
        # the sweep only reads a_j, t_j of j > i: a_i can be updated on the way
        a[i, 0] = r[i, 0] + beta * a[i, 0]
        a[i, 1] = r[i, 1] + beta * a[i, 1]
        a[i, 2] = r[i, 2] + beta * a[i, 2]
        acc[i, 0] = 0.0
        acc[i, 1] = 0.0
        acc[i, 2] = 0.0
        if free[i] == 0.0:
            t[i, 0] = 0.0
            t[i, 1] = 0.0
            t[i, 2] = 0.0
            q[i, 0] = 0.0
            q[i, 1] = 0.0
            q[i, 2] = 0.0
            continue
        q0, q1, q2 = _pull(up_ptr, up_other, ublk, t, i)
        q[i, 0] = q0
        q[i, 1] = q1
        q[i, 2] = q2
        t[i, 0], t[i, 1], t[i, 2] = _mul3(dinv, i, a[i, 0] + q0, a[i, 1] + q1, a[i, 2] + q2)
    c1 = omega - 1.0
    c2 = 2.0 - omega
    curv = 0.0
    for i in range(n):
        if free[i] == 0.0:
            w[i, 0] = 0.0
            w[i, 1] = 0.0
            w[i, 2] = 0.0
            continue
        y0, y1, y2 = _mul3(dinv, i, c1 * a[i, 0] - c2 * q[i, 0] + acc[i, 0],
                           c1 * a[i, 1] - c2 * q[i, 1] + acc[i, 1],
                           c1 * a[i, 2] - c2 * q[i, 2] + acc[i, 2])
        _push(up_ptr, up_other, ublk, i, y0, y1, y2, 1.0, acc)
        w0 = omega * a[i, 0] + c1 * q[i, 0] + acc[i, 0]
        w1 = omega * a[i, 1] + c1 * q[i, 1] + acc[i, 1]
        w2 = omega * a[i, 2] + c1 * q[i, 2] + acc[i, 2]
        w[i, 0] = w0
        w[i, 1] = w1
        w[i, 2] = w2
        curv += (a[i, 0] * (t[i, 0] + y0) + a[i, 1] * (t[i, 1] + y1)
                 + a[i, 2] * (t[i, 2] + y2))
    return curv


@njit(cache=True)
def _ssor_forward(up_ptr, up_other, ublk, dinv, free, s, y, acc):
    """Forward solve ``P y = s`` (push form) into ``y`` (zero at pinned particles)."""
    n = s.shape[0]
    for i in range(n):
        acc[i, 0] = 0.0
        acc[i, 1] = 0.0
        acc[i, 2] = 0.0
    for i in range(n):
        if free[i] == 0.0:
            y[i, 0] = 0.0
            y[i, 1] = 0.0
            y[i, 2] = 0.0
            continue
        y0, y1, y2 = _mul3(dinv, i, s[i, 0] + acc[i, 0], s[i, 1] + acc[i, 1],
                           s[i, 2] + acc[i, 2])
        y[i, 0] = y0
        y[i, 1] = y1
        y[i, 2] = y2
        _push(up_ptr, up_other, ublk, i, y0, y1, y2, 1.0, acc)


@njit(cache=True)
def _ssor_backward(up_ptr, up_other, ublk, dinv, free, a, t):
    """Backward solve ``P^T t = a`` (pull form; zero at pinned particles)."""
    for i in range(a.shape[0] - 1, -1, -1):
        if free[i] == 0.0:
            t[i, 0] = 0.0
            t[i, 1] = 0.0
            t[i, 2] = 0.0
            continue
        q0, q1, q2 = _pull(up_ptr, up_other, ublk, t, i)
        t[i, 0], t[i, 1], t[i, 2] = _mul3(dinv, i, a[i, 0] + q0, a[i, 1] + q1, a[i, 2] + q2)


@njit(cache=True)
def _ssor_unscale(up_ptr, up_other, ublk, dinv, free, rt, out):
    """``out = P D'^-1 rt`` (the residual of the original system from the one of the
    transformed system, ``rt = D' P^-1 r``); returns ``|out|^2``."""
    n = rt.shape[0]
    for i in range(n):
        out[i, 0] = rt[i, 0]
        out[i, 1] = rt[i, 1]
        out[i, 2] = rt[i, 2]
    for i in range(n):
        z0, z1, z2 = _mul3(dinv, i, rt[i, 0], rt[i, 1], rt[i, 2])
        _push(up_ptr, up_other, ublk, i, z0, z1, z2, -1.0, out)
    acc = 0.0
    for i in range(n):
        if free[i] == 0.0:
            out[i, 0] = 0.0
            out[i, 1] = 0.0
            out[i, 2] = 0.0
        acc += out[i, 0] * out[i, 0] + out[i, 1] * out[i, 1] + out[i, 2] * out[i, 2]
    return acc


@njit(cache=True)
def _wdot(dinv, u, v):
    """``u . D'^-1 v`` (the inner product of the ``a`` coordinates)."""
    acc = 0.0
    for i in range(u.shape[0]):
        z0, z1, z2 = _mul3(dinv, i, v[i, 0], v[i, 1], v[i, 2])
        acc += u[i, 0] * z0 + u[i, 1] * z1 + u[i, 2] * z2
    return acc


@njit(cache=True)
def pcg_ssor(pairs, free, blocks, diag, upper, b, x, tol, max_iter, omega, work, ordered):
    """SSOR-preconditioned CG for ``H x = b`` with Eisenstat's (1981) trick.

    The preconditioner is ``M = P D'^-1 P^T`` with ``P = D/omega + L`` (symmetric successive
    over-relaxation on the 3x3 particle blocks); CG runs on ``S^-1 H S^-T`` (``M = S S^T``),
    whose product costs one backward and one forward sweep over the springs and no separate
    product with ``H`` (Eisenstat 1981, "Efficient implementation of a class of preconditioned
    conjugate gradient methods", SIAM J. Sci. Stat. Comput.).  Every few iterations the
    recursive residual is mapped back to the original system (``r = P D'^-1 r_tilde``, half an
    iteration's work) and CG stops when ``|r| <= tol |b|``; after a breakdown or at the
    iteration limit the true residual ``|b - H x|`` is recomputed and CG restarted (with a
    tighter goal) if it is still above ``tol |b|``.  Pinned particles (``free`` 0) are
    decoupled identity rows.  ``work`` holds the scratch arrays (:meth:`SSORWorkspace.get`);
    ``ordered`` says that spring ``s`` is upper incidence ``s`` (then ``blocks`` is streamed in
    place instead of copied).  Returns (iterations, relative residual).
    """
    up_ptr, up_spring, up_other = upper
    n = b.shape[0]
    dsc, dinv, ublk, t, qv, acc, w, r, pv, ax, res, acc6 = work
    if ordered:  # spring s is upper incidence s: stream the operator's blocks in place
        ublk = blocks
    _ssor_setup(free, blocks, diag, up_ptr, up_spring, up_other, omega, dsc, dinv, ublk,
                not ordered, acc6)
    bnorm = start_norm(b, x)
    if bnorm == 0.0:
        return 0, 0.0
    for i in range(n):
        if free[i] == 0.0:
            for k in range(3):
                x[i, k] = b[i, k]
    it = 0
    true_rel = 1.0
    check = 8  # most iterations between residual checks
    zero_start = True
    for i in range(n):
        if free[i] != 0.0 and (x[i, 0] != 0.0 or x[i, 1] != 0.0 or x[i, 2] != 0.0):
            zero_start = False
            break
    for attempt in range(4):
        # residual of the original system (no product needed for a zero start)
        if attempt == 0 and zero_start:
            for i in range(n):
                for k in range(3):
                    res[i, k] = 0.0
        else:
            block_matvec(pairs, free, blocks, diag, x, res)
        rr = 0.0
        for i in range(n):
            fi = free[i]
            for k in range(3):
                res[i, k] = fi * (b[i, k] - res[i, k])
                rr += res[i, k] * res[i, k]
        true_rel = math.sqrt(rr) / bnorm
        if true_rel <= tol or it >= max_iter:
            break
        goal = (0.5 ** attempt * tol * bnorm) ** 2
        since = check
        # correction e solves H e = res: CG in a = C e_hat coordinates, a0 = 0
        # r_tilde = D' P^-1 res  (= res + acc of the forward solve)
        _ssor_forward(up_ptr, up_other, ublk, dinv, free, res, t, acc)
        for i in range(n):
            r[i, 0], r[i, 1], r[i, 2] = _mul3(dsc, i, t[i, 0], t[i, 1], t[i, 2])
            for k in range(3):
                ax[i, k] = 0.0
                pv[i, k] = r[i, k]
        rho = _wdot(dinv, r, r)
        beta = 0.0  # first direction: pv = r
        since = 0
        ratio = 0.0  # |r|^2 / rho at the last check
        converged = False
        while it < max_iter:
            # Map the recursive residual back to H (half an iteration's work) when the ratio
            # seen at the last check predicts convergence, or every ``check`` iterations.
            if since >= check or ratio * rho <= 2.0 * goal:
                since = 0
                rr = _ssor_unscale(up_ptr, up_other, ublk, dinv, free, r, acc)
                if rr <= goal:
                    converged = True
                    break
                ratio = rr / rho if rho > 0.0 else 0.0
            since += 1
            curv = _ssor_apply(up_ptr, up_other, ublk, dinv, free, omega, r, beta, pv, t, qv,
                               acc, w)
            if not curv > 0.0:
                break
            alpha = rho / curv
            rho_new = 0.0
            for i in range(n):
                for k in range(3):
                    ax[i, k] += alpha * pv[i, k]
                    r[i, k] -= alpha * w[i, k]
                z0, z1, z2 = _mul3(dinv, i, r[i, 0], r[i, 1], r[i, 2])
                rho_new += r[i, 0] * z0 + r[i, 1] * z1 + r[i, 2] * z2
            if not rho > 0.0:  # underflow (a state of ~1e-160): nothing left to solve
                it += 1
                break
            beta = rho_new / rho
            rho = rho_new
            it += 1
        # e = P^-T a
        _ssor_backward(up_ptr, up_other, ublk, dinv, free, ax, t)
        for i in range(n):
            fi = free[i]
            for k in range(3):
                x[i, k] += fi * t[i, k]
        if converged:
            # the recursive residual (checked against the true one only after a breakdown or
            # at the iteration limit: it drifts from it by rounding alone)
            true_rel = math.sqrt(rr) / bnorm
            break
    return it, true_rel
