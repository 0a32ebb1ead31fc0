"""glvox: headless GPU voxelization of triangle meshes, with exact CPU references.

The whole public API in one place::

    import glvox
    grid = glvox.voxelize("bunny.ply", 128, method="reference-conservative")
    grid.dense()          # bool (nx, ny, nz), indexed [i, j, k]
    grid.run.timings      # per-stage wall (and GPU) times
    glvox.save(grid, "bunny.npz")
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .errors import (BackendError, CapabilityError, EmptyMeshError, FaceIndexError, FormatError,
                     GlvoxError, GLError, GridError, LimitError, MeshError, MeshLoadError,
                     MethodError, NonFiniteVertexError, NotWatertightError, ShaderError)
from .grid import GridSpec, VoxelGrid, fit_grid
from .io import load, save
from .mesh import Mesh, load_mesh

__version__ = "0.1.0"

#: The method ``voxelize`` uses when none is named.
DEFAULT_METHOD = "ss-conservative"

__all__ = [
    "voxelize", "grid_for", "load_mesh", "fit_grid", "save", "load", "list_methods", "info",
    "GridSpec", "VoxelGrid", "Mesh", "DEFAULT_METHOD",
    "GlvoxError", "BackendError", "CapabilityError", "EmptyMeshError", "FaceIndexError",
    "FormatError", "GLError", "GridError", "LimitError", "MeshError", "MeshLoadError",
    "MethodError", "NonFiniteVertexError", "NotWatertightError", "ShaderError",
]


def grid_for(mesh: Mesh, resolution: int | None = None, *, dims: Sequence[int] | None = None,
             voxel_size: float | None = None, bounds: Any = None, padding: int = 0,
             tight: bool = False) -> GridSpec:
    """The grid spec for ``mesh`` (see :func:`glvox.grid.fit_grid`).

    ``bounds`` (2, 3) replaces the mesh's bounding box as the region to cover.
    """
    b = mesh.bounds if bounds is None else np.asarray(bounds, dtype=np.float64)
    return fit_grid(b, resolution, dims=dims, voxel_size=voxel_size, padding=padding, tight=tight)


def voxelize(mesh: Any, resolution: int | None = None, method: str = DEFAULT_METHOD, *,
             grid: GridSpec | None = None, dims: Sequence[int] | None = None,
             voxel_size: float | None = None, bounds: Any = None, padding: int = 0,
             tight: bool = False, allow_open: bool = False, backend: str | None = None,
             ctx=None, **options: Any):
    """Voxelize a mesh with a registered method.

    Parameters
    ----------
    mesh : path, "gen:NAME", trimesh.Trimesh, (vertices, faces) or Mesh
    resolution : int, optional
        N: voxels along the longest axis; cubic N^3 grid centered on the mesh
        (the papers' fit).  Or give ``grid``, ``dims`` or ``voxel_size``.
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
    **options
        Method options.

    Returns
    -------
    VoxelGrid (surface and solid methods) or the method kind's result type;
    ``.run`` holds method, grid, timings and statistics.
    """
    from .methods import run_method

    m = load_mesh(mesh)
    if grid is None:
        if resolution is None and dims is None and voxel_size is None:
            raise GridError("give a resolution (or dims, voxel_size or grid)")
        grid = grid_for(m, resolution, dims=dims, voxel_size=voxel_size, bounds=bounds,
                        padding=padding, tight=tight)
    return run_method(method, m, grid, ctx=ctx, backend=backend, allow_open=allow_open, **options)


def list_methods(kind: str | None = None, family: str | None = None):
    """Registry entries (:class:`glvox.methods.MethodInfo`), optionally filtered."""
    from .methods import method_infos

    return method_infos(kind, family)


def info(backend: str | None = None) -> dict:
    """Backend, vendor, renderer, GL version and limits of the shared context."""
    from .context import get_context

    return get_context(backend).describe()
