"""Numba kernels of the linear tetrahedral finite elements (:mod:`filters.elastic.fem`).

A tetrahedron ``t`` with nodes ``tets[t] = (n0, n1, n2, n3)`` has the constant deformation
gradient ``F = sum_k x_{n_k} (x) g_k`` with the shape-function gradients ``g_k`` (rows of
``D_m^{-1}`` for ``k = 1, 2, 3``, ``g_0 = -(g_1 + g_2 + g_3)``, ``D_m`` the rest edge matrix;
Sifakis & Barbič 2012, "FEM simulation of 3D deformable solids", SIGGRAPH course), rest volume
``W``, energy ``W Psi(F)``, nodal forces ``f_k = -W P(F) g_k`` and stiffness blocks
``K_kl[a, c] = W sum_{b, d} g_k[b] dP_ab/dF_cd g_l[d]``.

Every kernel runs over chunks of elements in parallel and writes per element (or per node, or
per matrix block, each gathered in a fixed order), so results do not depend on the number of
threads.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .materials import eigensystem, energy_density, first_piola

__all__ = [
    "element_energies",
    "element_forces",
    "element_hessians",
    "element_stiffness",
    "element_matvec",
    "gather_nodes",
    "assemble_blocks",
    "serial_sum",
]

#: Elements per parallel work item (each allocates its scratch once).
CHUNK = 256


@njit(cache=True)
def _scratch():
    return (np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)),
            np.empty((3, 3)), np.empty(3), np.empty(3), np.empty((9, 9)))


@njit(cache=True, inline="always")
def _deformation(x, tets, grads, t, f):
    for a in range(3):
        for b in range(3):
            acc = 0.0
            for k in range(4):
                acc += x[tets[t, k], a] * grads[t, k, b]
            f[a, b] = acc


@njit(parallel=True, cache=True)
def element_energies(x, tets, grads, vols, material, mu, lam, out):
    """Elastic energy ``W Psi(F)`` (J) of every element into ``out`` (T,)."""
    nt = tets.shape[0]
    for c in prange((nt + CHUNK - 1) // CHUNK):
        scratch = _scratch()
        f = np.empty((3, 3))
        for t in range(c * CHUNK, min(nt, (c + 1) * CHUNK)):
            _deformation(x, tets, grads, t, f)
            out[t] = vols[t] * energy_density(material, mu, lam, f, scratch)


@njit(parallel=True, cache=True)
def element_forces(x, tets, grads, vols, material, mu, lam, forces, energies):
    """Nodal elastic forces ``-W P g_k`` (N) into ``forces`` (T, 4, 3) and energies (J) into
    ``energies`` (T,)."""
    nt = tets.shape[0]
    for c in prange((nt + CHUNK - 1) // CHUNK):
        scratch = _scratch()
        f = np.empty((3, 3))
        p = np.empty((3, 3))
        for t in range(c * CHUNK, min(nt, (c + 1) * CHUNK)):
            _deformation(x, tets, grads, t, f)
            w = vols[t]
            energies[t] = w * first_piola(material, mu, lam, f, p, scratch)
            for k in range(4):
                for a in range(3):
                    forces[t, k, a] = -w * (p[a, 0] * grads[t, k, 0] + p[a, 1] * grads[t, k, 1]
                                            + p[a, 2] * grads[t, k, 2])


@njit(cache=True)
def element_stiffness(material, mu, lam, f, g, w, definite, out, scratch, tf, gv, kh):
    """Stiffness ``W d^2 Psi / dx^2`` (N/m) of one element into ``out`` (12, 12).

    Built in the frame of the signed SVD ``F = U diag(s) V^T``: with ``gv[k] = V^T g_k``, the
    scaling block ``A`` and the twist / flip eigenvalues ``(t, f)`` of each pair ``(i, j)``
    (:func:`filters.elastic.materials.eigensystem`), the block of nodes ``k, l`` is
    ``U Khat_kl U^T`` with ``Khat[i, j] = A_ij gv[k, i] gv[l, j]`` plus, per pair,
    ``(t + f)/2 (gv[k, j] gv[l, j] e_i e_i^T + gv[k, i] gv[l, i] e_j e_j^T)`` and
    ``(f - t)/2 (gv[k, j] gv[l, i] e_i e_j^T + gv[k, i] gv[l, j] e_j e_i^T)``.
    ``scratch`` as :func:`filters.elastic.materials.new_scratch`, ``tf`` (6,), ``gv`` (4, 3),
    ``kh`` (3, 3).
    """
    eigensystem(material, mu, lam, f, definite, scratch, tf)
    u = scratch[0]
    v = scratch[1]
    a = scratch[3]
    tmp = scratch[4]
    for k in range(4):
        for i in range(3):
            gv[k, i] = v[0, i] * g[k, 0] + v[1, i] * g[k, 1] + v[2, i] * g[k, 2]
    for k in range(4):
        for l in range(k, 4):
            for i in range(3):
                for j in range(3):
                    kh[i, j] = a[i, j] * gv[k, i] * gv[l, j]
            for p in range(3):  # the pair (i, j) opposite p
                i = 1 if p == 0 else 0
                j = 1 if p == 2 else 2
                plus = 0.5 * (tf[p] + tf[3 + p])
                minus = 0.5 * (tf[3 + p] - tf[p])
                kh[i, i] += plus * gv[k, j] * gv[l, j]
                kh[j, j] += plus * gv[k, i] * gv[l, i]
                kh[i, j] += minus * gv[k, j] * gv[l, i]
                kh[j, i] += minus * gv[k, i] * gv[l, j]
            # out block = w U kh U^T
            for r in range(3):
                for c in range(3):
                    tmp[r, c] = u[r, 0] * kh[0, c] + u[r, 1] * kh[1, c] + u[r, 2] * kh[2, c]
            for r in range(3):
                for c in range(3):
                    val = w * (tmp[r, 0] * u[c, 0] + tmp[r, 1] * u[c, 1] + tmp[r, 2] * u[c, 2])
                    out[3 * k + r, 3 * l + c] = val
                    out[3 * l + c, 3 * k + r] = val


@njit(parallel=True, cache=True)
def element_hessians(x, tets, grads, vols, material, mu, lam, definite, out):
    """Stiffness matrices ``-d f / d x`` (N/m) of every element into ``out`` (T, 12, 12),
    index ``3 k + a`` for node ``k``, axis ``a``; positive semi-definite with ``definite``."""
    nt = tets.shape[0]
    for c in prange((nt + CHUNK - 1) // CHUNK):
        scratch = _scratch()
        f = np.empty((3, 3))
        tf = np.empty(6)
        gv = np.empty((4, 3))
        kh = np.empty((3, 3))
        for t in range(c * CHUNK, min(nt, (c + 1) * CHUNK)):
            _deformation(x, tets, grads, t, f)
            element_stiffness(material, mu, lam, f, grads[t], vols[t], definite, out[t],
                              scratch, tf, gv, kh)


@njit(parallel=True, cache=True)
def element_matvec(blocks, tets, v, out):
    """``out[t] = blocks[t] v[tets[t]]`` for element matrices ``blocks`` (T, 12, 12), per
    element (T, 4, 3)."""
    nt = tets.shape[0]
    for t in prange(nt):
        for r in range(12):
            acc = 0.0
            for l in range(4):
                node = tets[t, l]
                acc += (blocks[t, r, 3 * l] * v[node, 0] + blocks[t, r, 3 * l + 1] * v[node, 1]
                        + blocks[t, r, 3 * l + 2] * v[node, 2])
            out[t, r // 3, r % 3] = acc


@njit(parallel=True, cache=True)
def gather_nodes(per_element, inc_ptr, inc_element, inc_local, out):
    """``out[i] = sum`` of ``per_element[t, k]`` over the elements ``t`` holding node ``i`` as
    their ``k``-th, in the fixed order of the incidence lists (N, 3)."""
    for i in prange(out.shape[0]):
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        for e in range(inc_ptr[i], inc_ptr[i + 1]):
            t = inc_element[e]
            k = inc_local[e]
            a0 += per_element[t, k, 0]
            a1 += per_element[t, k, 1]
            a2 += per_element[t, k, 2]
        out[i, 0] = a0
        out[i, 1] = a1
        out[i, 2] = a2


@njit(parallel=True, cache=True)
def assemble_blocks(ke, ke2, scale2, slot_ptr, slot_entry, bptr, bcols, diag_slot, diag, pinned,
                    data):
    """Assemble ``sum_t K_t + scale2 sum_t K2_t + diag`` into a block CSR matrix's ``data``.

    Parameters
    ----------
    ke, ke2 : (T, 12, 12) float64
        Element matrices (``ke2`` may have no rows when ``scale2`` is 0).
    scale2 : float
        Factor of ``ke2``.
    slot_ptr, slot_entry : int64 arrays
        For every block slot of the pattern, the element blocks ``16 t + 4 k + l`` it sums, in
        a fixed order (CSR form).
    bptr, bcols : int64 arrays
        Block-row pointers (N + 1,) and block columns of the pattern.
    diag_slot : (N,) int64
        Slot of every diagonal block.
    diag : (N, 3, 3) float64
        Added to the diagonal blocks (mass, damping and contact terms).
    pinned : (N,) bool
        Rows and columns of pinned nodes become the identity.
    data : float64 array
        The scalar CSR data: row ``3 i + r`` holds, for every block ``k`` of block-row ``i``,
        the columns ``3 bcols[k] + q``.
    """
    n = bptr.shape[0] - 1
    for c in prange((n + CHUNK - 1) // CHUNK):
        blk = np.empty((3, 3))
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            _assemble_row(ke, ke2, scale2, slot_ptr, slot_entry, bptr, bcols, diag_slot, diag,
                          pinned, data, i, blk)


@njit(cache=True, inline="always")
def _assemble_row(ke, ke2, scale2, slot_ptr, slot_entry, bptr, bcols, diag_slot, diag, pinned,
                  data, i, blk):
    """Block-row ``i`` of :func:`assemble_blocks` (``blk`` a (3, 3) scratch)."""
    nb = bptr[i + 1] - bptr[i]
    base = 9 * bptr[i]
    for slot in range(bptr[i], bptr[i + 1]):
        j = bcols[slot]
        blk[:, :] = 0.0
        if pinned[i] or pinned[j]:
            if i == j:
                for r in range(3):
                    blk[r, r] = 1.0
        else:
            for e in range(slot_ptr[slot], slot_ptr[slot + 1]):
                code = slot_entry[e]
                t = code // 16
                k = (code // 4) % 4
                l = code % 4
                for r in range(3):
                    for q in range(3):
                        blk[r, q] += ke[t, 3 * k + r, 3 * l + q]
                if scale2 != 0.0:
                    for r in range(3):
                        for q in range(3):
                            blk[r, q] += scale2 * ke2[t, 3 * k + r, 3 * l + q]
            if slot == diag_slot[i]:
                for r in range(3):
                    for q in range(3):
                        blk[r, q] += diag[i, r, q]
        col = 3 * (slot - bptr[i])
        for r in range(3):
            for q in range(3):
                data[base + 3 * r * nb + col + q] = blk[r, q]


@njit(cache=True)
def serial_sum(values):
    """Sum of a 1-d array in index order (the same bits for any thread count)."""
    acc = 0.0
    for i in range(values.shape[0]):
        acc += values[i]
    return acc
