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

from glvox.reference._candidates import check_axis, check_dims, check_tris, normals
from glvox.reference.solid import column_crossings


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
