"""Boundary particles for SPH walls and obstacles (Akinci et al. 2012), without density bias.

Akinci, Ihmsen, Akinci, Solenthaler & Teschner (2012) "Versatile rigid-fluid coupling for
incompressible SPH" (ACM TOG 31(4)) represent a solid by particles ``b`` that contribute
``rho0 * V_b * W(x_i - x_b)`` to a fluid particle's density, with ``V_b = 1 / sum_k W(x_b - x_k)``
over the boundary particles ``k``.  With one layer of samples that volume overestimates what a
wall contributes (measured here: +6 % density at a floor, +15 % in corners), enough to blow up a
stiff WCSPH at t = 0.  This module offers two samplings without that bias:

:func:`box_boundary`
    Several layers (``ceil(h / spacing)``) of lattice particles outside the faces of a box, each
    with the *fluid's own lattice volume*, so that a fluid particle on the fluid lattice next to a
    wall or in a corner sees exactly the neighbourhood it would see in the bulk: rest density.
:func:`mesh_boundary`
    The same lattice continued into any closed triangle mesh (vertices and faces as arrays):
    its outer layers, a kernel support deep, each particle with the fluid's lattice volume.

Both return :class:`BoundaryParticles` whose ``volumes`` are SPH volumes (m^3): a boundary
particle adds ``rho0 * volumes[b] * W`` to a density.  Each particle also carries the normal of
the surface it samples (the liquid groups boundary particles by it to keep fluid particles off
every wall of a corner, :mod:`filters.sph.dfsph`), a velocity (moving walls and bodies, see
:meth:`filters.sph.SPHLiquid.move_boundary`) and a friction factor (0: a free-slip wall).
:func:`boundary_volumes` gives the volumes of any sampled surface, e.g. of a body that deforms.
:func:`lattice_volume` is the volume that
makes a perfect fluid lattice of the given spacing have rest density.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..geometry import Box
from ..kernels import kernel_id, kernel_w
from ..neighbors import NeighborSearch
from ..validation import check_finite_vector, check_int, check_range

if TYPE_CHECKING:
    from collections.abc import Iterable

    from numpy.typing import ArrayLike

__all__ = ["BoundaryParticles", "lattice_volume", "box_boundary", "mesh_boundary",
           "boundary_volumes", "concatenate_boundaries", "BOX_FACES"]

#: Names of the faces of :func:`box_boundary`'s tank, for its ``free_slip`` argument.
BOX_FACES = ("x-", "x+", "y-", "y+", "z-", "z+")


@dataclass(frozen=True)
class BoundaryParticles:
    """Boundary particles: samples of walls or bodies that the liquid cannot enter.

    Parameters
    ----------
    points : (M, 3) array_like
        Positions (m).
    volumes : (M,) array_like
        SPH volumes (m^3), > 0; a boundary particle contributes ``rho0 * volumes[b] * W`` to a
        density.
    normals : (M, 3) array_like, optional
        Unit normal of the surface each particle samples (either orientation), or zeros where
        none is known.  Default: zeros.
    velocities : (M, 3) array_like, optional
        Velocities (m/s) of the surface (a moving wall or body); default zeros.
    friction : (M,) array_like, optional
        Factor >= 0 on the liquid's boundary viscosity at each particle: 1 (default) a no-slip
        wall with the liquid's ``boundary_viscosity``, 0 a free-slip wall.

    Notes
    -----
    The arrays are copied and made read-only.
    """

    points: np.ndarray
    volumes: np.ndarray
    normals: np.ndarray | None = None
    velocities: np.ndarray | None = None
    friction: np.ndarray | None = None

    def __post_init__(self):
        p = np.array(self.points, dtype=np.float64, order="C")
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"points must have shape (M, 3), got {p.shape}")
        m = p.shape[0]
        v = np.array(self.volumes, dtype=np.float64, order="C")
        if v.shape != (m,):
            raise ValueError(f"volumes must have shape ({m},), got {v.shape}")
        if not (np.isfinite(p).all() and np.isfinite(v).all() and (v > 0).all()):
            raise ValueError("boundary points must be finite and volumes finite and > 0")
        arrays = {"points": p, "volumes": v}
        for name, default in (("normals", 0.0), ("velocities", 0.0)):
            a = getattr(self, name)
            a = (np.full((m, 3), default) if a is None
                 else np.array(a, dtype=np.float64, order="C"))
            if a.shape != (m, 3) or not np.isfinite(a).all():
                raise ValueError(f"{name} must be a finite ({m}, 3) array, got shape {a.shape}")
            arrays[name] = a
        n = arrays["normals"]
        length = np.sqrt((n * n).sum(axis=1))
        if (length > 0).any() and np.abs(length[length > 0] - 1.0).max() > 1e-6:
            raise ValueError("normals must be unit vectors (or zero where unknown)")
        f = (np.ones(m) if self.friction is None
             else np.array(self.friction, dtype=np.float64, order="C"))
        if f.shape != (m,) or not (np.isfinite(f).all() and (f >= 0).all()):
            raise ValueError(f"friction must be a finite ({m},) array of values >= 0")
        arrays["friction"] = f
        for name, a in arrays.items():
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @property
    def n_points(self) -> int:
        """Number of boundary particles ``M``."""
        return self.points.shape[0]


def concatenate_boundaries(*parts: BoundaryParticles) -> BoundaryParticles:
    """Join several :class:`BoundaryParticles` (e.g. a tank and an obstacle) into one, in order
    (the particles of ``parts[1]`` follow those of ``parts[0]``, and so on), with their
    normals, velocities and friction factors."""
    if not parts:
        return BoundaryParticles(np.zeros((0, 3)), np.zeros(0))
    return BoundaryParticles(*(np.concatenate([getattr(p, name) for p in parts])
                               for name in ("points", "volumes", "normals", "velocities",
                                            "friction")))


def lattice_volume(spacing: float, support_m: float, kernel: str = "cubic") -> float:
    """Volume ``1 / sum_j W(x_j)`` over a cubic lattice of the given spacing (m^3).

    With masses ``rho0 * lattice_volume`` a fluid on this lattice has density ``rho0`` exactly
    (the kernel's lattice sum differs from its integral by up to a few percent).

    Parameters
    ----------
    spacing : float
        Lattice spacing (m).
    support_m : float
        Kernel support radius ``h`` (m).
    kernel : str
        Kernel name, see :data:`filters.kernels.SMOOTHING_KERNELS`.
    """
    spacing = check_range("spacing", spacing, 0.0, math.inf, low_inclusive=False)
    support = check_range("support_m", support_m, 0.0, math.inf, low_inclusive=False)
    return _lattice_sum_volume(np.full(3, spacing), support, kernel_id(kernel))


@njit(cache=True)
def _sum_w(kind, r, h):
    s = 0.0
    for k in range(r.shape[0]):
        s += kernel_w(kind, r[k], h)
    return s


def _axis_coords(lo, hi, spacing, layers):
    """Coordinates along one axis: inner samples at cell centres, ``layers`` outside each end."""
    length = hi - lo
    n = max(1, int(round(length / spacing)))
    step = length / n
    inner = lo + (np.arange(n) + 0.5) * step
    below = lo - (np.arange(layers)[::-1] + 0.5) * spacing
    above = hi + (np.arange(layers) + 0.5) * spacing
    coords = np.concatenate([below, inner, above])
    widths = np.concatenate([np.full(layers, spacing), np.full(n, step), np.full(layers, spacing)])
    return coords, widths


def box_boundary(lower: ArrayLike, upper: ArrayLike | None = None, spacing: float | None = None, *,
                 support_factor: float = 2.0, kernel: str = "cubic", layers: int | None = None,
                 open_top: bool = False, free_slip: Iterable[str] = ()) -> BoundaryParticles:
    """Boundary particles in layers outside the walls of the box ``[lower, upper]``.

    The fluid lives inside the box.  Samples sit on the fluid lattice continued through the walls
    (first layer ``spacing / 2`` outside each face), so a fluid block sampled at cell centres of
    the same lattice (``lower + (i + 1/2) spacing``) has rest density at the walls and corners.

    Parameters
    ----------
    lower, upper : sequence of 3 float
        Inner corners of the tank (m), ``upper > lower`` component-wise; or ``lower`` a
        :class:`filters.geometry.Box` (the tank's inner box) and ``upper`` omitted.
    spacing : float
        Particle spacing (m), > 0.
    support_factor : float
        Kernel support radius as a multiple of ``spacing`` (default 2, as in SPlisHSPlasH).
    kernel : str
        Kernel used for the lattice volume.
    layers : int, optional
        Number of layers; default ``ceil(support_factor)``, which gives full kernel support.
    open_top : bool
        Leave out the lid (the face at ``upper[2]``).
    free_slip : iterable of str
        Faces without friction (:data:`BOX_FACES`: ``"x-"`` is the wall at ``lower[0]``, ``"x+"``
        the one at ``upper[0]``, ...; an axis name ``"y"`` means both of its faces): their
        particles get ``friction`` 0, the others 1.

    Returns
    -------
    BoundaryParticles
        Each particle's normal is the axis of the face it lies behind (the axis along which it
        is farthest outside the box); particles beyond an edge or a corner count for one face.
    """
    if isinstance(lower, Box):
        if upper is not None:
            raise ValueError("upper must be omitted when lower is a filters.geometry.Box")
        lower, upper = lower.lower, lower.upper
    lower = check_finite_vector("lower", lower, 3)
    upper = check_finite_vector("upper", upper, 3)
    if spacing is None:
        raise TypeError("box_boundary needs the spacing (m)")
    spacing = check_range("spacing", spacing, 0.0, math.inf, low_inclusive=False)
    support_factor = check_range("support_factor", support_factor, 1.0, 4.0)
    if not (upper > lower).all():
        raise ValueError(f"upper must exceed lower in every component, got {lower} and {upper}")
    if ((upper - lower) / spacing > 5000).any():
        raise ValueError("box is more than 5000 spacings long; increase spacing")
    if layers is None:
        layers = int(math.ceil(support_factor - 1e-9))
    layers = check_int("layers", layers, 1, 8)
    if isinstance(free_slip, str):
        free_slip = (free_slip,)
    slip = set()
    for face in free_slip:
        if face in ("x", "y", "z"):
            slip.update((face + "-", face + "+"))
        elif face in BOX_FACES:
            slip.add(face)
        else:
            raise ValueError(f"free_slip faces must be among {BOX_FACES} or 'x', 'y', 'z'; "
                             f"got {face!r}")
    axes = [_axis_coords(lower[k], upper[k], spacing, layers) for k in range(3)]
    (cx, wx), (cy, wy), (cz, wz) = axes
    X, Y, Z = np.meshgrid(cx, cy, cz, indexing="ij")
    VX, VY, VZ = np.meshgrid(wx, wy, wz, indexing="ij")
    inside = ((X > lower[0]) & (X < upper[0]) & (Y > lower[1]) & (Y < upper[1])
              & (Z > lower[2]) & (Z < upper[2]))
    keep = ~inside
    if open_top:
        keep &= Z < upper[2]
    points = np.stack([X[keep], Y[keep], Z[keep]], axis=1)
    scale = lattice_volume(spacing, support_factor * spacing, kernel) / spacing ** 3
    volumes = (VX * VY * VZ)[keep] * scale
    # the face each particle lies behind: the axis along which it is farthest outside
    below = lower - points
    above = points - upper
    depth = np.maximum(below, above)
    axis = np.argmax(depth, axis=1)
    rows = np.arange(points.shape[0])
    low_side = below[rows, axis] > above[rows, axis]
    normals = np.zeros_like(points)
    normals[rows, axis] = np.where(low_side, 1.0, -1.0)  # into the tank
    face = np.array(BOX_FACES)[2 * axis + np.where(low_side, 0, 1)]
    friction = np.where(np.isin(face, sorted(slip)), 0.0, 1.0)
    return BoundaryParticles(points, volumes, normals, friction=friction)


# --------------------------------------------------------------------------------------------
# Closed triangle meshes.
# --------------------------------------------------------------------------------------------
@njit(parallel=True, cache=True)
def _akinci_volumes(x, off, idx, kind, h):
    n = x.shape[0]
    out = np.empty(n)
    w0 = kernel_w(kind, 0.0, h)
    for i in prange(n):
        s = w0
        for k in range(off[i], off[i + 1]):
            j = idx[k]
            dx = x[i, 0] - x[j, 0]
            dy = x[i, 1] - x[j, 1]
            dz = x[i, 2] - x[j, 2]
            s += kernel_w(kind, math.sqrt(dx * dx + dy * dy + dz * dz), h)
        out[i] = 1.0 / s
    return out


def _flat_wall_gamma(spacing, h, kind, kernel):
    """Scale of Akinci volumes that gives rest density next to a flat single-layer wall."""
    n = int(math.ceil(h / spacing)) + 1
    g = np.arange(-n, n + 1) * spacing
    # Wall layer at z = 0 (a square lattice), its Akinci volume from its in-plane neighbours.
    X, Y = np.meshgrid(g, g, indexing="ij")
    rw = np.sqrt(X * X + Y * Y).ravel()
    vol_wall = 1.0 / _sum_w(kind, rw, h)
    # Fluid half-space lattice z = spacing/2 + k spacing; test particle at (0, 0, spacing/2).
    zs = (np.arange(n + 1) + 0.5) * spacing
    X, Y, Z = np.meshgrid(g, g, zs, indexing="ij")
    rf = np.sqrt(X * X + Y * Y + (Z - 0.5 * spacing) ** 2).ravel()
    vol_fluid = lattice_volume(spacing, h, kernel)
    rho_fluid = vol_fluid * _sum_w(kind, rf, h)  # in units of rho0
    rb = np.sqrt(X[:, :, 0] ** 2 + Y[:, :, 0] ** 2 + (0.5 * spacing) ** 2).ravel()
    rho_wall = vol_wall * _sum_w(kind, rb, h)
    return (1.0 - rho_fluid) / rho_wall


def boundary_volumes(points: ArrayLike, spacing: float, *, support_factor: float = 2.0,
                     kernel: str = "cubic") -> np.ndarray:
    """Volumes of one layer of boundary particles sampling a surface (m^3).

    Akinci et al. (2012)'s ``1 / sum_k W(x_b - x_k)`` over the samples ``k``, multiplied by the
    factor that gives a fluid lattice resting ``spacing / 2`` from a flat wall sampled on a
    square lattice of step ``spacing`` its rest density.  Recompute them when a sampled surface
    deforms and pass them to :meth:`filters.sph.SPHLiquid.move_boundary`.  One such layer fills
    at most 0.22 of a particle's kernel and does not hold a liquid resting on it (measured: a
    six-layer pool falls through, see :func:`mesh_boundary`): a boundary that must hold liquid
    needs layers a kernel support deep (:func:`box_boundary`, :func:`mesh_boundary`).

    Parameters
    ----------
    points : (M, 3) array_like
        Samples of the surface (m), about ``spacing`` apart.
    spacing : float
        Fluid particle spacing (m), > 0.
    support_factor : float
        Kernel support radius over ``spacing``, in [1, 4].
    kernel : str
        Smoothing kernel name.

    Returns
    -------
    (M,) float64
    """
    x = np.ascontiguousarray(points, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or not np.isfinite(x).all():
        raise ValueError(f"points must be a finite (M, 3) array, got shape {x.shape}")
    spacing = check_range("spacing", spacing, 0.0, math.inf, low_inclusive=False)
    support_factor = check_range("support_factor", support_factor, 1.0, 4.0)
    kind = kernel_id(kernel)
    h = support_factor * spacing
    if x.shape[0] == 0:
        return np.zeros(0)
    off, idx = NeighborSearch(h, "auto").build(x).query()
    return _akinci_volumes(x, off, idx, kind, h) * _flat_wall_gamma(spacing, h, kind, kernel)


def mesh_boundary(vertices: ArrayLike, faces: ArrayLike, spacing: float, *,
                  support_factor: float = 2.0, kernel: str = "cubic",
                  check_closed: bool = True, layers: int | None = None,
                  origin: ArrayLike | None = None) -> BoundaryParticles:
    """Boundary particles filling the outer layers of the inside of a closed triangle mesh.

    The mesh is sampled as :func:`box_boundary` samples a tank's walls: a lattice continued
    into the solid, the cell centres ``origin + (i + 1/2) step`` that lie inside the mesh at
    most ``layers * spacing`` under its surface (a full kernel support by default), each with
    the lattice's volume (:func:`lattice_volume`).  By default the lattice fills the mesh's
    bounding box with whole cells: along each axis the step is ``spacing`` stretched to the
    nearest whole number of cells across the box (unchanged where the extent is a multiple of
    ``spacing``), so that every face of a box, and the outermost faces of any mesh, has its
    first layer half a step inside it.  A fluid lattice next to such a face then sees the
    neighbourhood it would see in the bulk (rest density), and the layers fill half of a
    particle's kernel at the surface, which the DFSPH wall constraints need
    (:mod:`filters.sph.dfsph`).  A box whose sides are whole multiples of ``spacing`` gets
    exactly a tank's wall layers seen from the other side.

    Parameters
    ----------
    vertices : (V, 3) array_like
        Vertices (m) of a closed, outward-oriented triangle mesh.
    faces : (F, 3) array_like of int
        Its triangles.
    spacing : float
        The fluid's particle spacing (m), > 0.
    support_factor : float
        Kernel support over ``spacing``, in [1, 4].
    kernel : str
        Smoothing kernel (for the lattice volume).
    check_closed : bool
        Require every edge to be shared by exactly two triangles (a closed, manifold surface).
        Without the check, an open surface encloses no lattice point and is refused all the
        same.
    layers : int, optional
        Depth of the sampled shell in spacings, in [1, 8]; default ``ceil(support_factor)``
        (a full kernel support).  A body thinner than twice that is sampled through.
    origin : (3,) array_like, optional
        A lattice point (m) of a lattice of step ``spacing`` on every axis (no stretching): put
        it on the fluid's lattice to continue that lattice into the solid.  Default: the lower
        corner of the mesh's bounding box, with the fitted steps above.

    Returns
    -------
    BoundaryParticles
        Normals: outward, of the surface nearest to each sample; volumes: the lattice volume
        of the steps used (that of :func:`lattice_volume` without stretching).

    Raises
    ------
    ValueError
        For a bad parameter, an open or flat mesh (with ``check_closed``), or a mesh so small
        or so thin that no lattice point falls inside it.

    Notes
    -----
    Earlier versions sampled the surface itself in one layer (Akinci et al. 2012), which fills
    at most 0.22 of a particle's kernel: neither solver's pressure engaged there, and a pool
    resting on such a surface fell through it (measured at 1 cm: all of a six-layer pool within
    0.13 s, DFSPH and WCSPH alike).  Samples lie on the lattice, so a curved surface is
    represented to within half a spacing, as the fluid's own surface is.
    """
    # imported here: filters.rigid (its bodies' samples) imports this module
    from ..rigid.sdf import mesh_distances

    v = np.ascontiguousarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 4 or not np.isfinite(v).all():
        raise ValueError(f"vertices must be a finite (V, 3) array with V >= 4, got {v.shape}")
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] < 4 or not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"faces must be an (F, 3) integer array with F >= 4, got {f.shape} "
                         f"{f.dtype}")
    f = np.ascontiguousarray(f, dtype=np.int64)
    if f.min() < 0 or f.max() >= v.shape[0]:
        raise ValueError(f"faces must index vertices in [0, {v.shape[0] - 1}]")
    spacing = check_range("spacing", spacing, 0.0, math.inf, low_inclusive=False)
    support_factor = check_range("support_factor", support_factor, 1.0, 4.0)
    kernel_id(kernel)  # refuses an unknown name before any work
    if layers is None:
        layers = int(math.ceil(support_factor - 1e-9))
    layers = check_int("layers", layers, 1, 8)
    if check_closed:
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        _, counts = np.unique(edges, axis=0, return_counts=True)
        if (counts != 2).any():
            raise ValueError(
                f"faces must form a closed surface (every edge in exactly 2 triangles); "
                f"{int((counts != 2).sum())} edges are not"
            )
    lo = v.min(axis=0)
    hi = v.max(axis=0)
    if ((hi - lo) / spacing > 2000).any():
        raise ValueError("the mesh is more than 2000 spacings across; increase spacing")
    if not ((hi - lo) > 1e-9 * spacing).all():
        raise ValueError("the mesh is flat (no extent along an axis): it encloses no volume")
    step = np.full(3, spacing)
    if origin is None:
        o = lo
        # whole cells across the bounding box: each axis's step stretched to it, so that the
        # faces of a box (and a mesh's extreme faces) have their first layer half a step
        # inside, where the liquid's lattice puts it next to a tank's wall (measured: a 4.4
        # spacings box on the unstretched lattice let 1,600 particles into it in 0.5 s and
        # pushed a symmetric pool sideways with 0.14 rho g V)
        cells = np.maximum(np.round((hi - lo) / spacing), 1.0)
        fitted = (hi - lo) / cells
        off = np.abs(fitted - spacing) > 1e-9 * spacing
        step[off] = fitted[off]
    else:
        o = check_finite_vector("origin", origin, 3)
    first = np.floor((lo - o) / step - 0.5).astype(np.int64)
    last = np.ceil((hi - o) / step - 0.5).astype(np.int64)
    axes = [o[k] + (np.arange(first[k], last[k] + 1) + 0.5) * step[k] for k in range(3)]
    X, Y, Z = np.meshgrid(*axes, indexing="ij")
    grid = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    d, n = mesh_distances(v, f, grid)
    keep = (d < -1e-9 * spacing) & (d >= -layers * spacing)
    if not keep.any():
        raise ValueError(f"no lattice point of spacing {spacing:g} m falls inside the mesh; "
                         f"decrease spacing (an open surface encloses none)")
    volume = _lattice_sum_volume(step, support_factor * spacing, kernel_id(kernel))
    points = grid[keep]
    return BoundaryParticles(points, np.full(points.shape[0], volume), n[keep])


def _lattice_sum_volume(step, h, kind):
    """``1 / sum_j W(x_j)`` over a lattice with the steps ``step`` (3,) along the axes (m^3):
    :func:`lattice_volume` with a step of its own per axis."""
    axes = [np.arange(-m, m + 1) * d for d, m in zip(step, np.ceil(h / step).astype(int) + 1,
                                                     strict=True)]
    X, Y, Z = np.meshgrid(*axes, indexing="ij")
    return 1.0 / _sum_w(kind, np.sqrt(X * X + Y * Y + Z * Z).ravel(), h)
