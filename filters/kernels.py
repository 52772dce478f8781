"""Every kernel of the package, in one place: SPH smoothing kernels and surface profiles.

Two families, each with its registry of names and the integer ids Numba code dispatches on:

* **Smoothing kernels** :data:`SMOOTHING_KERNELS` (the SPH solvers; :func:`kernel_id`): each has
  compact support of radius ``h`` (the *support radius*, the convention of SPlisHSPlasH:
  ``W(r, h) = 0`` for ``r >= h``), is normalised so that its integral over R^3 is 1, and comes
  with its radial derivative ``dW/dr`` and its gradient ``grad W(r_vec) = dW/dr * r_vec / |r_vec|``.
* **Surface profiles** :data:`SPLAT_KERNELS` (the metaball splats; :func:`splat_kernel_id`):
  functions ``K(q^2)`` of the squared distance over the support radius, with peak 1 at ``q = 0``
  and zero for ``q >= 1``, summed (or, for ``zhu_bridson``, averaged) into implicit fields.

The cubic spline of Monaghan (1992) serves both: normalised as :func:`cubic_w` /
:func:`cubic_dw`, and with peak 1 as :func:`spline_profile` (of ``q^2``) and its branch-free form
:func:`spline_row` (of ``q``, for loops the compiler vectorises).

Smoothing kernels
-----------------
``cubic``
    Cubic B-spline of Monaghan & Lattanzio (1985) / Monaghan (1992) "Smoothed particle
    hydrodynamics", Annu. Rev. Astron. Astrophys. 30, written for support ``h`` (the usual
    smoothing length is ``h / 2``).
``wendland``
    Wendland C2 (Wendland 1995; in SPH: Dehnen & Aly 2012), ``(1 - q)^4 (1 + 4 q)``.
``poly6``, ``spiky``, ``viscosity``
    Müller, Charypar & Gross (2003) "Particle-based fluid simulation for interactive
    applications", SCA.  poly6 for densities, spiky for pressure gradients (its gradient does not
    vanish at ``r = 0``), viscosity for its Laplacian ``45 / (pi h^6) (h - r)``.
``cohesion``, ``adhesion``
    Akinci, Akinci & Teschner (2013) "Versatile surface tension and adhesion for SPH fluids",
    ACM TOG 32(6): a spline that repels below ``h / 2`` and attracts between ``h / 2`` and ``h``
    (not normalised; it is a force profile, not a smoothing kernel), and the adhesion profile.

Surface profiles
----------------
``blobby``
    Blinn (1982), "A generalization of algebraic surface drawing": a Gaussian ``exp(-a q^2)``,
    shifted and scaled to vanish at ``q = 1``: ``(exp(-a q^2) - exp(-a)) / (1 - exp(-a))``
    with ``a`` the *blobbiness*.
``metaball``
    Wyvill, McPheeters & Wyvill (1986), "Data structure for soft objects": the "soft object"
    polynomial ``1 - 22/9 q^2 + 17/9 q^4 - 4/9 q^6``, which is 1/2 at ``q = 1/2``.
``sph``
    The cubic spline with peak 1; the splat sums it into the SPH volume (colour) field
    ``sum_j V_j W_j`` (Löschner et al. 2023).
``zhu_bridson``
    Zhu & Bridson (2005), "Animating sand as a fluid": the weights ``(1 - q^2)^3`` of a weighted
    mean centre and radius.

The scalar functions (``cubic_w(r, h)``, ``spline_profile(q2)``, ...) are ``@njit`` and meant
to be called inside other Numba kernels; the array functions (:func:`kernel_value`,
:func:`kernel_gradient`, :func:`kernel_laplacian`) evaluate many distances at once.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = [
    "SMOOTHING_KERNELS",
    "kernel_id",
    "SPLAT_KERNELS",
    "SPLAT_DEFAULTS",
    "ZHU_BRIDSON",
    "splat_kernel_id",
    "spline_profile", "spline_row",
    "splat_profile", "splat_row_profile",
    "lone_particle_radius",
    "cubic_w", "cubic_dw", "kernel_w_dw",
    "wendland_w", "wendland_dw",
    "poly6_w", "poly6_dw", "poly6_laplacian",
    "spiky_w", "spiky_dw",
    "viscosity_w", "viscosity_dw", "viscosity_laplacian",
    "cohesion_c", "adhesion_a",
    "kernel_w", "kernel_dw",
    "kernel_value", "kernel_gradient", "kernel_laplacian",
]

#: Names of the normalised smoothing kernels and their integer ids used inside Numba code.
SMOOTHING_KERNELS = {"cubic": 0, "wendland": 1, "poly6": 2, "spiky": 3, "viscosity": 4}

_PI = math.pi


def kernel_id(name: str) -> int:
    """Integer id of the smoothing kernel ``name`` (one of :data:`SMOOTHING_KERNELS`), for Numba
    dispatch."""
    if name not in SMOOTHING_KERNELS:
        options = ", ".join(repr(k) for k in SMOOTHING_KERNELS)
        raise ValueError(f"kernel must be one of {options}; got {name!r}")
    return SMOOTHING_KERNELS[name]


# --------------------------------------------------------------------------------------------
# Cubic spline (Monaghan 1992), support h.
# --------------------------------------------------------------------------------------------
@njit(cache=True, inline="always", error_model="numpy")
def cubic_w(r, h):
    """Cubic spline ``W(r, h)`` (1/m^3) for distance ``r`` (m) and support radius ``h`` (m)."""
    q = r / h
    k = 8.0 / (_PI * h * h * h)
    if q <= 0.5:
        return k * (6.0 * q * q * q - 6.0 * q * q + 1.0)
    if q < 1.0:
        t = 1.0 - q
        return k * 2.0 * t * t * t
    return 0.0


@njit(cache=True, inline="always", error_model="numpy")
def cubic_dw(r, h):
    """Radial derivative ``dW/dr`` (1/m^4) of :func:`cubic_w`."""
    q = r / h
    c = 48.0 / (_PI * h * h * h * h)
    if q <= 0.5:
        return c * q * (3.0 * q - 2.0)
    if q < 1.0:
        t = 1.0 - q
        return -c * t * t
    return 0.0


# --------------------------------------------------------------------------------------------
# Wendland C2, support h.
# --------------------------------------------------------------------------------------------
@njit(cache=True, inline="always", error_model="numpy")
def wendland_w(r, h):
    """Wendland C2 kernel ``21 / (2 pi h^3) (1 - q)^4 (1 + 4 q)``, ``q = r / h`` (1/m^3)."""
    q = r / h
    if q >= 1.0:
        return 0.0
    t = 1.0 - q
    t2 = t * t
    return 21.0 / (2.0 * _PI * h * h * h) * t2 * t2 * (1.0 + 4.0 * q)


@njit(cache=True, inline="always", error_model="numpy")
def wendland_dw(r, h):
    """Radial derivative of :func:`wendland_w`: ``-21 / (2 pi h^4) 20 q (1 - q)^3`` (1/m^4)."""
    q = r / h
    if q >= 1.0:
        return 0.0
    t = 1.0 - q
    return -21.0 / (2.0 * _PI * h * h * h * h) * 20.0 * q * t * t * t


# --------------------------------------------------------------------------------------------
# Müller et al. 2003.
# --------------------------------------------------------------------------------------------
@njit(cache=True, inline="always", error_model="numpy")
def poly6_w(r, h):
    """Poly6 kernel ``315 / (64 pi h^9) (h^2 - r^2)^3`` (1/m^3) (Müller et al. 2003)."""
    if r >= h:
        return 0.0
    d = h * h - r * r
    return 315.0 / (64.0 * _PI * h ** 9) * d * d * d


@njit(cache=True, inline="always", error_model="numpy")
def poly6_dw(r, h):
    """Radial derivative of :func:`poly6_w`: ``-945 / (32 pi h^9) r (h^2 - r^2)^2``."""
    if r >= h:
        return 0.0
    d = h * h - r * r
    return -945.0 / (32.0 * _PI * h ** 9) * r * d * d


@njit(cache=True, inline="always", error_model="numpy")
def poly6_laplacian(r, h):
    """Laplacian of :func:`poly6_w`: ``-945 / (32 pi h^9) (h^2 - r^2)(3 h^2 - 7 r^2)`` (1/m^5)."""
    if r >= h:
        return 0.0
    return -945.0 / (32.0 * _PI * h ** 9) * (h * h - r * r) * (3.0 * h * h - 7.0 * r * r)


@njit(cache=True, inline="always", error_model="numpy")
def spiky_w(r, h):
    """Spiky kernel ``15 / (pi h^6) (h - r)^3`` (1/m^3) (Müller et al. 2003)."""
    if r >= h:
        return 0.0
    d = h - r
    return 15.0 / (_PI * h ** 6) * d * d * d


@njit(cache=True, inline="always", error_model="numpy")
def spiky_dw(r, h):
    """Radial derivative of :func:`spiky_w`: ``-45 / (pi h^6) (h - r)^2`` (1/m^4)."""
    if r >= h:
        return 0.0
    d = h - r
    return -45.0 / (_PI * h ** 6) * d * d


@njit(cache=True, inline="always", error_model="numpy")
def viscosity_w(r, h):
    """Viscosity kernel of Müller et al. (2003) (1/m^3); singular like ``1 / r`` at ``r = 0``.

    ``15 / (2 pi h^3) (-r^3 / (2 h^3) + r^2 / h^2 + h / (2 r) - 1)`` for ``0 < r < h``.
    """
    if r >= h:
        return 0.0
    if r <= 0.0:
        return np.inf
    return 15.0 / (2.0 * _PI * h ** 3) * (
        -r * r * r / (2.0 * h ** 3) + r * r / (h * h) + h / (2.0 * r) - 1.0
    )


@njit(cache=True, inline="always", error_model="numpy")
def viscosity_dw(r, h):
    """Radial derivative of :func:`viscosity_w` (1/m^4)."""
    if r >= h or r <= 0.0:
        return 0.0
    return 15.0 / (2.0 * _PI * h ** 3) * (
        -3.0 * r * r / (2.0 * h ** 3) + 2.0 * r / (h * h) - h / (2.0 * r * r)
    )


@njit(cache=True, inline="always", error_model="numpy")
def viscosity_laplacian(r, h):
    """Laplacian of :func:`viscosity_w`: ``45 / (pi h^6) (h - r)`` (1/m^5)."""
    if r >= h:
        return 0.0
    return 45.0 / (_PI * h ** 6) * (h - r)


# --------------------------------------------------------------------------------------------
# Akinci et al. 2013 force profiles.
# --------------------------------------------------------------------------------------------
@njit(cache=True, inline="always", error_model="numpy")
def cohesion_c(r, h):
    """Cohesion spline ``C(r)`` of Akinci et al. (2013) (1/m^3).

    ``32 / (pi h^9) * (h - r)^3 r^3`` for ``h/2 < r <= h`` and
    ``32 / (pi h^9) * (2 (h - r)^3 r^3 - h^6 / 64)`` for ``0 < r <= h/2``: negative (repulsive)
    close in, positive (attractive) further out, zero beyond ``h``.
    """
    if r >= h or r <= 0.0:
        return 0.0
    k = 32.0 / (_PI * h ** 9)
    a = (h - r) * r
    a3 = a * a * a
    if 2.0 * r > h:
        return k * a3
    return k * (2.0 * a3 - h ** 6 / 64.0)


@njit(cache=True, inline="always", error_model="numpy")
def adhesion_a(r, h):
    """Adhesion profile ``A(r)`` of Akinci et al. (2013):
    ``0.007 / h^3.25 (-4 r^2/h + 6 r - 2 h)^(1/4)``
    for ``h/2 < r <= h``, zero elsewhere."""
    if r >= h or 2.0 * r <= h:
        return 0.0
    s = -4.0 * r * r / h + 6.0 * r - 2.0 * h
    if s <= 0.0:
        return 0.0
    return 0.007 / h ** 3.25 * s ** 0.25


# --------------------------------------------------------------------------------------------
# Dispatch by id (for code that takes the kernel as a parameter).
# --------------------------------------------------------------------------------------------
@njit(cache=True, inline="always", error_model="numpy")
def kernel_w(kind, r, h):
    """Value of kernel ``kind`` (an id of :data:`SMOOTHING_KERNELS`) at distance ``r``."""
    if kind == 0:
        return cubic_w(r, h)
    if kind == 1:
        return wendland_w(r, h)
    if kind == 2:
        return poly6_w(r, h)
    if kind == 3:
        return spiky_w(r, h)
    return viscosity_w(r, h)


@njit(cache=True, inline="always", error_model="numpy")
def kernel_dw(kind, r, h):
    """Radial derivative ``dW/dr`` of kernel ``kind`` at distance ``r``."""
    if kind == 0:
        return cubic_dw(r, h)
    if kind == 1:
        return wendland_dw(r, h)
    if kind == 2:
        return poly6_dw(r, h)
    if kind == 3:
        return spiky_dw(r, h)
    return viscosity_dw(r, h)


@njit(cache=True, inline="always", error_model="numpy")
def kernel_w_dw(kind, r, h):
    """``(W, dW/dr)`` of kernel ``kind`` at distance ``r <= h`` in one evaluation.

    The cubic spline is evaluated without a branch on ``q = r / h``, as ``k (2 t^3 - 8 s^3)``
    with ``t = 1 - q`` and ``s = max(1/2 - q, 0)`` (the same polynomial pieces as
    :func:`cubic_w`), which keeps the hot loops of the SPH solvers free of unpredictable
    branches.  Other kernels fall back to :func:`kernel_w` and :func:`kernel_dw`.
    """
    if kind == 0:
        q = r / h
        t = 1.0 - q
        s = max(0.5 - q, 0.0)
        k = 8.0 / (_PI * h * h * h)
        return (k * (2.0 * t * t * t - 8.0 * s * s * s),
                6.0 * k / h * (4.0 * s * s - t * t))
    return _kernel_w_dw_call(kind, r, h)


@njit(cache=True, error_model="numpy")
def _kernel_w_dw_call(kind, r, h):
    # a call, not inlined: the other kernels' ten bodies inlined into every loop that evaluates
    # kernels made Numba compile the SPH neighbourhood pass for 12 s instead of 3 s
    return kernel_w(kind, r, h), kernel_dw(kind, r, h)


@njit(parallel=True, cache=True, error_model="numpy")
def _values(kind, r, h, out):
    for i in prange(r.shape[0]):
        out[i] = kernel_w(kind, r[i], h)


@njit(parallel=True, cache=True, error_model="numpy")
def _gradients(kind, d, h, out):
    for i in prange(d.shape[0]):
        r = math.sqrt(d[i, 0] * d[i, 0] + d[i, 1] * d[i, 1] + d[i, 2] * d[i, 2])
        if r > 0.0:
            f = kernel_dw(kind, r, h) / r
            out[i, 0] = f * d[i, 0]
            out[i, 1] = f * d[i, 1]
            out[i, 2] = f * d[i, 2]
        else:
            out[i, 0] = 0.0
            out[i, 1] = 0.0
            out[i, 2] = 0.0


@njit(parallel=True, cache=True, error_model="numpy")
def _laplacians(kind, r, h, out):
    for i in prange(r.shape[0]):
        if kind == 2:
            out[i] = poly6_laplacian(r[i], h)
        else:
            out[i] = viscosity_laplacian(r[i], h)


def _check_h(h):
    if isinstance(h, bool) or not isinstance(h, (int, float, np.floating, np.integer)):
        raise TypeError(f"h must be a real number (m), got {h!r}")
    h = float(h)
    if not (math.isfinite(h) and h > 0.0):
        raise ValueError(f"h must be in (0, inf) (m), got {h!r}")
    return h


def kernel_value(name: str, r: ArrayLike, h: float) -> np.ndarray:
    """Kernel values for an array of distances.

    Parameters
    ----------
    name : str
        One of :data:`SMOOTHING_KERNELS`.
    r : array_like of float, any shape
        Distances (m), >= 0.
    h : float
        Support radius (m), > 0.

    Returns
    -------
    ndarray of float64, same shape as ``r``
        ``W(r, h)`` (1/m^3).
    """
    kind = kernel_id(name)
    h = _check_h(h)
    r = np.asarray(r, dtype=np.float64)
    flat = np.ascontiguousarray(r.ravel())
    out = np.empty_like(flat)
    _values(kind, flat, h, out)
    return out.reshape(r.shape)


def kernel_gradient(name: str, d: ArrayLike, h: float) -> np.ndarray:
    """Kernel gradients ``grad W(d)`` for an array of difference vectors ``d = x_i - x_j``.

    Parameters
    ----------
    name : str
        One of :data:`SMOOTHING_KERNELS`.
    d : (M, 3) array_like
        Difference vectors (m).
    h : float
        Support radius (m).

    Returns
    -------
    (M, 3) float64 ndarray
        ``dW/dr * d / |d|`` (1/m^4); zero where ``d = 0``.
    """
    kind = kernel_id(name)
    h = _check_h(h)
    d = np.ascontiguousarray(d, dtype=np.float64)
    if d.ndim != 2 or d.shape[1] != 3:
        raise ValueError(f"d must have shape (M, 3), got {d.shape}")
    out = np.empty_like(d)
    _gradients(kind, d, h, out)
    return out


def kernel_laplacian(name: str, r: ArrayLike, h: float) -> np.ndarray:
    """Laplacian of the ``poly6`` or ``viscosity`` kernel at distances ``r`` (1/m^5).

    Parameters
    ----------
    name : {"poly6", "viscosity"}
        The kernels whose Laplacians SPH uses (Müller et al. 2003).
    r : array_like of float
        Distances (m).
    h : float
        Support radius (m).
    """
    if name not in ("poly6", "viscosity"):
        raise ValueError(f"name must be one of 'poly6', 'viscosity' for a Laplacian; got {name!r}")
    kind = kernel_id(name)
    h = _check_h(h)
    r = np.asarray(r, dtype=np.float64)
    flat = np.ascontiguousarray(r.ravel())
    out = np.empty_like(flat)
    _laplacians(kind, flat, h, out)
    return out.reshape(r.shape)


# --------------------------------------------------------------------------------------------
# Surface profiles: functions of q^2 with peak 1 at q = 0, zero for q >= 1.
# --------------------------------------------------------------------------------------------
#: Names of the surface profiles, in the order of their Numba ids.
SPLAT_KERNELS = ("blobby", "metaball", "sph", "zhu_bridson")
#: Numba id of the ``zhu_bridson`` profile (the one that is averaged, not summed).
ZHU_BRIDSON = 3
#: Default ``support`` (support radius / particle radius) and ``iso`` per surface profile.
SPLAT_DEFAULTS = {
    "blobby": {"support": 2.0, "iso": 0.5},
    "metaball": {"support": 2.0, "iso": 0.5},
    "sph": {"support": 4.0, "iso": 0.6},
    "zhu_bridson": {"support": 2.0, "iso": 0.0},
}


def splat_kernel_id(name: str) -> int:
    """Integer id of the surface profile ``name`` (one of :data:`SPLAT_KERNELS`)."""
    if name not in SPLAT_KERNELS:
        options = ", ".join(repr(k) for k in SPLAT_KERNELS)
        raise ValueError(f"kernel must be one of {options}; got {name!r}")
    return SPLAT_KERNELS.index(name)


# The constants below are float32: with float32 arguments the arithmetic stays in float32 (the
# splats' SIMD loops), with float64 arguments it is float64 (exact values, the same operations).
@njit(cache=True, inline="always")
def spline_profile(q2):
    """Monaghan's cubic spline with peak 1 and support 1, as a function of ``q^2``.

    ``1 - 6 q^2 + 6 q^3`` for ``q < 1/2``, ``2 (1 - q)^3`` up to 1, 0 beyond (``q2`` is clamped
    to 1). Float32 in, float32 out; float64 in, float64 out.
    """
    q2 = min(q2, np.float32(1.0))
    q = math.sqrt(q2)
    inner = np.float32(1.0) - np.float32(6.0) * q2 + np.float32(6.0) * q2 * q
    t = np.float32(1.0) - q
    outer = np.float32(2.0) * t * t * t
    return inner if q < np.float32(0.5) else outer


@njit(cache=True, inline="always")
def spline_row(q):
    """:func:`spline_profile` without branches, of ``q`` (not ``q^2``), ``0 <= q``:
    ``2 (1 - q)_+^3 - 8 (1/2 - q)_+^3``, for loops the compiler vectorises."""
    e = max(np.float32(1.0) - q, np.float32(0.0))
    f = max(np.float32(0.5) - q, np.float32(0.0))
    return np.float32(2.0) * e * e * e - np.float32(8.0) * f * f * f


@njit(cache=True, inline="always", fastmath=True)
def splat_profile(kernel, q2, blob_a, blob_e):
    """Surface profile ``kernel`` (a :func:`splat_kernel_id`) at ``q^2`` (clamped to 1).

    ``blob_a`` is the blobbiness ``a`` and ``blob_e = exp(-a)`` (used by ``blobby`` only).
    """
    q2 = min(q2, np.float32(1.0))
    if kernel == 2:
        return spline_profile(q2)
    if kernel == 1:
        return np.float32(1.0) + q2 * (np.float32(-22.0 / 9.0) + q2 * (
            np.float32(17.0 / 9.0) - np.float32(4.0 / 9.0) * q2))
    if kernel == 0:
        return (math.exp(-blob_a * q2) - blob_e) / (np.float32(1.0) - blob_e)
    t = np.float32(1.0) - q2
    return t * t * t


@njit(cache=True, inline="always", fastmath=True)
def splat_row_profile(kernel, q2, blob_a, blob_e):
    """Branch-free :func:`splat_profile` of the summed profiles (``sph``, ``metaball``,
    ``blobby``) for SIMD loops; ``q2`` already clamped to <= 1."""
    if kernel == 2:
        return spline_row(np.sqrt(q2))
    if kernel == 1:
        return np.float32(1.0) + q2 * (np.float32(-22.0 / 9.0) + q2 * (
            np.float32(17.0 / 9.0) - np.float32(4.0 / 9.0) * q2))
    return (np.exp(-blob_a * q2) - blob_e) / (np.float32(1.0) - blob_e)


def _check_positive(name, value, high=math.inf):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise TypeError(f"{name} must be a real number, got {value!r}")
    value = float(value)
    if not (0.0 < value <= high):
        raise ValueError(f"{name} must be in (0, {high:g}], got {value!r}")
    return value


def lone_particle_radius(kernel: str = "sph", radius: float = 1.0, *,
                         support_r: float | None = None,
                         iso: float | None = None, blobbiness: float = 4.0) -> float:
    """Radius (m) of the iso-surface of one isolated particle, from the profile alone.

    For the summed profiles it is ``q* h`` with ``K(q*) = iso`` (for ``sph`` the density of a
    lone particle is ``m W(0)``, so ``f = W(r) / W(0)``); for ``zhu_bridson`` it is the particle
    radius. Solved by bisection to machine precision.

    Parameters
    ----------
    kernel : str
        One of :data:`SPLAT_KERNELS`.
    radius : float
        Particle radius ``r`` (m), > 0.
    support_r : float, optional
        Support radius over particle radius, in (0, 1000]; default per profile
        (:data:`SPLAT_DEFAULTS`).
    iso : float, optional
        Iso value of the summed field, > 0; default per profile.
    blobbiness : float
        ``a`` of the blobby profile, in (0, 100].

    Returns
    -------
    float
        The iso-surface radius (m); 0 if ``iso >= 1`` (no surface).
    """
    kid = splat_kernel_id(kernel)
    radius = _check_positive("radius", radius)
    support_r = SPLAT_DEFAULTS[kernel]["support"] if support_r is None else support_r
    support_r = _check_positive("support_r", support_r, 1e3)
    iso = SPLAT_DEFAULTS[kernel]["iso"] if iso is None else iso
    blobbiness = _check_positive("blobbiness", blobbiness, 100.0)
    if kernel == "zhu_bridson":
        return radius
    iso = _check_positive("iso", iso)
    if iso >= 1.0:
        return 0.0
    e = math.exp(-blobbiness)
    lo, hi = 0.0, 1.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if splat_profile(kid, mid * mid, blobbiness, e) > iso:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi) * support_r * radius
