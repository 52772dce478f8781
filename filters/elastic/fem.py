"""Linear tetrahedral finite elements: element forces, energies and Hessians, and a FEM system.

Each tetrahedron has a constant deformation gradient ``F`` (:mod:`filters.elastic.fem_kernels`)
and a hyperelastic material of :mod:`filters.elastic.materials` -- the corotational linear
material (Müller & Gross 2004) or the stable Neo-Hookean one (Smith, de Goes & Kim 2018) --
given by Young's modulus ``E`` (Pa) and Poisson's ratio ``nu`` instead of spring stiffnesses.
Element energies ``W Psi(F)``, forces ``-W P(F) g_k`` (exactly minus the energy's gradient)
and stiffness matrices (exact, or with the definiteness fix of Teran et al. 2005) come from
the array-level functions :func:`tet_energies`, :func:`tet_forces` and :func:`tet_hessians`.

:class:`FEMSystem` is an :class:`filters.linalg.ImplicitSystem`, driven by the same schemes of
:mod:`filters.integrators` as the springs: lumped masses, gravity, Rayleigh damping
``C = alpha M + beta K`` (Rayleigh 1877; the stiffness part with ``K`` frozen at the start of
the step, which makes it a quadratic dissipation potential in
:func:`filters.integrators.backward_euler`) and pins.  Contacts are not part of the system:
the schemes add them (``contact=``, :class:`filters.elastic.contact_model.ContactModel`, the
same barrier, friction and normal damping as for the springs), with a barrier stiffness that
follows :meth:`FEMSystem.elastic_diagonal`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..linalg import ImplicitSystem
from ..validation import check_finite_vector, check_points, check_range
from .fem_kernels import (
    CHUNK,
    assemble_stiffness,
    color_chunks,
    csr_matvec,
    element_energies,
    element_forces,
    element_hessians,
    finish_system,
    gather_nodes,
    serial_sum,
)
from .materials import MATERIALS, lame_parameters, material_parameters
from .threads import serial_below

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray
    from scipy.sparse import csr_matrix

__all__ = [
    "MATERIALS",
    "tet_geometry",
    "tet_energies",
    "tet_forces",
    "tet_hessians",
    "FEMSystem",
]

#: Below this many elements the kernels run on one thread (a parallel region costs more than
#: the work, and a descheduled worker stalls every region on a busy machine).
PARALLEL_MIN_TETS = 8192


def _threads(work):
    """One thread below ``PARALLEL_MIN_TETS`` (:func:`filters.elastic.threads.serial_below`)."""
    return serial_below(work, PARALLEL_MIN_TETS)


def _check_tets(tets, n_points):
    tets = np.ascontiguousarray(tets, dtype=np.int64)
    if tets.ndim != 2 or tets.shape[1] != 4 or tets.shape[0] == 0:
        raise ValueError(f"tets must be a non-empty (T, 4) int array, got shape {tets.shape}")
    if tets.min() < 0 or tets.max() >= n_points:
        raise ValueError(f"tets must index nodes in [0, {n_points - 1}]")
    return tets


def tet_geometry(rest_positions: ArrayLike,
                 tets: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Shape-function gradients and rest volumes of tetrahedra.

    Parameters
    ----------
    rest_positions : (N, 3) array_like
        Rest positions (m).
    tets : (T, 4) int array_like
        Node indices, positively oriented.

    Returns
    -------
    grads : (T, 4, 3) float64
        ``g_k`` (1/m): ``F = sum_k x_k (x) g_k``; rows of ``D_m^{-1}`` for ``k = 1..3``.
    volumes : (T,) float64
        Rest volumes ``W`` (m^3).

    Raises
    ------
    ValueError
        If a tetrahedron is inverted or flat (volume <= 1e-12 of its bounding box's).
    """
    x = check_points("rest_positions", rest_positions)
    t = _check_tets(tets, x.shape[0])
    dm = np.stack([x[t[:, k]] - x[t[:, 0]] for k in (1, 2, 3)], axis=2)  # columns = edges
    det = np.linalg.det(dm)
    scale = np.abs(dm).max(axis=(1, 2))
    bad = ~(det > 1e-12 * scale ** 3)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"tets must be positively oriented with a volume > 0: tetrahedron {i} "
                         f"has volume {det[i] / 6.0:.3g} m^3 ({int(bad.sum())} such)")
    inv = np.linalg.inv(dm)  # rows: g_1, g_2, g_3
    grads = np.empty((t.shape[0], 4, 3))
    grads[:, 1:, :] = inv
    grads[:, 0, :] = -inv.sum(axis=1)
    return np.ascontiguousarray(grads), det / 6.0


def _prep(positions, rest_positions, tets, youngs_modulus, poisson_ratio, material):
    rest = check_points("rest_positions", rest_positions)
    x = check_points("positions", positions)
    if x.shape != rest.shape:
        raise ValueError(f"positions must have the shape of rest_positions {rest.shape}, "
                         f"got {x.shape}")
    code, mu, lam = material_parameters(material, youngs_modulus, poisson_ratio)
    grads, vols = tet_geometry(rest, tets)
    return x, np.ascontiguousarray(tets, dtype=np.int64), grads, vols, code, mu, lam


def tet_energies(positions: ArrayLike, rest_positions: ArrayLike, tets: ArrayLike, *,
                 youngs_modulus: float, poisson_ratio: float,
                 material: str = "neo_hookean") -> NDArray[np.float64]:
    """Elastic energy (J) of every tetrahedron.

    Parameters
    ----------
    positions : (N, 3) array_like
        Deformed node positions (m).
    rest_positions : (N, 3) array_like
        Rest positions (m).
    tets : (T, 4) int array_like
        Positively oriented tetrahedra.
    youngs_modulus : float
        ``E`` (Pa), > 0.
    poisson_ratio : float
        ``nu``, in [0, 0.5).
    material : {"neo_hookean", "corotated"}
        See :mod:`filters.elastic.materials`.

    Returns
    -------
    (T,) float64
    """
    x, t, g, w, code, mu, lam = _prep(positions, rest_positions, tets, youngs_modulus,
                                      poisson_ratio, material)
    out = np.empty(t.shape[0])
    element_energies(x, t, g, w, code, mu, lam, out)
    return out


def tet_forces(positions: ArrayLike, rest_positions: ArrayLike, tets: ArrayLike, *,
               youngs_modulus: float, poisson_ratio: float,
               material: str = "neo_hookean") -> NDArray[np.float64]:
    """Elastic forces (N) on the four nodes of every tetrahedron, ``-W P(F) g_k``, (T, 4, 3).

    Arguments as in :func:`tet_energies`; the forces are minus the gradient of its energies.
    """
    x, t, g, w, code, mu, lam = _prep(positions, rest_positions, tets, youngs_modulus,
                                      poisson_ratio, material)
    forces = np.empty((t.shape[0], 4, 3))
    element_forces(x, t, g, w, code, mu, lam, forces, np.empty(t.shape[0]))
    return forces


def tet_hessians(positions: ArrayLike, rest_positions: ArrayLike, tets: ArrayLike, *,
                 youngs_modulus: float, poisson_ratio: float, material: str = "neo_hookean",
                 definite: bool = True) -> NDArray[np.float64]:
    """Stiffness matrices ``d^2 (W Psi) / dx^2`` (N/m) of every tetrahedron, (T, 12, 12).

    Index ``3 k + a`` is node ``k`` (of ``tets[t]``), axis ``a``.  Arguments as in
    :func:`tet_energies`; ``definite=False`` gives the exact Hessian, ``definite=True`` the
    positive semi-definite one with negative eigenvalues of ``dP/dF`` clamped (used by the
    implicit solves).
    """
    x, t, g, w, code, mu, lam = _prep(positions, rest_positions, tets, youngs_modulus,
                                      poisson_ratio, material)
    out = np.empty((t.shape[0], 12, 12))
    element_hessians(x, t, g, w, code, mu, lam, bool(definite), out)
    return out


class FEMSystem(ImplicitSystem):
    """Linear tetrahedra with a hyperelastic material, masses, gravity, damping and pins.

    An :class:`filters.linalg.ImplicitSystem` (see the module docstring): forces, energies and
    the implicit system matrix ``H = M/h^2 + K(x) + C(xdir)/h``, assembled in Numba into a
    fixed-pattern ``scipy.sparse`` CSR matrix with ``K`` the definite stiffness, ``C = alpha M
    + beta K(xdir)``, and rows and columns of pinned nodes replaced by the identity.  It has no
    matrix-free form (element blocks do not fit the pair operator of the springs), so PCG runs
    on the CSR matrix (:func:`filters.linalg.pcg`) or a direct solve factors it.

    Parameters
    ----------
    rest_positions : (N, 3) array_like
        Rest positions (m); also the initial ones of a simulation.
    tets : (T, 4) int array_like
        Positively oriented tetrahedra.
    masses : (N,) array_like
        Lumped node masses (kg), > 0.
    youngs_modulus : float
        ``E`` (Pa), > 0.
    poisson_ratio : float
        ``nu``, in [0, 0.5).
    material : {"neo_hookean", "corotated"}
        Stable Neo-Hookean (Smith et al. 2018) or corotational linear (Müller & Gross 2004).
    mass_damping : float
        Rayleigh ``alpha`` (1/s), >= 0: force ``-alpha m v`` per node.
    stiffness_damping : float
        Rayleigh ``beta`` (s), >= 0: force ``-beta K v``.
    gravity : sequence of 3 float
        Acceleration (m/s^2).
    pinned : (N,) bool array_like, optional
        Nodes held fixed.
    fractions : (T,) array_like, optional
        Volume fraction in (0, 1] of every tetrahedron filled by the solid (a lattice cut by a
        surface, :attr:`filters.elastic.tetmesh.TetMesh.fractions`): it scales the element's
        volume ``W``, so its energy, forces and stiffness (the finite cell method, Parvizian,
        Duster & Rank 2007); default 1.

    Contacts are not part of the system: the schemes of :mod:`filters.integrators` add them
    (``contact=``, :class:`filters.elastic.contact_model.ContactModel`).
    """

    def __init__(self, rest_positions: ArrayLike, tets: ArrayLike, masses: ArrayLike, *,
                 youngs_modulus: float, poisson_ratio: float, material: str = "neo_hookean",
                 mass_damping: float = 0.0, stiffness_damping: float = 0.0,
                 gravity: ArrayLike = (0.0, 0.0, -9.81), pinned: ArrayLike | None = None,
                 fractions: ArrayLike | None = None):
        rest = check_points("rest_positions", rest_positions)
        n = rest.shape[0]
        masses = np.ascontiguousarray(masses, dtype=np.float64)
        if masses.shape != (n,) or not np.isfinite(masses).all() or masses.min() <= 0.0:
            raise ValueError(f"masses must be ({n},), finite and > 0 (kg)")
        self.n_points = n
        self.rest_positions = rest
        self.tets = _check_tets(tets, n)
        self.material = material
        self.material_code, self.mu, self.lam = material_parameters(material, youngs_modulus,
                                                                    poisson_ratio)
        self.youngs_modulus = float(youngs_modulus)
        self.poisson_ratio = float(poisson_ratio)
        self.grads, self.volumes = tet_geometry(rest, self.tets)
        self.fractions = np.ones(self.tets.shape[0])
        if fractions is not None:
            f = np.ascontiguousarray(fractions, dtype=np.float64)
            if f.shape != self.fractions.shape or not np.all((f > 0.0) & (f <= 1.0)):
                raise ValueError(f"fractions must be a ({self.tets.shape[0]},) array of volume "
                                 "fractions in (0, 1]")
            self.fractions = f
            self.volumes = np.ascontiguousarray(self.volumes * f)
        self.masses = masses
        self.mass_damping = check_range("mass_damping", mass_damping, 0.0)
        self.stiffness_damping = check_range("stiffness_damping", stiffness_damping, 0.0)
        self.gravity = check_finite_vector("gravity", gravity, 3).copy()
        if pinned is None:
            pinned = np.zeros(n, dtype=bool)
        pinned = np.ascontiguousarray(pinned, dtype=bool)
        if pinned.shape != (n,):
            raise ValueError(f"pinned must have shape ({n},), got {pinned.shape}")
        self.pinned = pinned
        self.inv_mass = np.where(pinned, 0.0, 1.0 / masses)
        nt = self.tets.shape[0]
        # node -> (element, local corner) incidence, by node then element (a fixed order)
        order = np.argsort(self.tets.ravel(), kind="stable")
        self._inc_ptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(self.tets.ravel(), minlength=n), out=self._inc_ptr[1:])
        self._inc_element = np.ascontiguousarray(order // 4)
        self._inc_local = np.ascontiguousarray(order % 4)
        self._fe = np.empty((nt, 4, 3))
        self._energies = np.empty(nt)
        self._pattern = None
        self._cache_x = None  # positions of the last elastic evaluation and its results
        self._cache_force = np.empty((n, 3))
        self._cache_energy = 0.0
        self._damp_x = None  # positions of the frozen damping stiffness (in the pattern)
        #: Constant nodal loads (N, 3) (N) of the next steps, e.g. a liquid's pressure on the
        #: solid (:mod:`filters.coupling`), or None.  Like gravity they enter the forces and,
        #: as ``-sum f . x``, the potential energy, so Newton's line search sees them.
        self.loads = None

    @property
    def n_tets(self) -> int:
        """Number of tetrahedra."""
        return self.tets.shape[0]

    # -- elastic part ------------------------------------------------------------------------
    def _elastic(self, x):
        """Elastic forces (N, 3) and energy (J) at ``x`` (cached for the last ``x``)."""
        if self._cache_x is not None and np.array_equal(self._cache_x, x):
            return self._cache_force, self._cache_energy
        x = np.ascontiguousarray(x, dtype=np.float64)
        with _threads(self.n_tets):
            element_forces(x, self.tets, self.grads, self.volumes, self.material_code, self.mu,
                           self.lam, self._fe, self._energies)
            gather_nodes(self._fe, self._inc_ptr, self._inc_element, self._inc_local,
                         self._cache_force)
        self._cache_energy = float(serial_sum(self._energies))
        self._cache_x = x.copy()
        return self._cache_force, self._cache_energy

    def elastic_energy(self, x: np.ndarray) -> float:
        """Elastic (strain) energy (J) at ``x``."""
        return self._elastic(x)[1]

    def elastic_forces(self, x: np.ndarray) -> np.ndarray:
        """Elastic forces (N) at ``x``, (N, 3) (a copy)."""
        return self._elastic(x)[0].copy()

    def energy_density(self, x: np.ndarray) -> np.ndarray:
        """Strain energy density ``Psi(F)`` (J/m^3) of every tetrahedron at ``x``, (T,)."""
        x = np.ascontiguousarray(x, dtype=np.float64)
        out = np.empty(self.n_tets)
        with _threads(self.n_tets):
            element_energies(x, self.tets, self.grads, self.volumes, self.material_code,
                             self.mu, self.lam, out)
        return out / self.volumes

    def volume(self, x: np.ndarray) -> float:
        """Signed volume (m^3) of the solid at ``x``: every tetrahedron's times its volume
        fraction."""
        t = self.tets
        e1 = x[t[:, 1]] - x[t[:, 0]]
        e2 = x[t[:, 2]] - x[t[:, 0]]
        e3 = x[t[:, 3]] - x[t[:, 0]]
        return float((np.einsum("ij,ij->i", e1, np.cross(e2, e3)) * self.fractions).sum() / 6.0)

    def _stiffness(self, x, data):
        """Assemble the definite stiffness at ``x`` into ``data`` (the pattern's CSR data)."""
        p = self._pattern
        x = np.ascontiguousarray(x, dtype=np.float64)
        with _threads(self.n_tets):
            assemble_stiffness(x, self.tets, self.grads, self.volumes, self.material_code,
                               self.mu, self.lam, True, p["color_ptr"], p["color_order"],
                               p["block_offset"], p["row_stride"], data)
        return data

    def _damping_stiffness(self, xdir):
        """The definite stiffness at ``xdir`` (frozen for the damping), as CSR data, cached."""
        if self._pattern is None:
            self._build_pattern()
        p = self._pattern
        if self._damp_x is None or not np.array_equal(self._damp_x, xdir):
            self._stiffness(xdir, p["damping"])
            self._damp_x = np.array(xdir, dtype=np.float64, copy=True)
        return p["damping"]

    # -- ImplicitSystem ----------------------------------------------------------------------
    def forces(self, x: np.ndarray, v: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Total force (N): elastic, gravity, :attr:`loads` and damping, (N, 3)."""
        f = np.empty_like(x) if out is None else out
        f[...] = self._elastic(x)[0]
        f += self.masses[:, None] * self.gravity[None, :]
        if self.loads is not None:
            f += self.loads
        f += self.damping_forces(x, v)
        return f

    def conservative_forces(self, x: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Elastic, gravity and :attr:`loads` forces (N), (N, 3); contacts are the
        integrators'."""
        f = np.empty_like(x) if out is None else out
        f[...] = self._elastic(x)[0]
        f += self.masses[:, None] * self.gravity[None, :]
        if self.loads is not None:
            f += self.loads
        return f

    def damping_forces(self, xdir: np.ndarray, v: np.ndarray,
                       out: np.ndarray | None = None) -> np.ndarray:
        """Rayleigh damping ``-(alpha M + beta K(xdir)) v`` (N), linear in ``v``, (N, 3)."""
        f = np.empty_like(v) if out is None else out
        f[...] = -self.mass_damping * self.masses[:, None] * v
        if self.stiffness_damping > 0.0:
            kd = self._damping_stiffness(xdir)
            mat = self._pattern["matrix"]
            kv = np.empty((self.n_points, 3))
            with _threads(self.n_tets):
                csr_matvec(mat.indptr, mat.indices, kd, np.ascontiguousarray(v, np.float64),
                           kv)
            f -= self.stiffness_damping * kv
        return f

    def gravitational_energy(self, x: np.ndarray) -> float:
        """``-sum m g . x`` (J)."""
        return float(-np.einsum("i,ij,j->", self.masses, x, self.gravity))

    def potential_energy(self, x: np.ndarray) -> float:
        """Elastic plus gravitational energy (J), and ``-sum f . x`` of the :attr:`loads`."""
        e = self.elastic_energy(x) + self.gravitational_energy(x)
        if self.loads is not None:
            e -= float(np.einsum("ij,ij->", self.loads, x))
        return e

    def kinetic_energy(self, v: np.ndarray) -> float:
        """Kinetic energy (J)."""
        return float(0.5 * np.einsum("i,ij,ij->", self.masses, v, v))

    def energy(self, x: np.ndarray, v: np.ndarray) -> float:
        """Kinetic plus potential energy (J) (contacts are the contact model's)."""
        return self.kinetic_energy(v) + self.potential_energy(x)

    def elastic_diagonal(self) -> np.ndarray:
        """Each node's elastic stiffness (N/m) at rest, (N,): the mean diagonal entry of its
        block of ``K``, ``sum_e W_e |g_ek|^2 (mu + (lambda + mu) / 3)`` with the Lamé
        constants of ``E`` and ``nu`` (both materials linearise to linear elasticity, whose
        element stiffness block is ``W (mu |g|^2 I + (lambda + mu) g g^T)``).  The contact
        model scales its barrier stiffness by it, as for the springs."""
        mu, lam = lame_parameters(self.youngs_modulus, self.poisson_ratio)
        g2 = np.einsum("tkj,tkj->tk", self.grads, self.grads)
        per_corner = self.volumes[:, None] * g2 * (mu + (lam + mu) / 3.0)
        return np.bincount(self.tets.ravel(), weights=per_corner.ravel(),
                           minlength=self.n_points)

    def _build_pattern(self):
        """The block CSR pattern of the node adjacency, where every element block lands in it,
        and the element colours of the race-free parallel assembly."""
        import scipy.sparse as sp

        n = self.n_points
        t = self.tets
        rows = np.repeat(t, 4, axis=1).ravel()  # (T*16,): 16 t + 4 k + l
        cols = np.tile(t, (1, 4)).ravel()
        keys, slot_of = np.unique(rows * n + cols, return_inverse=True)
        brow = keys // n
        bcols = keys % n
        bptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(brow, minlength=n), out=bptr[1:])
        nb = np.diff(bptr)
        # scalar CSR: row 3i + r holds, for every block s of block-row i, columns 3 bcols[s] + q
        # at 9 bptr[i] + 3 r nb[i] + 3 (s - bptr[i]) + q
        first = 9 * bptr[brow] + 3 * (np.arange(keys.size) - bptr[brow])  # entry (0, 0)
        indptr = np.zeros(3 * n + 1, dtype=np.int64)
        indptr[1:] = np.cumsum(np.repeat(3 * nb, 3))
        indices = np.empty(9 * keys.size, dtype=np.int64)
        for r in range(3):
            for q in range(3):
                indices[first + 3 * r * nb[brow] + q] = 3 * bcols + q
        index_dtype = np.int32 if 9 * keys.size < 2**31 else np.int64
        mat = sp.csr_matrix((np.zeros(9 * keys.size), indices.astype(index_dtype),
                             indptr.astype(index_dtype)), shape=(3 * n, 3 * n), copy=False)
        mat.has_sorted_indices = True
        diag_slot = np.searchsorted(keys, np.arange(n) * (n + 1))
        color_ptr, color_order = color_chunks(t, n, CHUNK)
        self._pattern = dict(
            matrix=mat, color_ptr=color_ptr, color_order=color_order,
            block_offset=np.ascontiguousarray(first[slot_of].reshape(-1, 16)),
            row_stride=np.ascontiguousarray(3 * nb[t]),
            diag_offset=np.ascontiguousarray(first[diag_slot]),
            node_stride=np.ascontiguousarray(3 * nb),
            stiffness=np.zeros(9 * keys.size), damping=np.zeros(9 * keys.size),
            diag=np.zeros((n, 3, 3)))

    def system_matrix(self, x: np.ndarray, xdir: np.ndarray, h: float) -> csr_matrix:
        """Assemble ``H = M (1/h^2 + alpha/h) + K(x) + beta K(xdir)/h`` in place into the
        fixed-pattern CSR matrix.

        Parameters
        ----------
        x : (N, 3) array
            Positions (m) of the stiffness ``K`` (definite).
        xdir : (N, 3) array
            Positions of the frozen damping stiffness.
        h : float
            Time step (s).

        Returns
        -------
        scipy.sparse.csr_matrix, (3N, 3N)
            The same object every call (its ``data`` is overwritten).
        """
        if self._pattern is None:
            self._build_pattern()
        p = self._pattern
        h = float(h)
        stiffness = self._stiffness(x, p["stiffness"])
        scale = self.stiffness_damping / h
        damping = self._damping_stiffness(xdir) if scale > 0.0 else stiffness
        diag = p["diag"]
        diag[...] = 0.0
        m = self.masses * (1.0 / (h * h) + self.mass_damping / h)
        for r in range(3):
            diag[:, r, r] = m
        mat = p["matrix"]
        with _threads(self.n_tets):
            finish_system(mat.indptr, mat.indices, stiffness, damping, scale, p["diag_offset"],
                          p["node_stride"], diag, self.pinned, mat.data)
        return mat
