"""Closed triangle meshes as solids: validation and exact mass properties.

:func:`check_closed_mesh` refuses what does not bound a solid (open, non-manifold, inconsistently
oriented, inverted or flat meshes), each with its own message. :func:`mass_properties` integrates
``1, x, y, z, x^2, y^2, z^2, xy, yz, zx`` over the enclosed volume exactly, by the divergence
theorem turned into sums over the triangles: Mirtich (1996, "Fast and accurate computation of
polyhedral mass properties", Journal of Graphics Tools 1(2)) in the simplification for
triangles of Eberly (2002, "Polyhedral mass properties (revisited)", Geometric Tools). The
result is exact up to round-off for any closed, outward-oriented triangle mesh; the vertices are
shifted to their mean before integrating so that a mesh far from the origin loses no digits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..validation import check_range

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["MassProperties", "check_closed_mesh", "mass_properties", "mesh_volume"]


@dataclass(frozen=True)
class MassProperties:
    """Mass properties of a solid of uniform density.

    Attributes
    ----------
    volume : float
        Enclosed volume (m^3).
    mass : float
        ``density * volume`` (kg).
    center : (3,) float64 array
        Centre of mass (m), in the mesh's coordinates.
    inertia : (3, 3) float64 array
        Inertia tensor about the centre of mass (kg m^2), in the mesh's axes:
        ``I = integral rho (|r|^2 1 - r r^T) dV``, ``r = x - center``.
    principal_moments : (3,) float64 array
        Eigenvalues of ``inertia``, ascending (kg m^2).
    principal_axes : (3, 3) float64 array
        A rotation whose columns are the principal axes (``inertia = A diag(moments) A^T``,
        ``det A = +1``).
    """

    volume: float
    mass: float
    center: np.ndarray
    inertia: np.ndarray
    principal_moments: np.ndarray
    principal_axes: np.ndarray


def check_closed_mesh(vertices: ArrayLike,
                      faces: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Validate a triangle mesh as the boundary of a solid and return it as arrays.

    Parameters
    ----------
    vertices : (V, 3) array_like
        Vertex positions (m), finite.
    faces : (F, 3) array_like of int
        Triangles as vertex indices, counter-clockwise seen from outside (normals point out).

    Returns
    -------
    vertices : (V, 3) float64 array
    faces : (F, 3) int64 array

    Raises
    ------
    ValueError
        Naming the defect: shapes or indices out of range, a triangle that repeats a vertex, an
        open mesh (an edge in one triangle), a non-manifold edge (in more than two), inconsistent
        orientation (an edge traversed twice in the same direction), inverted faces (negative
        enclosed volume) or no enclosed volume.  A vertex shared by two otherwise separate
        sheets (two solids touching at a point) is accepted: the integrals do not mind it.
    """
    try:
        v = np.array(vertices, dtype=np.float64, order="C")
    except (TypeError, ValueError):
        raise TypeError("vertices must be a (V, 3) array of numbers") from None
    if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 4:
        raise ValueError(f"vertices must have shape (V, 3) with V >= 4, got {v.shape}")
    if not np.isfinite(v).all():
        raise ValueError("vertices contain NaN or infinite values")
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] < 4 or not (
            np.issubdtype(f.dtype, np.integer)):
        raise ValueError(f"faces must be an (F, 3) integer array with F >= 4, got shape "
                         f"{f.shape} and dtype {f.dtype}")
    f = np.array(f, dtype=np.int64, order="C")
    if f.min() < 0 or f.max() >= v.shape[0]:
        raise ValueError(f"faces must index vertices in [0, {v.shape[0] - 1}], got "
                         f"[{f.min()}, {f.max()}]")
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 2] == f[:, 0])
    if repeated.any():
        raise ValueError(f"faces must use three different vertices; face "
                         f"{int(np.flatnonzero(repeated)[0])} repeats one")
    n = v.shape[0]
    directed = np.stack([f, np.roll(f, -1, axis=1)], axis=-1).reshape(-1, 2)
    lo = directed.min(axis=1)
    hi = directed.max(axis=1)
    _, counts = np.unique(lo * n + hi, return_counts=True)
    if (counts == 1).any():
        raise ValueError(f"the mesh is open: {int((counts == 1).sum())} edges belong to one "
                         f"triangle only (a closed mesh has every edge in exactly two)")
    if (counts > 2).any():
        raise ValueError(f"the mesh is non-manifold: {int((counts > 2).sum())} edges belong to "
                         f"more than two triangles")
    _, dcounts = np.unique(directed[:, 0] * n + directed[:, 1], return_counts=True)
    if (dcounts > 1).any():
        raise ValueError(f"the faces are inconsistently oriented: {int((dcounts > 1).sum())} "
                         f"edges are traversed twice in the same direction (flip the faces "
                         f"whose normals point inwards)")
    volume = mesh_volume(v, f)
    extent = float(np.ptp(v, axis=0).max())
    if abs(volume) <= 1e-12 * extent ** 3:
        raise ValueError(f"the mesh encloses no volume (|V| = {abs(volume):.3g} m^3 for an "
                         f"extent of {extent:.3g} m): it is flat or degenerate")
    if volume < 0.0:
        raise ValueError(f"the faces are inverted (enclosed volume {volume:.6g} m^3 < 0): their "
                         f"normals point inwards; reverse every face's vertex order")
    return v, f


def mesh_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Signed volume (m^3) enclosed by a closed triangle mesh (positive for outward normals):
    ``sum (a . (b x c)) / 6`` over the triangles, with the vertices shifted to their mean."""
    v = np.asarray(vertices, dtype=np.float64)
    v = v - v.mean(axis=0)
    a, b, c = v[faces[:, 0]], v[faces[:, 1]], v[faces[:, 2]]
    return float(np.einsum("ij,ij->", a, np.cross(b, c))) / 6.0


def _subexpressions(w0, w1, w2):
    """Eberly's (2002) sums of one coordinate over a triangle's vertices."""
    temp0 = w0 + w1
    f1 = temp0 + w2
    temp1 = w0 * w0
    temp2 = temp1 + w1 * temp0
    f2 = temp2 + w2 * f1
    f3 = w0 * temp1 + w1 * temp2 + w2 * f2
    g0 = f2 + w0 * (f1 + w0)
    g1 = f2 + w1 * (f1 + w1)
    g2 = f2 + w2 * (f1 + w2)
    return f1, f2, f3, g0, g1, g2


def mass_properties(vertices: ArrayLike, faces: ArrayLike, density: float = 1.0) -> MassProperties:
    """Volume, mass, centre of mass and inertia tensor of the solid bounded by a mesh.

    Parameters
    ----------
    vertices : (V, 3) array_like
        Vertex positions (m).
    faces : (F, 3) array_like of int
        Outward-oriented triangles (validated by :func:`check_closed_mesh`).
    density : float
        Uniform density (kg/m^3), > 0 and finite.

    Returns
    -------
    MassProperties

    Notes
    -----
    With ``d = (b - a) x (c - a)`` the (unnormalised) normal of triangle ``abc``, the
    divergence theorem gives, e.g., ``integral x dV = sum d_x (a_x^2 + b_x^2 + c_x^2 + a_x b_x
    + b_x c_x + c_x a_x) / 24``; Eberly (2002) writes all ten integrals with shared
    subexpressions (``f1, f2, f3, g0, g1, g2`` here).  The inertia about the centre follows by
    the parallel-axis theorem.
    """
    v, f = check_closed_mesh(vertices, faces)
    density = check_range("density", density, 0.0, math.inf, low_inclusive=False,
                          high_inclusive=False)
    shift = v.mean(axis=0)
    v = v - shift
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    d = np.cross(b - a, c - a)
    fx = _subexpressions(a[:, 0], b[:, 0], c[:, 0])
    fy = _subexpressions(a[:, 1], b[:, 1], c[:, 1])
    fz = _subexpressions(a[:, 2], b[:, 2], c[:, 2])
    d0, d1, d2 = d[:, 0], d[:, 1], d[:, 2]
    one = (d0 * fx[0]).sum() / 6.0
    first = np.array([(d0 * fx[1]).sum(), (d1 * fy[1]).sum(), (d2 * fz[1]).sum()]) / 24.0
    second = np.array([(d0 * fx[2]).sum(), (d1 * fy[2]).sum(), (d2 * fz[2]).sum()]) / 60.0
    xy = (d0 * (a[:, 1] * fx[3] + b[:, 1] * fx[4] + c[:, 1] * fx[5])).sum() / 120.0
    yz = (d1 * (a[:, 2] * fy[3] + b[:, 2] * fy[4] + c[:, 2] * fy[5])).sum() / 120.0
    zx = (d2 * (a[:, 0] * fz[3] + b[:, 0] * fz[4] + c[:, 0] * fz[5])).sum() / 120.0
    volume = float(one)
    cm = first / volume
    # second moments about the centre of mass (per unit density)
    cxx = second[0] - volume * cm[0] * cm[0]
    cyy = second[1] - volume * cm[1] * cm[1]
    czz = second[2] - volume * cm[2] * cm[2]
    cxy = xy - volume * cm[0] * cm[1]
    cyz = yz - volume * cm[1] * cm[2]
    czx = zx - volume * cm[2] * cm[0]
    inertia = density * np.array([[cyy + czz, -cxy, -czx],
                                  [-cxy, cxx + czz, -cyz],
                                  [-czx, -cyz, cxx + cyy]])
    moments, axes = np.linalg.eigh(inertia)
    if np.linalg.det(axes) < 0.0:
        axes[:, 2] = -axes[:, 2]
    if moments[0] <= 0.0:
        raise ValueError("the mesh's inertia tensor is not positive definite (a degenerate "
                         "solid)")
    return MassProperties(volume=volume, mass=density * volume, center=cm + shift,
                          inertia=inertia, principal_moments=moments, principal_axes=axes)
