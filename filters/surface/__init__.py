"""Implicit surfaces of particles: splatting onto a block-sparse voxel grid, contouring support,
smoothing, mesh utilities and constructive solid geometry.

:mod:`filters.surface.grid` (sparse and dense voxel grids), :mod:`filters.surface.splat`
(spherical kernels), :mod:`filters.surface.anisotropy` and :mod:`filters.surface.ellipsoids`
(anisotropic kernels, Yu & Turk 2013), :mod:`filters.surface.smoothing` (feature-weighted
Laplacian smoothing, Löschner et al. 2023), :mod:`filters.surface.mesh` (stitching and mesh
statistics), :mod:`filters.surface.csg` (fields combined with :mod:`filters.geometry` shapes).
"""
