"""glvox: headless GPU voxelization of triangle meshes, with exact CPU references.

The whole public API in one place (nothing inside glvox imports this module)::

    import glvox
    grid = glvox.voxelize("bunny.ply", 128, method="reference-conservative")
    grid.dense()          # bool (nx, ny, nz), indexed [i, j, k]
    grid.run.timings      # per-stage wall (and GPU) times
    glvox.save(grid, "bunny.npz")
"""

from __future__ import annotations

import os
from typing import Any, Sequence

from ._version import __version__
from . import datasets
from .errors import (BackendError, CapabilityError, DatasetError, EmptyMeshError, FaceIndexError, FormatError,
                     GLError, GlvoxError, GridError, LimitError, MeshError, MeshLoadError, MeshNotFoundError,
                     MethodError, NonFiniteVertexError, NotWatertightError, ShaderError)
from .gl.context import get_context
from .gpu.cuda import check_device
from .grid import DEFAULT_RESOLUTION, GridSpec, fit_grid, grid_for
from .inspect import MeshReport, inspect_mesh
from .io import load, save
from .mesh import Mesh
from .mesh import load_mesh as _load_mesh
from .methods import DEFAULT_METHOD, Request, get_method, method_infos, run_method
from .methods.ldi.leung_wang import overlap_bounds, overlap_grid, run_intersection
from .methods.sdf.field import DEFAULT_BAND, signed_distance_field
from .methods.sdf.samples import sdf_samples as _sdf_samples
from .results import LDI, SDFGrid, SparseOctree, VoxelGrid
from .visuals import load_visual_mesh

__all__ = [
    "voxelize", "grid_for", "load_mesh", "fit_grid", "save", "load", "list_methods", "info",
    "ldi", "sdf", "sdf_samples", "SDFGrid", "intersect_ldi", "intersecting_volume", "LDI", "datasets", "inspect_mesh", "MeshReport",
    "GridSpec", "VoxelGrid", "SparseOctree", "Mesh", "DEFAULT_METHOD", "DEFAULT_RESOLUTION", "__version__",
    "GlvoxError", "BackendError", "CapabilityError", "DatasetError", "EmptyMeshError", "FaceIndexError",
    "FormatError", "GLError", "GridError", "LimitError", "MeshError", "MeshLoadError", "MeshNotFoundError",
    "MethodError", "NonFiniteVertexError", "NotWatertightError", "ShaderError",
]


def _resolve(mesh: Any) -> Any:
    """A mesh argument as the command line takes it: a file, ``gen:NAME`` or a mesh name
    glvox knows (fetched when missing: :func:`glvox.datasets.resolve_mesh`); other
    arguments (arrays, trimesh objects, Mesh) as they are."""
    return datasets.resolve_mesh(mesh) if isinstance(mesh, (str, os.PathLike)) else mesh


def load_mesh(mesh: Any, *, name: str | None = None) -> Mesh:
    """Load and validate a mesh given as :func:`voxelize` and the command line take it.

    Parameters
    ----------
    mesh : path, "gen:NAME", mesh name, trimesh.Trimesh, (vertices, faces) or Mesh
        A file trimesh can load; ``"gen:NAME"``, a generated mesh
        (:func:`glvox.mesh.generated_mesh`); a name ``glvox data list`` shows
        (e.g. ``"stanford_bunny_bun_zipper.ply"``), looked for in
        ``GLVOX_MESHES``, ``../shared/meshes`` or the user cache and
        downloaded when missing (:mod:`glvox.datasets`); a trimesh mesh; or
        arrays, vertices (V, 3) float and faces (F, 3) int.  A :class:`Mesh`
        is returned as is.
    name : str, optional
        The mesh's label (default the file name).

    Returns
    -------
    Mesh

    Raises
    ------
    MeshNotFoundError
        Neither a file, ``gen:NAME`` nor a known name (the command line's
        one-line message; a :class:`MeshLoadError` and a :class:`DatasetError`).
    DatasetError, MeshLoadError, EmptyMeshError, NonFiniteVertexError, FaceIndexError
    """
    return _load_mesh(_resolve(mesh), name=name)


def voxelize(mesh: Any, resolution: int | None = None, method: str = DEFAULT_METHOD, *,
             grid: GridSpec | None = None, dims: Sequence[int] | None = None,
             voxel_size: float | None = None, bounds: Any = None, padding: int = 0,
             tight: bool = False, allow_open: bool = False, backend: str | None = None,
             ctx=None, attributes: Any = None, normals: str = "face", fill_attributes: str = "none",
             progress=None, device: str | None = None, **options: Any):
    """Voxelize a mesh with a registered method.

    Parameters
    ----------
    mesh : path, "gen:NAME", mesh name, trimesh.Trimesh, (vertices, faces) or Mesh
        As :func:`load_mesh` takes it.
    resolution : int, optional
        N: voxels along the longest axis; cubic N^3 grid centered on the mesh
        (the papers' fit).  Or give ``grid``, ``dims`` or ``voxel_size``; with
        none of them, :data:`~glvox.grid.DEFAULT_RESOLUTION` (128).
    method : str
        Registry name (``glvox methods`` lists them).
    grid : GridSpec, optional
        Explicit placement; overrides every other grid argument.
    dims, voxel_size, bounds, padding, tight
        Other fits, see :func:`glvox.grid.fit_grid`.
    allow_open : bool
        Let solid methods run on meshes that are not watertight.
    backend : {'egl', 'osmesa', 'auto'}, optional
    ctx : GLContext, optional
    attributes : sequence of str or comma-separated str, optional
        ``triangle``, ``color``, ``normal``, ``material``: carried per set
        voxel from its source triangle (``result.attributes``, one row per
        ``result.indices()`` row; README "Attributes").  The mesh is then
        loaded with its materials and textures.
    normals : {'face', 'vertex'}
    fill_attributes : {'none', 'nearest'}
        Solid methods: what interior voxels carry.
    progress : callable, optional
        ``progress(done, total)`` after each z slab where the method works the grid
        in slabs (as :func:`glvox.methods.run_method`).
    device : {'host', 'cuda'}, optional
        'cuda': the packed words stay in CUDA memory on the GL context's GPU,
        ``result.device_words``, a DLPack producer for PyTorch, CuPy or JAX
        (:mod:`glvox.gpu.cuda`; ``pip install 'glvox[cuda]'``).
    **options
        Method options.

    Returns
    -------
    VoxelGrid (surface and solid methods) or the method kind's result type;
    ``.run`` holds method, grid, timings and statistics.
    """
    # before loading: unknown methods, options and attributes fail fast, and are not checked again
    request = Request.make(method, options, attributes, normals, fill_attributes)
    check_device(device)
    m = load_visual_mesh(_resolve(mesh)) if request.attributes else load_mesh(mesh)
    if grid is None:
        if resolution is None and dims is None and voxel_size is None:
            resolution = DEFAULT_RESOLUTION
        grid = grid_for(m, resolution, dims=dims, voxel_size=voxel_size, bounds=bounds,
                        padding=padding, tight=tight)
    return run_method(request, m, grid, ctx=ctx, backend=backend, allow_open=allow_open, progress=progress,
                      device=device)


def ldi(mesh: Any, resolution: int | None = None, method: str = "leung-wang-ldi", *,
        grid: GridSpec | None = None, dims: Sequence[int] | None = None,
        voxel_size: float | None = None, bounds: Any = None, padding: int = 0, tight: bool = False,
        allow_open: bool = False, backend: str | None = None, ctx=None, **options: Any) -> LDI:
    """A layered depth image of a mesh (an ``ldi`` method; default Leung & Wang's conservative LDI).

    Rays run along ``axis`` (option, default 2 = z) through the centers of the
    grid's voxel columns; see :class:`glvox.ldi.LDI`.

    Parameters
    ----------
    mesh, resolution, grid, dims, voxel_size, bounds, padding, tight, allow_open, backend, ctx
        As :func:`voxelize`.
    method : {'leung-wang-ldi', 'peel-ldi', 'reference-ldi'}
    **options
        Method options, e.g. ``lod_c=1024, axis=2`` (``glvox methods --kind ldi``).

    Returns
    -------
    LDI
        ``.depths`` (n_p, n_q, n_max) float32 voxel units along the axis,
        ``.counts``, ``.volume``, ``.to_grid()``, ``.save(path)``.
    """
    kind = get_method(method).info.kind
    if kind != "ldi":
        raise MethodError(f"glvox.ldi needs a method of kind 'ldi', got {method!r} (kind {kind!r}); "
                          "use glvox.voxelize for voxel grids")
    return voxelize(mesh, resolution, method, grid=grid, dims=dims, voxel_size=voxel_size, bounds=bounds,
                    padding=padding, tight=tight, allow_open=allow_open, backend=backend, ctx=ctx, **options)


def intersect_ldi(mesh_a: Any, mesh_b: Any, resolution: int | None = None, *, lod_c: int = 1024,
                  axis: int = 2, grid: GridSpec | None = None, dims: Sequence[int] | None = None,
                  voxel_size: float | None = None, padding: int = 0, allow_open: bool = False,
                  backend: str | None = None, ctx=None, targets: int = 8) -> LDI:
    """The conservative LDI of the overlap of two closed meshes (Leung & Wang 2013 Sec. V-A).

    The grid (unless ``grid`` is given) is fitted to the intersection of the
    two bounding boxes, where the overlap lies; when those do not overlap in
    volume, to the union of the boxes (the LDI is then empty).

    Parameters
    ----------
    mesh_a, mesh_b : path, "gen:NAME", mesh name, trimesh.Trimesh, (vertices, faces) or Mesh
    resolution, grid, dims, voxel_size, padding
        The grid, as :func:`voxelize` (fitted to the overlap region; with
        none of them, :data:`~glvox.grid.DEFAULT_RESOLUTION`).
    lod_c : int
        Cells along the rays (Leung & Wang's LOD-C).
    axis : {0, 1, 2}
        Ray direction.

    Returns
    -------
    LDI
        ``.volume`` is the intersecting volume (world units cubed); it bounds
        the overlap sampled on the rays from above.
    """
    a, b = load_mesh(mesh_a), load_mesh(mesh_b)
    if grid is None:
        if resolution is None and dims is None and voxel_size is None:
            resolution = DEFAULT_RESOLUTION
        grid = overlap_grid(a, b, resolution, dims=dims, voxel_size=voxel_size, padding=padding)
    return run_intersection(a, b, grid, ctx=ctx, backend=backend, allow_open=allow_open, lod_c=lod_c,
                            axis=axis, targets=targets)


def intersecting_volume(mesh_a: Any, mesh_b: Any, resolution: int | None = None, **kwargs: Any) -> float:
    """The intersecting volume of two closed meshes in world units cubed, from the
    conservative LDI of their overlap (:func:`intersect_ldi`, same arguments);
    0.0 when their bounding boxes do not overlap in volume."""
    a, b = load_mesh(mesh_a), load_mesh(mesh_b)
    if kwargs.get("grid") is None and overlap_bounds(a, b) is None:
        return 0.0
    return intersect_ldi(a, b, resolution, **kwargs).volume


def sdf(mesh: Any, resolution: int | None = None, *, grid: GridSpec | None = None, band: Any = DEFAULT_BAND,
        sign: str = "solid", truncation: Any = None, dims: Sequence[int] | None = None,
        voxel_size: float | None = None, bounds: Any = None, padding: int = 0, tight: bool = False,
        allow_open: bool = False, backend: str | None = None, ctx=None) -> SDFGrid:
    """The signed distance from every voxel center to the mesh, on the GPU.

    Parameters
    ----------
    mesh : path, "gen:NAME", mesh name, trimesh.Trimesh, (vertices, faces) or Mesh
        As :func:`load_mesh` takes it.
    resolution, grid, dims, voxel_size, bounds, padding, tight
        The grid, as :func:`voxelize`.
    band : float or 'all'
        Voxels: distances are exact within ``band`` voxels of the surface and
        ``+-band * voxel_size`` beyond (clamped); ``'all'``: exact everywhere
        (the voxels beyond the band on the CPU: slower).
    sign : str
        The solid method whose occupancy gives the sign (inside negative);
        ``'solid'`` picks one per mesh.
    truncation : float, str or None
        A TSDF: values clamped to ``+-truncation`` (world units, or voxels as
        ``'2vox'``); a truncation wider than the band widens the band.
    allow_open, backend, ctx
        As :func:`voxelize`.

    Returns
    -------
    SDFGrid
        ``.sdf`` float32 (nx, ny, nz) in world units, ``.band`` and
        ``.uncertain`` bool (nx, ny, nz), ``.origin``, ``.voxel_size``, ``.dims``.
    """
    m = load_mesh(mesh)
    if grid is None:
        if resolution is None and dims is None and voxel_size is None:
            resolution = DEFAULT_RESOLUTION
        grid = grid_for(m, resolution, dims=dims, voxel_size=voxel_size, bounds=bounds, padding=padding,
                        tight=tight)
    return signed_distance_field(m, grid, band=band, sign=sign, truncation=truncation, ctx=ctx,
                                 backend=backend, allow_open=allow_open)


def sdf_samples(mesh: Any, n: int, *, seed: int = 0, **kwargs: Any) -> dict:
    """``n`` points near the surface (area-weighted, Gaussian offsets) and in the box, each with its
    exact signed distance (world units); see :func:`glvox.methods.sdf.samples.sdf_samples`."""
    return _sdf_samples(load_mesh(mesh), n, seed=seed, **kwargs)


def list_methods(kind: str | None = None, family: str | None = None, pipeline: str | None = None):
    """Registry entries (:class:`glvox.methods.MethodInfo`), optionally filtered by kind
    (``'surface'``, ``'solid'``, ``'ldi'``, ``'sparse'``), family (``'ss'``, ``'depth'``, ...)
    or pipeline (``'raster'``, ``'compute'``, ``'cpu'``)."""
    return method_infos(kind, family, pipeline)


def info(backend: str | None = None) -> dict:
    """Backend, vendor, renderer, GL version and limits of the shared context."""
    return get_context(backend).describe()
