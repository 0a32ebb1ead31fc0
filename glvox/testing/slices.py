"""A CPU formulation of ``eisemann-surface`` (Eisemann & Decoret 2006's OR surface).

The OR variant draws every triangle along the render axis ``a`` and, for each
fragment (a column center ``c`` of the ``(a+1, a+2)`` plane covered by the
triangle's projection), sets the one voxel of the column that holds the
crossing ``q`` (the triangle's ``a`` coordinate at ``c``): slice ``floor(q)``,
the grid's far face ``q = n_a`` belonging to the last slice, crossings outside
``[0, n_a]`` setting nothing.  Coverage follows the top-left rule of
:func:`glvox.reference.solid` (``coverage='exact'``), with the same
symmetric edge functions, so a center on an edge shared by two triangles is
covered by exactly one.  Triangles parallel to ``a`` cover no center.

This is the method's definition written independently of its shaders (a
rasterizer, XOR/OR masks, render targets): on geometry where nothing rounds
the two must agree voxel for voxel.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..grid import snap_to_planes
from ..reference._candidates import check_axis, check_dims, check_tris, normals
from ..reference.solid import column_crossings


def eisemann_slices(tris: np.ndarray, dims: Sequence[int], axis: int = 2) -> np.ndarray:
    """The voxels ``eisemann-surface`` sets (module docstring), (nx, ny, nz) bool.

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Triangle vertices in voxel space.
    dims : (3,) int
        Grid size ``(nx, ny, nz)``.
    axis : {0, 1, 2}
        The render axis.
    """
    tris = check_tris(tris)
    dims = check_dims(dims)
    axis = check_axis(axis)
    u, v = (axis + 1) % 3, (axis + 2) % 3
    n = normals(tris)
    keep = n[:, axis] != 0.0
    tris, n = tris[keep], n[keep]
    out = np.zeros(dims, dtype=bool)
    # the crossings of reference-solid and reference-ldi: the top-left rule at the column centers
    for tri, ju, jv, q in column_crossings(tris, n, dims, axis):
        s = np.where(q == dims[axis], dims[axis] - 1, np.floor(q))
        ok = (s >= 0) & (s < dims[axis])
        idx = [None] * 3
        idx[axis], idx[u], idx[v] = s[ok].astype(np.int64), ju[ok], jv[ok]
        out[tuple(idx)] = True
    return out


def edge_on_boxes(tris: np.ndarray, dims, axis: int, rtol: float = 1e-6) -> np.ndarray:
    """Voxels in the bounding box of a triangle whose normal is within ``rtol`` of
    perpendicular to ``axis``: its crossing at a column center is rounding (a wall parallel
    to the axis up to the float32 rounding of its vertices: messy_wallhole.obj)."""
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    edge_on = np.abs(n[:, axis]) <= rtol * np.linalg.norm(n, axis=1)
    out = np.zeros(tuple(dims), bool)
    for t in tris[edge_on & (n[:, axis] != 0)]:
        lo = np.maximum(np.floor(t.min(axis=0)).astype(int) - 1, 0)
        hi = np.minimum(np.floor(t.max(axis=0)).astype(int) + 1, np.array(dims) - 1)
        out[lo[0]:hi[0] + 1, lo[1]:hi[1] + 1, lo[2]:hi[2] + 1] = True
    return out


def double_voxel_coords(mesh, spec) -> np.ndarray:
    """The triangles in voxel space as the Eisemann pipeline sees them, (T, 3, 3) float64: its
    transform runs in double (transform_vertices(double=True)), gpu_vertices_voxel without the
    final float32 rounding."""
    v32, _ = mesh.gpu_arrays()
    origin = np.asarray(spec.origin, dtype=np.float64) - mesh.anchor
    return snap_to_planes((v32.astype(np.float64) - origin) * (1.0 / spec.voxel_size))[mesh.faces]


def off_slices(got: np.ndarray, mesh, spec, axis: int) -> np.ndarray:
    """The voxels where ``got`` (an ``eisemann-surface`` result, dense) is not its CPU
    formulation :func:`eisemann_slices` on the vertices the GPU sees, (nx, ny, nz) bool.

    Excused: voxels near triangles edge-on to the render axis up to rounding, whose
    crossings rounding places, and where a crossing lies within 1e-9 voxel of a slice
    boundary or a column center within 1e-9 voxel of a projected edge (all of these on
    messy_wallhole.obj alone among the shared meshes, with vertices at thirds of the grid).
    """
    tris = double_voxel_coords(mesh, spec)
    # a crossing within 1e-9 voxel of a slice boundary (the GPU's double arithmetic in
    # another order): both slices are the definition's, up to that rounding
    shift = np.zeros(3)
    shift[axis] = 1e-9
    knife = eisemann_slices(tris + shift, spec.dims, axis) ^ eisemann_slices(tris - shift, spec.dims, axis)
    diff = (got ^ eisemann_slices(tris, spec.dims, axis)) & ~edge_on_boxes(tris, spec.dims, axis) & ~knife
    # a column center within 1e-9 voxel of a projected edge: which triangle covers it is
    # the sign of a rounded zero (the GPU's double arithmetic may contract it differently)
    u, v = (axis + 1) % 3, (axis + 2) % 3
    for idx in np.argwhere(diff):
        c = np.array([idx[u] + 0.5, idx[v] + 0.5])
        p, q = tris[:, :, [u, v]], np.roll(tris, -1, axis=1)[:, :, [u, v]]
        d, w = q - p, c - p
        t = np.clip(np.einsum("tei,tei->te", w, d) / np.maximum(np.einsum("tei,tei->te", d, d), 1e-300), 0, 1)
        if (np.linalg.norm(w - t[..., None] * d, axis=-1) <= 1e-9).any():
            diff[tuple(idx)] = False
    return diff
