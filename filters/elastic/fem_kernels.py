"""Numba kernels of the linear tetrahedral finite elements (:mod:`filters.elastic.fem`).

A tetrahedron ``t`` with nodes ``tets[t] = (n0, n1, n2, n3)`` has the constant deformation
gradient ``F = sum_k x_{n_k} (x) g_k`` with the shape-function gradients ``g_k`` (rows of
``D_m^{-1}`` for ``k = 1, 2, 3``, ``g_0 = -(g_1 + g_2 + g_3)``, ``D_m`` the rest edge matrix;
Sifakis & Barbič 2012, "FEM simulation of 3D deformable solids", SIGGRAPH course), rest volume
``W``, energy ``W Psi(F)``, nodal forces ``f_k = -W P(F) g_k`` and stiffness blocks
``K_kl[a, c] = W sum_{b, d} g_k[b] dP_ab/dF_cd g_l[d]``.

Every kernel runs over chunks of elements in parallel and writes per element, per node
(gathered in a fixed order) or, for the stiffness matrix, per matrix block from one colour of
element chunks at a time (chunks of one colour share no node), so results do not depend on the
number of threads.
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
    "gather_nodes",
    "color_chunks",
    "assemble_stiffness",
    "finish_system",
    "csr_matvec",
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
        for l in range(k, 4):  # noqa: E741 (node l of the block k, l, as in the docstring)
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


@njit(cache=True)
def color_chunks(tets, n_nodes, chunk):
    """Greedy colouring of the chunks of ``chunk`` consecutive elements: two chunks of one
    colour share no node.

    Returns ``(ptr, order)``: the chunks of colour ``c`` are ``order[ptr[c]:ptr[c + 1]]``, in
    increasing order.  Consecutive elements of a lattice mesh are neighbours, so a chunk is a
    compact piece of the mesh and a handful of colours suffice.
    """
    nt = tets.shape[0]
    nc = (nt + chunk - 1) // chunk
    last = np.full(n_nodes, -1, np.int64)  # per node: the last chunk that holds it
    # chunk -> nodes, node -> chunks (without repeats)
    count = np.zeros(n_nodes + 1, np.int64)
    for c in range(nc):
        for t in range(c * chunk, min(nt, (c + 1) * chunk)):
            for k in range(4):
                node = tets[t, k]
                if last[node] != c:
                    last[node] = c
                    count[node + 1] += 1
    for i in range(n_nodes):
        count[i + 1] += count[i]
    fill = count[:-1].copy()
    inc = np.empty(count[-1], np.int64)
    last[:] = -1
    for c in range(nc):
        for t in range(c * chunk, min(nt, (c + 1) * chunk)):
            for k in range(4):
                node = tets[t, k]
                if last[node] != c:
                    last[node] = c
                    inc[fill[node]] = c
                    fill[node] += 1
    color = np.full(nc, -1, np.int64)
    stamp = np.full(nc + 1, -1, np.int64)  # stamp[k] == c: colour k taken by a neighbour of c
    ncolors = 0
    for c in range(nc):
        for t in range(c * chunk, min(nt, (c + 1) * chunk)):
            for k in range(4):
                node = tets[t, k]
                for e in range(count[node], count[node + 1]):
                    other = color[inc[e]]
                    if other >= 0:
                        stamp[other] = c
        k = 0
        while stamp[k] == c:
            k += 1
        color[c] = k
        ncolors = max(ncolors, k + 1)
    ptr = np.zeros(ncolors + 1, np.int64)
    for c in range(nc):
        ptr[color[c] + 1] += 1
    for k in range(ncolors):
        ptr[k + 1] += ptr[k]
    fill = ptr[:-1].copy()
    order = np.empty(nc, np.int64)
    for c in range(nc):
        order[fill[color[c]]] = c
        fill[color[c]] += 1
    return ptr, order


@njit(parallel=True, cache=True)
def assemble_stiffness(x, tets, grads, vols, material, mu, lam, definite, color_ptr,
                       color_order, block_offset, row_stride, data):
    """Assemble the stiffness ``sum_t K_t`` (N/m) into a block CSR matrix's ``data`` (zeroed
    here), element by element, one colour of chunks at a time (:func:`color_chunks`: chunks of
    a colour share no node, so they add into distinct blocks in parallel; every entry sums its
    elements in the same order whatever the number of threads).

    Parameters
    ----------
    color_ptr, color_order : int64 arrays
        The chunks of :data:`CHUNK` elements of every colour (:func:`color_chunks`).
    block_offset : (T, 16) int64
        Index in ``data`` of the entry ``(0, 0)`` of the block of nodes ``(k, l)`` of element
        ``t`` (``16 t + 4 k + l``).
    row_stride : (T, 4) int64
        Distance in ``data`` between the scalar rows of node ``k``'s block row.
    """
    for i in prange(data.shape[0]):
        data[i] = 0.0
    nt = tets.shape[0]
    for color in range(color_ptr.shape[0] - 1):
        for e in prange(color_ptr[color], color_ptr[color + 1]):
            chunk = color_order[e]
            scratch = _scratch()
            f = np.empty((3, 3))
            tf = np.empty(6)
            gv = np.empty((4, 3))
            kh = np.empty((3, 3))
            ke = np.empty((12, 12))
            for t in range(chunk * CHUNK, min(nt, (chunk + 1) * CHUNK)):
                _deformation(x, tets, grads, t, f)
                element_stiffness(material, mu, lam, f, grads[t], vols[t], definite, ke,
                                  scratch, tf, gv, kh)
                for k in range(4):
                    stride = row_stride[t, k]
                    for l in range(4):  # noqa: E741 (node l of the block k, l)
                        base = block_offset[t, 4 * k + l]
                        for r in range(3):
                            for q in range(3):
                                data[base + r * stride + q] += ke[3 * k + r, 3 * l + q]


@njit(parallel=True, cache=True)
def finish_system(indptr, indices, stiffness, damping, scale, diag_offset, row_stride, diag,
                  pinned, data):
    """``data = stiffness + scale * damping`` plus the 3x3 ``diag`` blocks on the diagonal, for
    a CSR matrix of 3x3 blocks (rows ``3 i + r``); the rows and columns of pinned nodes become
    those of the identity."""
    for row in prange(indptr.shape[0] - 1):
        i = row // 3
        for p in range(indptr[row], indptr[row + 1]):
            j = indices[p] // 3
            if pinned[i] or pinned[j]:
                data[p] = 1.0 if indices[p] == row else 0.0
            elif scale != 0.0:
                data[p] = stiffness[p] + scale * damping[p]
            else:
                data[p] = stiffness[p]
    for i in prange(diag.shape[0]):
        if pinned[i]:
            continue
        base = diag_offset[i]
        stride = row_stride[i]
        for r in range(3):
            for q in range(3):
                data[base + r * stride + q] += diag[i, r, q]


@njit(parallel=True, cache=True)
def csr_matvec(indptr, indices, data, v, out):
    """``out = A v`` for a CSR matrix and vectors of shape (N, 3) (rows ``3 i + a``)."""
    flat_v = v.reshape(-1)
    flat_out = out.reshape(-1)
    for r in prange(indptr.shape[0] - 1):
        acc = 0.0
        for p in range(indptr[r], indptr[r + 1]):
            acc += data[p] * flat_v[indices[p]]
        flat_out[r] = acc


@njit(cache=True)
def serial_sum(values):
    """Sum of a 1-d array in index order (the same bits for any thread count)."""
    acc = 0.0
    for i in range(values.shape[0]):
        acc += values[i]
    return acc
