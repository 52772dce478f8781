"""SPH sums of the weakly compressible solver (and of the force terms DFSPH shares): density by
summation, the Tait equation of state, Akinci et al. (2013) normals, pressure / viscosity /
surface-tension accelerations, Adami et al. (2012) boundary pressures and XSPH.

The method (WCSPH)
------------------
* Density by summation, ``rho_i = sum_j m W_ij + sum_b rho0 V_b W_ib`` (fluid and boundary).
* Tait equation of state (Becker & Teschner 2007, after Monaghan 1994)
  ``p = B ((rho / rho0)^gamma - 1)``, ``B = rho0 c^2 / gamma``, ``gamma = 7``, with the density
  clamped at ``rho0`` from below (no tension at the free surface).  The speed of sound ``c`` is ten
  times the largest expected speed ``sqrt(2 g H)`` unless given, which keeps density errors
  around 1 % (Monaghan 1994: ``|drho| / rho0 ~ (v / c)^2``).
* Pressure acceleration ``-sum_j m (p_i / rho_i^2 + p_j / rho_j^2) grad W_ij``; boundary particles
  (Akinci et al. 2012) act with mass ``rho0 V_b`` and a pressure extrapolated from the fluid
  including the hydrostatic term (Adami, Hu & Adams 2012, "A generalized wall boundary condition
  for smoothed particle hydrodynamics", JCP 231), or optionally the fluid particle's own pressure
  mirrored onto them.
* Artificial viscosity (Monaghan 1992) ``Pi_ij = -alpha c mu_ij / rho_bar_ij`` with
  ``mu_ij = h' v_ij . x_ij / (|x_ij|^2 + 0.01 h'^2)`` for approaching pairs (``h' = h / 2``, the
  smoothing length), also against the (static) boundary particles, which gives wall friction
  (scaled by each boundary particle's friction factor);
  optional XSPH velocity smoothing (Monaghan 1989) with factor ``xsph``.
* Surface tension and cohesion of Akinci, Akinci & Teschner (2013): a cohesion force with the
  spline ``C(r)`` (repulsive closer than ``h / 2``, attractive out to ``h``, zero beyond) plus the
  curvature term on the normals ``n_i = h sum_j m / rho_j grad W_ij``, both scaled by
  ``2 rho0 / (rho_i + rho_j)``.
* External accelerations: gravity (default ``(0, 0, -9.81)``) plus an optional field, a callable
  ``field(positions, velocities, time) -> (N, 3)`` or an object with such an ``acceleration``
  method.
* Symplectic (semi-implicit) Euler, ``v += dt a; x += dt v``, with an adaptive step
  (:meth:`filters.sph.SPHLiquid.max_step`): the CFL condition with Monaghan's viscous term
  ``dt <= cfl h' / (c (1 + 0.6 alpha) + |v|_max)`` and the force condition
  ``dt <= 0.25 sqrt(h' / |a|_max)`` (Monaghan 1992; Becker & Teschner 2007).

Every kernel gathers over each particle's own neighbour rows (``tab[i, :cnt[i]]``, fluid, and
``btab``/``bcnt``, boundary) and skips pairs beyond the support ``h``, so any valid superset list
(e.g. Verlet lists with a skin) gives the same sums.  See :mod:`filters.sph.liquid` for the
method and its references.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..kernels import cohesion_c, kernel_dw, kernel_w

__all__ = ["density", "tait_pressure", "normals", "accelerations", "boundary_pressures", "xsph"]


@njit(parallel=True, cache=True, error_model="numpy")
def density(x, tab, cnt, xb, btab, bcnt, bpsi, m, h, kind, rho):
    """rho_i = m W(0) + sum_j m W_ij + sum_b psi_b W_ib (kg/m^3)."""
    w0 = kernel_w(kind, 0.0, h)
    h2 = h * h
    for i in prange(x.shape[0]):
        s = 0.0
        for k in range(cnt[i]):
            j = tab[i, k]
            dx = x[i, 0] - x[j, 0]
            dy = x[i, 1] - x[j, 1]
            dz = x[i, 2] - x[j, 2]
            r2 = dx * dx + dy * dy + dz * dz
            if r2 < h2:
                s += kernel_w(kind, math.sqrt(r2), h)
        sb = 0.0
        for k in range(bcnt[i]):
            b = btab[i, k]
            dx = x[i, 0] - xb[b, 0]
            dy = x[i, 1] - xb[b, 1]
            dz = x[i, 2] - xb[b, 2]
            r2 = dx * dx + dy * dy + dz * dz
            if r2 < h2:
                sb += bpsi[b] * kernel_w(kind, math.sqrt(r2), h)
        rho[i] = m * (w0 + s) + sb


@njit(parallel=True, cache=True, error_model="numpy")
def tait_pressure(rho, rho0, stiffness, gamma, p):
    """Tait pressure with the density clamped at rho0; returns the largest compression."""
    n = rho.shape[0]
    err = 0.0
    for i in prange(n):
        r = rho[i] / rho0
        if r < 1.0:
            r = 1.0
        p[i] = stiffness * (r ** gamma - 1.0)
        err = max(err, r - 1.0)
    return err


@njit(parallel=True, cache=True, error_model="numpy")
def normals(x, rho, tab, cnt, m, h, kind, nrm):
    """Akinci et al. (2013) surface normals n_i = h sum_j m / rho_j grad W_ij (dimensionless)."""
    for i in prange(x.shape[0]):
        nx = 0.0
        ny = 0.0
        nz = 0.0
        for k in range(cnt[i]):
            j = tab[i, k]
            dx = x[i, 0] - x[j, 0]
            dy = x[i, 1] - x[j, 1]
            dz = x[i, 2] - x[j, 2]
            r2 = dx * dx + dy * dy + dz * dz
            if r2 > 0.0 and r2 < h * h:
                r = math.sqrt(r2)
                f = m / rho[j] * kernel_dw(kind, r, h) / r
                nx += f * dx
                ny += f * dy
                nz += f * dz
        nrm[i, 0] = h * nx
        nrm[i, 1] = h * ny
        nrm[i, 2] = h * nz


@njit(parallel=True, cache=True, error_model="numpy")
def accelerations(x, v, rho, p, tab, cnt, xb, btab, bcnt, bpsi, bpr, bfric, m, h, kind, alpha,
                   alpha_b, c, rho0, st, nrm, g, a):
    """Pressure, viscosity, surface tension and gravity accelerations (m/s^2) into ``a``.

    ``bpr[b]`` is ``p_b / rho_b^2`` of boundary particle ``b`` (Adami et al. 2012), or negative
    for pressure mirroring (``p_b / rho_b^2 = p_i / rho_i^2``, Akinci et al. 2012); ``bfric[b]``
    its friction factor (multiplies ``alpha_b``).  Returns ``max |a|``.
    """
    n = x.shape[0]
    hs = 0.5 * h
    eps = 0.01 * hs * hs
    h2 = h * h
    amax = np.zeros(n)
    for i in prange(n):
        ri = rho[i]
        pi_ = p[i] / (ri * ri)
        ax = g[0]
        ay = g[1]
        az = g[2]
        for k in range(cnt[i]):
            j = tab[i, k]
            dx = x[i, 0] - x[j, 0]
            dy = x[i, 1] - x[j, 1]
            dz = x[i, 2] - x[j, 2]
            r2 = dx * dx + dy * dy + dz * dz
            if r2 == 0.0 or r2 >= h2:
                continue
            r = math.sqrt(r2)
            rj = rho[j]
            fac = -m * (pi_ + p[j] / (rj * rj))
            vd = (v[i, 0] - v[j, 0]) * dx + (v[i, 1] - v[j, 1]) * dy + (v[i, 2] - v[j, 2]) * dz
            if vd < 0.0 and alpha > 0.0:
                mu = hs * vd / (r2 + eps)
                fac += m * alpha * c * mu / (0.5 * (ri + rj))
            fw = fac * kernel_dw(kind, r, h) / r
            ax += fw * dx
            ay += fw * dy
            az += fw * dz
            if st > 0.0:
                kij = 2.0 * rho0 / (ri + rj)
                cc = m * cohesion_c(r, h) / r
                ax -= st * kij * (cc * dx + nrm[i, 0] - nrm[j, 0])
                ay -= st * kij * (cc * dy + nrm[i, 1] - nrm[j, 1])
                az -= st * kij * (cc * dz + nrm[i, 2] - nrm[j, 2])
        for k in range(bcnt[i]):
            b = btab[i, k]
            dx = x[i, 0] - xb[b, 0]
            dy = x[i, 1] - xb[b, 1]
            dz = x[i, 2] - xb[b, 2]
            r2 = dx * dx + dy * dy + dz * dz
            if r2 == 0.0 or r2 >= h2:
                continue
            r = math.sqrt(r2)
            fac = -bpsi[b] * (pi_ + (pi_ if bpr[b] < 0.0 else bpr[b]))
            vd = v[i, 0] * dx + v[i, 1] * dy + v[i, 2] * dz
            if vd < 0.0 and alpha_b > 0.0:
                mu = hs * vd / (r2 + eps)
                fac += bpsi[b] * alpha_b * bfric[b] * c * mu / ri
            fw = fac * kernel_dw(kind, r, h) / r
            ax += fw * dx
            ay += fw * dy
            az += fw * dz
        a[i, 0] = ax
        a[i, 1] = ay
        a[i, 2] = az
        amax[i] = math.sqrt(ax * ax + ay * ay + az * az)
    return amax.max() if n else 0.0


@njit(cache=True, error_model="numpy")
def boundary_pressures(x, rho, p, xb, btab, bcnt, h, kind, g, rho0, stiffness, gamma, mirror, bpr):
    """Boundary pressures extrapolated from the fluid (Adami, Hu & Adams 2012, static walls):

    ``p_b = (sum_f p_f W_bf + g . sum_f rho_f (x_b - x_f) W_bf) / sum_f W_bf``, clamped at 0,
    stored as ``p_b / rho_b^2`` with ``rho_b`` from the inverse Tait equation.  A boundary
    particle without fluid neighbours gets ``-1`` (mirroring).  Serial scatter over the fluid's
    boundary lists (only particles near walls have any), so no races.
    """
    nb = xb.shape[0]
    num = np.zeros(nb)
    den = np.zeros(nb)
    for i in range(x.shape[0]):
        for k in range(bcnt[i]):
            b = btab[i, k]
            dx = xb[b, 0] - x[i, 0]
            dy = xb[b, 1] - x[i, 1]
            dz = xb[b, 2] - x[i, 2]
            r2 = dx * dx + dy * dy + dz * dz
            if r2 >= h * h:
                continue
            w = kernel_w(kind, math.sqrt(r2), h)
            num[b] += (p[i] + rho[i] * (g[0] * dx + g[1] * dy + g[2] * dz)) * w
            den[b] += w
    for b in range(nb):
        if mirror or den[b] <= 0.0:
            bpr[b] = -1.0
        else:
            pb = max(num[b] / den[b], 0.0)
            rb = rho0 * (pb / stiffness + 1.0) ** (1.0 / gamma)
            bpr[b] = pb / (rb * rb)


@njit(parallel=True, cache=True, error_model="numpy")
def xsph(v, rho, x, tab, cnt, m, h, kind, eps, out):
    """XSPH smoothing v_i + eps sum_j 2 m / (rho_i + rho_j) (v_j - v_i) W_ij (Monaghan 1989)."""
    for i in prange(v.shape[0]):
        sx = 0.0
        sy = 0.0
        sz = 0.0
        for k in range(cnt[i]):
            j = tab[i, k]
            dx = x[i, 0] - x[j, 0]
            dy = x[i, 1] - x[j, 1]
            dz = x[i, 2] - x[j, 2]
            r2 = dx * dx + dy * dy + dz * dz
            if r2 >= h * h:
                continue
            f = 2.0 * m / (rho[i] + rho[j]) * kernel_w(kind, math.sqrt(r2), h)
            sx += f * (v[j, 0] - v[i, 0])
            sy += f * (v[j, 1] - v[i, 1])
            sz += f * (v[j, 2] - v[i, 2])
        out[i, 0] = v[i, 0] + eps * sx
        out[i, 1] = v[i, 1] + eps * sy
        out[i, 2] = v[i, 2] + eps * sz
