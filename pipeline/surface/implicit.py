"""The implicit field of particles and its contour, the first two stages of the surface chain.

:class:`MetaballSplat` splats particles (vtkPointSet) into an implicit field (negative inside)
on a voxel lattice, dense (vtkImageData) or in bricks (a vtkPartitionedDataSet of images), with
the kernels of :mod:`filters.surface.splat`, anisotropic ones included, optionally combined
with a shape (:mod:`filters.surface.csg`); :class:`MarchingCubes` contours it into one
watertight vtkPolyData (flying edges or marching tetrahedra, :mod:`pipeline.surface.contour`).
"""

from __future__ import annotations

import math

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import (
    vtkDataObject,
    vtkImageData,
    vtkPartitionedDataSet,
    vtkPointSet,
    vtkPolyData,
)

from filters.geometry import Box, Shape
from filters.kernels import SPLAT_DEFAULTS, SPLAT_KERNELS
from filters.surface.anisotropy import check_anisotropy
from filters.surface.csg import OPERATIONS, combine_dense, combine_sparse
from filters.surface.ellipsoids import ANISOTROPIC_KERNELS
from filters.surface.grid import DEFAULT_MAX_BYTES, check_budget
from filters.surface.splat import (
    splat_dense,
    splat_dense_anisotropic,
    splat_sparse,
    splat_sparse_anisotropic,
)
from filters.surface.tetra import TetraPieces
from filters.surface.walls import WALL_MARGIN_R, grow_walls
from filters.validation import check_bool, check_choice, check_int, check_range

from ..algorithm import Algorithm
from .contour import (
    CONTOUR_METHODS,
    Pieces,
    brick_images,
    check_grid_sizes,
    flying_edges,
    image_of,
    mesh_to_polydata,
)
from .options import SURFACE_DEFAULTS
from .particle_stages import (
    check_optional_range,
    check_optional_str,
    particles_from,
    radii_from,
)

__all__ = ["MetaballSplat", "MarchingCubes"]


class MetaballSplat(Algorithm):
    """Particles (vtkPolyData / any vtkPointSet) -> implicit field on a voxel lattice.

    Parameters
    ----------
    radius : float
        Particle radius (m), > 0, used where the input has no ``radius_array``.
    cell_size : float, optional
        Voxel edge (m), > 0; default ``radius / 2`` (splashsurf's cube size 0.5).
    kernel : {"blobby", "metaball", "sph", "zhu_bridson"}
        See :mod:`filters.kernels`.
    support_r, iso, blobbiness
        See :func:`filters.surface.splat.splat_sparse` (``support_r`` in (0, 1000] multiples
        of the radius, ``iso`` > 0, ``blobbiness`` in (0, 100]).
    radius_array : str, optional
        Point array holding per-particle radii (m).
    sparse : bool
        True: a vtkPartitionedDataSet of image bricks covering the surface (memory follows the
        surface); False: one vtkImageData over the whole reachable box.
    block_size, brick_blocks : int
        Voxels per block edge, in [4, 64]; blocks per brick edge, in [1, 64] (sparse output).
    max_bytes : int
        Memory budget (bytes) of the grid, >= 1.
    implicit : filters.geometry.Shape, optional
        A shape combined with the particle field by ``operation`` (:mod:`filters.surface.csg`).
        A :class:`filters.geometry.Box` intersected with the field is the liquid's tank (see
        ``mirror_walls``).
    operation : {"union", "intersection", "difference"}
        How ``implicit`` combines with the particles' field.
    anisotropic : bool
        Splat ellipsoidal kernels stretched along the local particle distribution (Yu & Turk
        2013, :mod:`filters.surface.anisotropy`): flat water without bumps and sharper edges, at
        a higher cost; drops of a few particles come out larger. Kernels ``sph``, ``metaball``
        and ``blobby``.
    anisotropy : dict, optional
        Options of :func:`filters.surface.anisotropy.anisotropic_kernels` (``neighbor_radius_r``,
        ``stretch``, ``min_neighbors``, ``smoothing``, ``layer_band_r``, ``max_axis_r``,
        ``isotropy``).
    mirror_walls : bool
        With a :class:`filters.geometry.Box` ``implicit`` and ``operation="intersection"`` (the
        liquid's tank): mirror the particles near its walls across them (ghost particles,
        :mod:`filters.surface.walls`) and intersect the field with the box grown by one
        spacing (:data:`filters.surface.walls.WALL_MARGIN_R` radii) instead: the surface goes
        on through the walls, and :class:`pipeline.surface.liquid.ClipBox` cuts it exactly at them
        (:func:`surface_stages` adds it), so that it meets the walls, their edges and corners
        without a gap.
    """

    def __init__(self, radius: float = SURFACE_DEFAULTS["radius"], cell_size: float | None = None,
                 *, kernel: str = SURFACE_DEFAULTS["kernel"], support_r: float | None = None,
                 iso: float | None = None,
                 blobbiness: float = 4.0, radius_array: str | None = None, sparse: bool = True,
                 block_size: int = 8, brick_blocks: int = 4,
                 max_bytes: int = DEFAULT_MAX_BYTES, implicit: Shape | None = None,
                 operation: str = "intersection", anisotropic: bool = False,
                 anisotropy: dict | None = None, mirror_walls: bool = False):
        self.radius = check_range("radius", radius, 0.0, math.inf, low_inclusive=False,
                                  high_inclusive=False)
        self.cell_size = (self.radius / 2 if cell_size is None else
                          check_range("cell_size", cell_size, 0.0, math.inf, low_inclusive=False,
                                      high_inclusive=False))
        self.kernel = check_choice("kernel", kernel, SPLAT_KERNELS)
        self.anisotropic = check_bool("anisotropic", anisotropic)
        if self.anisotropic and kernel not in ANISOTROPIC_KERNELS:
            raise ValueError(f"kernel must be one of {', '.join(map(repr, ANISOTROPIC_KERNELS))} "
                             f"when anisotropic=True, got {kernel!r}")
        self.support_r = check_optional_range("support_r", support_r, 0.0, 1e3, False)
        self.iso = check_optional_range("iso", iso, 0.0, math.inf)
        self.blobbiness = check_range("blobbiness", blobbiness, 0.0, 100.0, low_inclusive=False)
        self.radius_array = check_optional_str("radius_array", radius_array)
        self.sparse = check_bool("sparse", sparse)
        self.block_size = check_int("block_size", block_size, 4, 64)
        self.brick_blocks = check_int("brick_blocks", brick_blocks, 1, 64)
        self.max_bytes = check_int("max_bytes", max_bytes, 1)
        if implicit is not None and not isinstance(implicit, Shape):
            raise TypeError(f"implicit must be a filters.geometry.Shape or None, got "
                            f"{type(implicit).__name__}")
        self.implicit = implicit
        self.operation = check_choice("operation", operation, OPERATIONS)
        self.mirror_walls = check_bool("mirror_walls", mirror_walls)
        if anisotropy is not None and not isinstance(anisotropy, dict):
            raise TypeError(f"anisotropy must be a dict of options, got {anisotropy!r}")
        self.anisotropy = dict(anisotropy or {})
        if self.anisotropy:
            support = (self.support_r if self.support_r is not None
                       else SPLAT_DEFAULTS[self.kernel]["support"])
            check_anisotropy(support, **self.anisotropy)
        check_grid_sizes(self.radius, self.cell_size, self.kernel, self.support_r,
                         self.block_size, self.brick_blocks, self.max_bytes,
                         self.sparse and self.radius_array is None)
        Algorithm.__init__(
            self, nInputPorts=1, inputType="vtkPointSet", nOutputPorts=1,
            outputType="vtkPartitionedDataSet" if self.sparse else "vtkImageData")

    def _options(self):
        options = dict(kernel=self.kernel, support_r=self.support_r, iso=self.iso,
                       block_size=self.block_size, blobbiness=self.blobbiness,
                       max_bytes=self.max_bytes)
        if self.walls is not None:
            # the liquid's tank: ghosts mirrored across its walls
            options["walls"] = self.walls
        if self.anisotropic:
            options.update(self.anisotropy)
        return options

    @property
    def walls(self) -> Box | None:
        """The tank whose walls the particles are mirrored across, or None."""
        if self.mirror_walls and isinstance(self.implicit, Box) \
                and self.operation == "intersection":
            return self.implicit
        return None

    def _shape(self, radius):
        """The shape combined with the field: the tank grown by WALL_MARGIN_R radii with
        ghosts, else ``implicit``."""
        if self.walls is None:
            return self.implicit
        margin = WALL_MARGIN_R * float(np.max(radius)) if np.size(radius) else 0.0
        lo, hi = grow_walls((np.asarray(self.walls.lower, float),
                             np.asarray(self.walls.upper, float)), margin)
        return Box(tuple(lo), tuple(hi))

    def _splat(self, sparse: bool):
        """The splatting function for the chosen grid and kernel shape."""
        if self.anisotropic:
            return splat_sparse_anisotropic if sparse else splat_dense_anisotropic
        return splat_sparse if sparse else splat_dense

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkPointSet.GetData(inInfo[0], 0)
        positions = particles_from(inp)
        radius = radii_from(inp, positions, self.radius, self.radius_array)
        if self.sparse:
            grid = self._splat(True)(positions, radius, self.cell_size, **self._options())
            if self.implicit is not None:
                grid = combine_sparse(grid, self._shape(radius), self.operation,
                                      max_bytes=self.max_bytes)
            out = vtkPartitionedDataSet.GetData(outInfo, 0)
            out.Initialize()
            k = 0
            spent = grid.data.nbytes
            for origin, values in brick_images(grid, self.brick_blocks, max_bytes=self.max_bytes):
                # deep copies: the output outlives this call and the reused buffer; they count
                # against the budget with the grid
                spent += values.nbytes
                check_budget(spent, self.max_bytes, f"the grid and {k + 1} brick images of "
                             f"{values.shape[0]}^3 voxels")
                image, _keep = image_of(values, origin, deep=True)
                image.SetOrigin(*(origin.astype(np.float64) * grid.cell_size))
                image.SetSpacing(grid.cell_size, grid.cell_size, grid.cell_size)
                out.SetPartition(k, image)
                k += 1
        else:
            field = self._splat(False)(positions, radius, self.cell_size, **self._options())
            if self.implicit is not None:
                field = combine_dense(field, self._shape(radius), self.operation)
            out = vtkImageData.GetData(outInfo, 0)
            image, _keep = image_of(np.ascontiguousarray(field.values), field.index_origin,
                                    deep=True)
            out.ShallowCopy(image)
            out.SetOrigin(*field.origin)
            out.SetSpacing(field.cell_size, field.cell_size, field.cell_size)
        return 1


class MarchingCubes(Algorithm):
    """Implicit field (vtkImageData or a brick set) -> one watertight vtkPolyData.

    Parameters
    ----------
    value : float
        Contour value, finite (0 for :class:`MetaballSplat` output: negative inside).
    method : {"flying_edges", "tetrahedra"}
        ``"flying_edges"``: VTK's vtkFlyingEdges3D (marching cubes); ``"tetrahedra"``: marching
        tetrahedra on the Kuhn split of every cube (:mod:`filters.surface.tetra`), in Numba,
        about twice the triangles.  Both stitch bricks into one mesh with shared vertices.
    """

    def __init__(self, value: float = 0.0, method: str = "flying_edges"):
        self.value = check_range("value", value)
        if not math.isfinite(self.value):
            raise ValueError(f"value must be finite, got {value!r}")
        self.method = check_choice("method", method, CONTOUR_METHODS)
        Algorithm.__init__(self, nInputPorts=1, inputType="vtkDataObject", nOutputPorts=1,
                           outputType="vtkPolyData")

    def RequestData(self, request, inInfo, outInfo):
        inp = vtkDataObject.GetData(inInfo[0], 0)
        pts, tris = self._contour(inp)
        vtkPolyData.GetData(outInfo, 0).ShallowCopy(mesh_to_polydata(pts, tris))
        return 1

    def _contour(self, inp):
        if isinstance(inp, vtkImageData):
            images = [inp]
        elif isinstance(inp, vtkPartitionedDataSet):
            images = [inp.GetPartition(i) for i in range(inp.GetNumberOfPartitions())]
            images = [im for im in images if im is not None]
        else:
            raise TypeError(f"MarchingCubes needs vtkImageData or vtkPartitionedDataSet input, "
                            f"got {inp.GetClassName()}")
        tetra = self.method == "tetrahedra"
        if tetra:
            pieces = TetraPieces(self.value)
        else:
            fe = flying_edges()
            fe.SetValue(0, self.value)
            pieces = Pieces()
        cell = None
        for im in images:
            if im.GetNumberOfPoints() == 0 or min(im.GetDimensions()) < 2:
                continue
            spacing = np.array(im.GetSpacing())
            if not np.allclose(spacing, spacing[0]):
                raise ValueError(f"MarchingCubes needs cubic voxels, got spacing "
                                 f"{spacing.tolist()}")
            if cell is None:
                cell = float(spacing[0])
            # contour in index space so that bricks share bitwise equal vertices
            index_origin = np.round(np.array(im.GetOrigin()) / spacing)
            if tetra:
                nx, ny, nz = im.GetDimensions()
                scalars = im.GetPointData().GetScalars()
                if scalars is None:
                    raise ValueError("MarchingCubes needs point scalars on its input images")
                values = numpy_support.vtk_to_numpy(scalars).reshape(nz, ny, nx)
                pieces.add(values, index_origin.astype(np.int64))
                continue
            work = vtkImageData()
            work.ShallowCopy(im)
            work.SetOrigin(*index_origin)
            work.SetSpacing(1.0, 1.0, 1.0)
            fe.SetInputData(work)
            fe.Modified()
            fe.Update()
            pieces.add(fe, index_origin, index_origin + np.array(im.GetDimensions()) - 1)
        return pieces.mesh(1.0 if cell is None else cell)
