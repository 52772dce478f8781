"""Hyperelastic materials of the finite elements: energy density, stress and its derivative.

Two isotropic materials, functions of the deformation gradient ``F`` (3x3):

* :data:`COROTATED` -- the corotational linear material of Müller & Gross (2004, "Interactive
  virtual materials", Graphics Interface), whose forces rotate linear elasticity into each
  element's frame ``R`` (the rotation of the polar decomposition ``F = R S``), in the energy
  form of McAdams et al. (2011, "Efficient elasticity for character skinning with contact and
  collisions", SIGGRAPH) and Stomakhin et al. (2012, "Energetically consistent invertible
  elasticity", SCA)::

      Psi = mu |F - R|^2 + lambda / 2 tr(S - I)^2,    P = 2 mu (F - R) + lambda tr(S - I) R,

  so that the force is exactly minus the energy's gradient (Müller & Gross freeze ``R``;
  here its derivative is kept, and the Hessian is the consistent one).
* :data:`NEO_HOOKEAN` -- the stable Neo-Hookean material of Smith, de Goes & Kim (2018,
  "Stable Neo-Hookean flesh simulation", ACM TOG 37(2)), Eq. 14 with its rest-stable offset and
  its reparametrised Lamé constants (Sec. 3.4: ``mu = 4/3 mu_L``, ``lambda = lambda_L + 5/6
  mu_L``, so that small strains follow linear elasticity with the user's ``E`` and ``nu``)::

      Psi = mu/2 (I_C - 3) + lambda/2 (J - alpha)^2 - mu/2 log(I_C + 1) - Psi_0,
      alpha = 1 + 3 mu / (4 lambda),

  with ``I_C = |F|^2``, ``J = det F`` and ``Psi_0`` the constant that makes ``Psi(I) = 0``.
  Defined for inverted elements (``J < 0``), no singularity at ``J = 0``.

Both are rotation invariant: a rigid motion has zero energy and zero stress.

The stress derivative ``dP/dF`` (9x9, row-major ``vec F``) comes from the analytic
eigensystem of isotropic energies in the signed singular values ``s`` of ``F = U diag(s) V^T``
(Teran, Sifakis, Irving & Fedkiw 2005, "Robust quasistatic finite elements and flesh
simulation"; Smith, de Goes & Kim 2019, "Analytic eigensystems for isotropic distortion
energies", ACM TOG 38(1)): a 3x3 block ``d^2 Psi / ds_i ds_j`` on the scaling modes
``u_i v_i^T``, and for every pair ``(i, j)`` a *twist* mode ``(u_i v_j^T - u_j v_i^T)/sqrt 2``
with eigenvalue ``(psi_i + psi_j) / (s_i + s_j)`` and a *flip* mode
``(u_i v_j^T + u_j v_i^T)/sqrt 2`` with ``(psi_i - psi_j) / (s_i - s_j)`` (``psi_i = dPsi/ds_i``),
written for each material without the removable divisions.  The *definite* derivative clamps
negative twist and flip eigenvalues to 0 and projects the 3x3 block onto the positive
semi-definite cone, which makes every element's stiffness positive semi-definite (Teran et al.
2005; Smith et al. 2019).

The functions here are Numba kernels' building blocks; :mod:`filters.elastic.fem` has the
array-level API.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from ..linalg.eigen3 import svd3, sym_project_psd3
from ..validation import check_choice, check_range

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = [
    "COROTATED",
    "NEO_HOOKEAN",
    "MATERIALS",
    "lame_parameters",
    "material_parameters",
    "energy_density",
    "first_piola",
    "stress_derivative",
    "eigensystem",
    "new_scratch",
]

COROTATED, NEO_HOOKEAN = 0, 1
#: Names of the materials, by code.
MATERIALS = ("corotated", "neo_hookean")

_SQRT_HALF = math.sqrt(0.5)


def lame_parameters(youngs_modulus: float, poisson_ratio: float) -> NDArray[np.float64]:
    """Lamé constants ``(mu, lambda)`` (Pa) of linear elasticity from ``E`` (Pa) and ``nu``.

    ``mu = E / (2 (1 + nu))``, ``lambda = E nu / ((1 + nu)(1 - 2 nu))``.

    Parameters
    ----------
    youngs_modulus : float
        Young's modulus ``E`` (Pa), > 0.
    poisson_ratio : float
        Poisson ratio ``nu``, in [0, 0.5).

    Returns
    -------
    (float, float)
    """
    e = check_range("youngs_modulus", youngs_modulus, 0.0, math.inf, low_inclusive=False)
    nu = check_range("poisson_ratio", poisson_ratio, 0.0, 0.5, high_inclusive=False)
    return e / (2.0 * (1.0 + nu)), e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))


def material_parameters(material: str, youngs_modulus: float,
                        poisson_ratio: float) -> tuple[int, float, float]:
    """Material code and the ``(mu, lambda)`` the energy uses, for ``E`` and ``nu``.

    The corotated material uses the Lamé constants; the stable Neo-Hookean one the
    reparametrised ``mu = 4/3 mu_L``, ``lambda = lambda_L + 5/6 mu_L`` (Smith et al. 2018,
    Sec. 3.4), so that both linearise to the same linear elasticity.

    Returns
    -------
    code : int
        :data:`COROTATED` or :data:`NEO_HOOKEAN`.
    mu, lam : float
        Energy parameters (Pa).
    """
    name = check_choice("material", material, MATERIALS)
    mu_l, lam_l = lame_parameters(youngs_modulus, poisson_ratio)
    if name == "corotated":
        return COROTATED, mu_l, lam_l
    return NEO_HOOKEAN, 4.0 / 3.0 * mu_l, lam_l + 5.0 / 6.0 * mu_l


def new_scratch() -> tuple[np.ndarray, ...]:
    """Scratch arrays of :func:`energy_density`, :func:`first_piola` and
    :func:`stress_derivative`: ``(u, v, m, a, q) (3, 3)`` and ``(s, w) (3,)`` float64, and
    ``modes (9, 9)``."""
    return (np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)),
            np.empty((3, 3)), np.empty(3), np.empty(3), np.empty((9, 9)))


@njit(cache=True, inline="always")
def _nh_alpha(mu, lam):
    return 1.0 + 0.75 * mu / lam


@njit(cache=True, inline="always")
def _nh_rest(mu, lam):
    """Energy density of the stable Neo-Hookean formula at ``F = I`` (subtracted)."""
    a = _nh_alpha(mu, lam)
    return 0.5 * lam * (1.0 - a) * (1.0 - a) - 0.5 * mu * math.log(4.0)


@njit(cache=True, inline="always")
def _det3(f):
    return (f[0, 0] * (f[1, 1] * f[2, 2] - f[1, 2] * f[2, 1])
            - f[0, 1] * (f[1, 0] * f[2, 2] - f[1, 2] * f[2, 0])
            + f[0, 2] * (f[1, 0] * f[2, 1] - f[1, 1] * f[2, 0]))


@njit(cache=True)
def energy_density(material, mu, lam, f, scratch):
    """Strain energy density ``Psi(F)`` (J/m^3) of the material ``material`` (a code)."""
    u, v, m, _, _, s, w, _ = scratch
    if material == NEO_HOOKEAN:
        ic = 0.0
        for i in range(3):
            for j in range(3):
                ic += f[i, j] * f[i, j]
        dj = _det3(f) - _nh_alpha(mu, lam)
        return (0.5 * mu * (ic - 3.0) + 0.5 * lam * dj * dj - 0.5 * mu * math.log(ic + 1.0)
                - _nh_rest(mu, lam))
    svd3(f, u, s, v, m, w)
    tr = s[0] + s[1] + s[2] - 3.0
    return (mu * ((s[0] - 1.0) ** 2 + (s[1] - 1.0) ** 2 + (s[2] - 1.0) ** 2)
            + 0.5 * lam * tr * tr)


@njit(cache=True)
def first_piola(material, mu, lam, f, p, scratch):
    """First Piola-Kirchhoff stress ``P = dPsi/dF`` (Pa) into ``p`` (3, 3); returns ``Psi``."""
    u, v, m, _, _, s, w, _ = scratch
    if material == NEO_HOOKEAN:
        ic = 0.0
        for i in range(3):
            for j in range(3):
                ic += f[i, j] * f[i, j]
        det = _det3(f)
        dj = det - _nh_alpha(mu, lam)
        mup = mu * (1.0 - 1.0 / (ic + 1.0))
        r = lam * dj
        # cofactor matrix dJ/dF
        p[0, 0] = mup * f[0, 0] + r * (f[1, 1] * f[2, 2] - f[1, 2] * f[2, 1])
        p[0, 1] = mup * f[0, 1] + r * (f[1, 2] * f[2, 0] - f[1, 0] * f[2, 2])
        p[0, 2] = mup * f[0, 2] + r * (f[1, 0] * f[2, 1] - f[1, 1] * f[2, 0])
        p[1, 0] = mup * f[1, 0] + r * (f[0, 2] * f[2, 1] - f[0, 1] * f[2, 2])
        p[1, 1] = mup * f[1, 1] + r * (f[0, 0] * f[2, 2] - f[0, 2] * f[2, 0])
        p[1, 2] = mup * f[1, 2] + r * (f[0, 1] * f[2, 0] - f[0, 0] * f[2, 1])
        p[2, 0] = mup * f[2, 0] + r * (f[0, 1] * f[1, 2] - f[0, 2] * f[1, 1])
        p[2, 1] = mup * f[2, 1] + r * (f[0, 2] * f[1, 0] - f[0, 0] * f[1, 2])
        p[2, 2] = mup * f[2, 2] + r * (f[0, 0] * f[1, 1] - f[0, 1] * f[1, 0])
        return (0.5 * mu * (ic - 3.0) + 0.5 * lam * dj * dj - 0.5 * mu * math.log(ic + 1.0)
                - _nh_rest(mu, lam))
    svd3(f, u, s, v, m, w)
    tr = s[0] + s[1] + s[2] - 3.0
    for i in range(3):
        for j in range(3):
            rot = u[i, 0] * v[j, 0] + u[i, 1] * v[j, 1] + u[i, 2] * v[j, 2]
            p[i, j] = 2.0 * mu * (f[i, j] - rot) + lam * tr * rot
    return (mu * ((s[0] - 1.0) ** 2 + (s[1] - 1.0) ** 2 + (s[2] - 1.0) ** 2)
            + 0.5 * lam * tr * tr)


@njit(cache=True)
def eigensystem(material, mu, lam, f, definite, scratch, tf):
    """The eigensystem of ``dP/dF`` (module docstring) in the frame of the signed SVD.

    Fills ``u``, ``s``, ``v`` (``scratch[1]`` is ``v``, ``scratch[5]`` is ``s``) with the SVD of
    ``f``, ``scratch[3]`` with the 3x3 scaling block ``d^2 Psi / ds_i ds_j`` and ``tf`` (6,) with
    the twist and flip eigenvalues of the pairs opposite ``k = 0, 1, 2`` (``tf[k]`` twist,
    ``tf[3 + k]`` flip).  With ``definite`` negative eigenvalues are clamped to 0.
    """
    u, v, m, a, q, s, w, _ = scratch
    svd3(f, u, s, v, m, w)
    if material == NEO_HOOKEAN:
        ic = s[0] * s[0] + s[1] * s[1] + s[2] * s[2]
        det = s[0] * s[1] * s[2]
        r = lam * (det - _nh_alpha(mu, lam))
        mup = mu * (1.0 - 1.0 / (ic + 1.0))
        c2 = 2.0 * mu / ((ic + 1.0) * (ic + 1.0))
        g0 = s[1] * s[2]
        g1 = s[0] * s[2]
        g2 = s[0] * s[1]
        a[0, 0] = mup + c2 * s[0] * s[0] + lam * g0 * g0
        a[1, 1] = mup + c2 * s[1] * s[1] + lam * g1 * g1
        a[2, 2] = mup + c2 * s[2] * s[2] + lam * g2 * g2
        a[0, 1] = a[1, 0] = c2 * s[0] * s[1] + lam * g0 * g1 + r * s[2]
        a[0, 2] = a[2, 0] = c2 * s[0] * s[2] + lam * g0 * g2 + r * s[1]
        a[1, 2] = a[2, 1] = c2 * s[1] * s[2] + lam * g1 * g2 + r * s[0]
        for k in range(3):  # pair k: the two indices other than k
            tf[k] = mup + r * s[k]
            tf[3 + k] = mup - r * s[k]
    else:
        tr = s[0] + s[1] + s[2] - 3.0
        for i in range(3):
            for j in range(3):
                a[i, j] = lam + (2.0 * mu if i == j else 0.0)
        num = 2.0 * lam * tr - 4.0 * mu
        # (psi_i + psi_j) / (s_i + s_j); s_i + s_j vanishes only for inverted elements
        tf[0] = 2.0 * mu + num / _nonzero(s[1] + s[2])
        tf[1] = 2.0 * mu + num / _nonzero(s[0] + s[2])
        tf[2] = 2.0 * mu + num / _nonzero(s[0] + s[1])
        tf[3] = tf[4] = tf[5] = 2.0 * mu
    if definite:
        for k in range(6):
            tf[k] = max(tf[k], 0.0)
        # Sylvester's criterion first: most blocks are definite and need no eigenvectors
        minor2 = a[0, 0] * a[1, 1] - a[0, 1] * a[0, 1]
        det = (a[0, 0] * (a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1])
               - a[0, 1] * (a[1, 0] * a[2, 2] - a[1, 2] * a[2, 0])
               + a[0, 2] * (a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]))
        if not (a[0, 0] > 0.0 and minor2 > 0.0 and det > 0.0):
            sym_project_psd3(a, w, q, m)


@njit(cache=True)
def stress_derivative(material, mu, lam, f, h, definite, scratch):
    """``dP/dF`` (Pa) into ``h`` (9, 9), indices ``3 a + b`` of ``F[a, b]`` (row-major).

    From the eigensystem in the singular values (:func:`eigensystem`); with ``definite`` the
    negative eigenvalues are clamped to 0, so that ``h`` is positive semi-definite.
    """
    u, v, _, a, _, _, _, modes = scratch
    tf = np.empty(6)
    eigensystem(material, mu, lam, f, definite, scratch, tf)
    # modes[0..2]: scaling u_i v_i^T; modes[3..5]: twist of pair k; modes[6..8]: flip
    for k in range(3):
        i = 1 if k == 0 else 0
        j = 1 if k == 2 else 2
        for x in range(3):
            for y in range(3):
                modes[k, 3 * x + y] = u[x, k] * v[y, k]
                pa = u[x, i] * v[y, j]
                pb = u[x, j] * v[y, i]
                modes[3 + k, 3 * x + y] = _SQRT_HALF * (pa - pb)
                modes[6 + k, 3 * x + y] = _SQRT_HALF * (pa + pb)
    for r1 in range(9):
        for r2 in range(r1, 9):
            acc = 0.0
            for i in range(3):
                acc += modes[i, r1] * (a[i, 0] * modes[0, r2] + a[i, 1] * modes[1, r2]
                                       + a[i, 2] * modes[2, r2])
            for k in range(3):
                acc += (tf[k] * modes[3 + k, r1] * modes[3 + k, r2]
                        + tf[3 + k] * modes[6 + k, r1] * modes[6 + k, r2])
            h[r1, r2] = acc
            h[r2, r1] = acc


@njit(cache=True, inline="always")
def _nonzero(x):
    """``x``, moved away from 0 to +-1e-12 (keeps the sign)."""
    if abs(x) >= 1e-12:
        return x
    return 1e-12 if x >= 0.0 else -1e-12
