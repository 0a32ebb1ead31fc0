"""The voxels as a coloured point cloud or coloured cubes, through trimesh.

==================================  ===============================================================
suffix                              what is written (world coordinates, the mesh's frame)
==================================  ===============================================================
``.points.ply``, ``.points.glb``    one point per set voxel at its center, ``origin + (ijk + 1/2) h``,
                                    with the voxel's RGBA as the point's colour
``.cubes.ply``, ``.cubes.glb``      the exposed faces of the voxels' cubes (a face between two set
                                    voxels is left out), each a quad of two triangles wound outwards
                                    with four vertices of its own in the voxel's RGBA, so no colour
                                    bleeds across a cube's edge
==================================  ===============================================================

The double suffix keeps ``.ply`` and ``.glb`` for meshes (what ``glvox
voxelize`` reads) and says what the file holds.  Colours are the
``'color'`` attribute (:func:`glvox.formats.colors.voxel_colors`); voxels
without one, and every voxel of a result without colours, take
:data:`~glvox.formats.colors.DEFAULT_COLOR`.  PLY is binary with float32
positions and uchar RGBA; GLB keeps glTF's float32 positions and
``COLOR_0`` (glTF is y-up: the world's y is written as it is).  Readers
that merge vertices by position (trimesh's default ``process=True``) mix
the colours of neighbouring faces: read with ``process=False``.

Cube faces are found without a dense grid: the set voxels' linear indices
are sorted (C order), and a neighbour is set when ``searchsorted`` finds
it, so memory scales with the set voxels (4 vertices of 12 + 4 bytes per
exposed face in the file).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import FormatError
from ..results import Result
from .colors import filled, voxel_colors
from .common import Format, warn_dropped


def _export(geometry, path: Path, what: str) -> None:
    """trimesh's export by the file's last suffix, or a one-line FormatError."""
    file_type = path.suffix.lower().lstrip(".")
    try:
        data = geometry.export(file_type=file_type)
    except Exception as exc:  # noqa: BLE001 - trimesh raises ValueError, KeyError, NotImplementedError...
        raise FormatError(f"cannot write {what} as {file_type}: {exc}") from None
    path.write_bytes(data)


def points(result: Result):
    """A ``trimesh.PointCloud`` of the set voxels' world centers in their colours.

    Returns
    -------
    trimesh.PointCloud
        ``vertices`` (M, 3) float64 world centers in C order of the voxels,
        ``colors`` (M, 4) uint8 RGBA.
    """
    import trimesh  # lazy: trimesh takes a second to import and only the exports need it

    indices, colors = voxel_colors(result, "points")
    return trimesh.PointCloud(result.spec.centers(indices), colors=filled(colors, len(indices)))


def exposed_faces(indices: np.ndarray, dims) -> list[tuple[int, int, np.ndarray]]:
    """The exposed faces of a set of voxels, per direction.

    Parameters
    ----------
    indices : (M, 3) int64
        Set voxels in C order (sorted, as ``np.argwhere``).
    dims : (3,) int

    Returns
    -------
    list of (axis, sign, rows)
        For each of the six directions (axis 0..2, sign -1 or +1), the rows
        of ``indices`` whose neighbour that way is empty or outside the grid.
    """
    dims = np.asarray(dims, dtype=np.int64)
    strides = np.array([dims[1] * dims[2], dims[2], 1], dtype=np.int64)
    lin = indices @ strides
    out = []
    for axis in range(3):
        for sign in (-1, 1):
            inside = (indices[:, axis] + sign >= 0) & (indices[:, axis] + sign < dims[axis])
            nb = lin + sign * strides[axis]
            pos = np.minimum(np.searchsorted(lin, nb), max(len(lin) - 1, 0))
            has = inside & (lin[pos] == nb) if len(lin) else inside
            out.append((axis, sign, np.flatnonzero(~has)))
    return out


def cubes(result: Result):
    """A ``trimesh.Trimesh`` of the exposed faces of the voxels' cubes in their colours.

    Returns
    -------
    trimesh.Trimesh
        World coordinates; 4 vertices and 2 triangles per exposed face,
        wound so the normals point out of the voxels; ``vertex_colors``
        (V, 4) uint8, the voxel's RGBA.  Built with ``process=False`` (no
        vertex merging).
    """
    import trimesh  # lazy: trimesh takes a second to import and only the exports need it

    indices, colors = voxel_colors(result, "cubes")
    rgba = filled(colors, len(indices))
    h, origin = float(result.voxel_size), np.asarray(result.origin, np.float64)
    corners, quad_colors = [], []
    for axis, sign, rows in exposed_faces(indices, result.dims):
        e = np.eye(3, dtype=np.int64)
        u, v = e[(axis + 1) % 3], e[(axis + 2) % 3]
        base = indices[rows] + (sign > 0) * e[axis]
        # (axis, u, v) is cyclic, so u x v = +e_axis: counter-clockwise 0, u, u+v, v faces +axis
        ring = (0 * u, u, u + v, v) if sign > 0 else (0 * u, v, u + v, u)
        corners.append(np.stack([base + c for c in ring], axis=1))      # (F, 4, 3) voxel corners
        quad_colors.append(np.repeat(rgba[rows], 4, axis=0))
    quads = np.concatenate(corners)                       # six directions, each (F, 4, 3), maybe empty
    vertices = origin + quads.reshape(-1, 3) * h
    first = np.arange(len(quads), dtype=np.int64)[:, None] * 4
    faces = np.concatenate([first + [0, 1, 2], first + [0, 2, 3]], axis=1).reshape(-1, 3)
    return trimesh.Trimesh(vertices, faces, vertex_colors=np.concatenate(quad_colors), process=False)


def write_points(result: Result, path: Path) -> None:
    """Write the voxel centers in their colours (``.points.ply`` / ``.points.glb``)."""
    warn_dropped(result, "points", keeps="the voxel centers and their colours", keeps_attributes=("color",))
    _export(points(result), path, "points")


def write_cubes(result: Result, path: Path) -> None:
    """Write the voxels' exposed cube faces in their colours (``.cubes.ply`` / ``.cubes.glb``)."""
    warn_dropped(result, "cubes", keeps="the voxels' faces and their colours", keeps_attributes=("color",))
    _export(cubes(result), path, "cubes")


POINTS = Format("points", (".points.ply", ".points.glb"), write_points, None, attributes=("color",))
CUBES = Format("cubes", (".cubes.ply", ".cubes.glb"), write_cubes, None, attributes=("color",))
