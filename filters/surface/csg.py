"""Constructive solid geometry of particle fields and shapes (:mod:`filters.geometry`).

A particle field from :mod:`filters.surface.splat` (negative inside) combines with a shape
(signed distance, negative inside the solid) by Ricci's (1973) operators: ``"union"`` (min),
``"intersection"`` (max), ``"difference"`` (``max(field, -shape)``): e.g. the liquid clipped by
the inside of its tank (``operation="intersection"`` with the tank's inner
:class:`filters.geometry.Box`) or a liquid merged with a solid blob (``"union"``). The shape's
distance is scaled into the units of
the field (about the slope of an SPH field across a surface) before the min / max, so that both
slopes are comparable where the surfaces meet; the zero set, hence the surface, does not depend
on that scale.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import Box, Shape
from ..validation import check_choice, check_range
from .grid import (
    DEFAULT_MAX_BYTES,
    DenseField,
    SparseGrid,
    check_budget,
    pack_keys,
    unpack_keys,
)

__all__ = ["combine_dense", "combine_sparse", "OPERATIONS"]

OPERATIONS = ("union", "intersection", "difference")


_BLOCKS_PER_CALL = 128  # blocks whose voxels one shape evaluation takes (12 KiB each)


def _apply(op, field, shape):
    if op == "union":
        return np.minimum(field, shape)
    if op == "intersection":
        return np.maximum(field, shape)
    return np.maximum(field, -shape)


def _box_blocks(box, origins, bsz, cell):
    """Signed distance of a Box at the voxels of blocks with corners ``origins`` (B, 3) (m):
    (B, bsz, bsz, bsz) as [z, y, x], from the per-axis distances (the voxels of a block are
    a product of three rows); the formula of :meth:`filters.geometry.Box.evaluate`."""
    lo = np.asarray(box.lower, np.float64)
    hi = np.asarray(box.upper, np.float64)
    c = 0.5 * (lo + hi)
    half = 0.5 * (hi - lo)
    idx = np.arange(bsz, dtype=np.float64) * cell
    q = np.abs(origins[:, :, None] + idx[None, None, :] - c[None, :, None]) - half[None, :, None]
    qx = q[:, 0][:, None, None, :]
    qy = q[:, 1][:, None, :, None]
    qz = q[:, 2][:, :, None, None]
    outside = np.sqrt(np.maximum(qx, 0.0) ** 2 + np.maximum(qy, 0.0) ** 2
                      + np.maximum(qz, 0.0) ** 2)
    inside = np.minimum(np.maximum(np.maximum(qx, qy), qz), 0.0)
    return outside + inside


def _voxel_centres(index_lo, shape_zyx, cell):
    nz, ny, nx = shape_zyx
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    pts = np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1).astype(np.float64)
    return (pts + np.asarray(index_lo, np.float64)) * cell


def combine_dense(field: DenseField, shape: Shape, operation: str = "intersection", *,
                  scale: float | None = None) -> DenseField:
    """Combine a dense particle field with an implicit shape.

    Parameters
    ----------
    field : DenseField
        Implicit values of the particles (negative inside).
    shape : filters.geometry.Shape
        The shape (signed distance, m, negative inside).
    operation : {"union", "intersection", "difference"}
        ``field op shape``.
    scale : float, optional
        Multiplies the shape's distances before combining (field units per metre); default
        ``1 / (8 cell_size)``, about the slope of an SPH field across a surface.

    Returns
    -------
    DenseField
        A new field; the box is unchanged (a union with a shape reaching outside it is cut
        at the box).
    """
    operation = check_choice("operation", operation, OPERATIONS)
    if not isinstance(shape, Shape):
        raise TypeError(f"shape must be a filters.geometry.Shape, got {type(shape).__name__}")
    scale = 1.0 / (8.0 * field.cell_size) if scale is None else check_range(
        "scale", scale, 0.0, math.inf, low_inclusive=False)
    values = field.values.copy()
    nz, ny, nx = values.shape
    for k in range(nz):  # one z slice at a time bounds the temporary memory
        lo = field.index_origin + np.array([0, 0, k])
        s = shape.evaluate(_voxel_centres(lo, (1, ny, nx), field.cell_size)) * scale
        values[k] = _apply(operation, values[k], s.reshape(ny, nx).astype(np.float32))
    return DenseField(values=values, index_origin=field.index_origin.copy(),
                      cell_size=field.cell_size)


def combine_sparse(grid: SparseGrid, shape: Shape, operation: str = "intersection", *,
                   scale: float | None = None, max_bytes: int = DEFAULT_MAX_BYTES) -> SparseGrid:
    """Combine a sparse particle field with an implicit shape, keeping the grid sparse.

    Blocks are classified against the shape by its value at the block centre: a 1-Lipschitz
    distance larger than the half-diagonal of the block grown by one voxel means the shape has
    one sign over the block and its neighbours' adjacent voxels, so the block keeps a constant
    state; the other blocks get voxel values. For a union, blocks are added over the shape's
    bounding box (the shape must then be bounded).

    Parameters
    ----------
    grid : SparseGrid
    shape : filters.geometry.Shape
    operation : {"union", "intersection", "difference"}
    scale : float, optional
        As in :func:`combine_dense`.
    max_bytes : int
        Memory budget (bytes) for the new grid.

    Returns
    -------
    SparseGrid
    """
    operation = check_choice("operation", operation, OPERATIONS)
    if not isinstance(shape, Shape):
        raise TypeError(f"shape must be a filters.geometry.Shape, got {type(shape).__name__}")
    cell = grid.cell_size
    bsz = grid.block_size
    scale = 1.0 / (8.0 * cell) if scale is None else check_range(
        "scale", scale, 0.0, math.inf, low_inclusive=False)
    e_keys = grid.keys
    i_keys = grid.inside_keys
    o_keys = np.zeros(0, np.int64)
    if operation == "union":
        b = shape.bounds()
        if b is None:
            raise ValueError("a union with an unbounded shape (e.g. a Plane) needs a dense grid; "
                             "intersect it with a Box first")
        lo = np.floor(b[0] / (cell * bsz)).astype(np.int64) - 1
        hi = np.floor(b[1] / (cell * bsz)).astype(np.int64) + 1
        ranges = [np.arange(lo[a], hi[a] + 1) for a in range(3)]
        gz, gy, gx = np.meshgrid(ranges[2], ranges[1], ranges[0], indexing="ij")
        box = pack_keys(np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1))
        known = np.concatenate([e_keys, i_keys])
        o_keys = np.setdiff1d(box, known)
    half_diag = 0.5 * math.sqrt(3.0) * (bsz + 2) * cell

    def centres(keys):
        return (unpack_keys(keys).astype(np.float64) * bsz + 0.5 * (bsz - 1)) * cell

    new_e_keys, new_e_data, new_i = [], [], []
    # evaluated blocks: voxel by voxel
    local = _voxel_centres((0, 0, 0), (bsz, bsz, bsz), cell)
    check_budget((e_keys.size + i_keys.size + o_keys.size) * 4 * bsz**3, max_bytes,
                 "combining the grid with a shape")
    for keys, base in ((e_keys, None), (i_keys, grid.inside_value), (o_keys, grid.outside_value)):
        if keys.size == 0:
            continue
        s_c = shape.evaluate(centres(keys))
        if base is None:
            sel = np.arange(keys.size)
        else:
            constant_in = s_c < -half_diag
            constant_out = s_c > half_diag
            inside_after = {"union": (base < 0) | constant_in,
                            "intersection": (base < 0) & constant_in,
                            "difference": (base < 0) & constant_out}[operation]
            fixed = constant_in | constant_out
            new_i.append(keys[fixed & inside_after])
            sel = np.flatnonzero(~fixed)
        # the shape at every voxel of the selected blocks, a few thousand blocks per call
        for start in range(0, sel.size, _BLOCKS_PER_CALL):
            part = sel[start:start + _BLOCKS_PER_CALL]
            origins = unpack_keys(keys[part]).astype(np.float64) * bsz * cell
            if isinstance(shape, Box):
                s = (_box_blocks(shape, origins, bsz, cell) * scale).astype(np.float32)
            else:
                pts = (origins[:, None, :] + local[None, :, :]).reshape(-1, 3)
                s = (shape.evaluate(pts) * scale).astype(np.float32).reshape(-1, bsz, bsz, bsz)
            vals = (grid.data[part] if base is None
                    else np.full((part.size,) + (bsz,) * 3, base, np.float32))
            new_e_keys.append(keys[part])
            new_e_data.append(_apply(operation, vals, s))
    keys_out = (np.concatenate(new_e_keys).astype(np.int64) if new_e_keys
                else np.zeros(0, np.int64))
    data_out = (np.concatenate(new_e_data) if new_e_data
                else np.zeros((0, bsz, bsz, bsz), np.float32))
    inside_out = np.sort(np.concatenate(new_i)) if new_i else np.zeros(0, np.int64)
    # drop evaluated blocks without any inside voxel next to nothing inside: keep all (cheap)
    return SparseGrid(cell, bsz, keys_out, data_out.astype(np.float32), inside_out,
                      grid.inside_value, grid.outside_value)
