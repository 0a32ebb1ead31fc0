"""Exact per-ray crossings (float64): the reference for layered depth images (LDI).

An LDI along ``axis`` has one ray per pixel center of the grid's other two
axes, ``(p, q) = ldi_axes(axis)`` in increasing order (x, y for rays along z;
y, z along x; x, z along y), through the centers ``(i + 1/2, j + 1/2)`` in
voxel space (docs/design.md).  A ray's crossings with the surface, sorted, are the
exact LDI samples: pairs ``(2i, 2i+1)`` bound the solid along the ray.

Which rays a triangle crosses and where is decided exactly as
``reference-solid`` decides it (:mod:`.solid`: edge functions from the
lexicographically smaller end point, top-left fill rule for centers on an edge,
the crossing from the plane clamped to the triangle's extent along the axis),
so a ray through a shared edge or vertex of a closed mesh crosses once and a
silhouette is crossed 0 or 2 times.  Depths are in voxel units along the
axis, clamped to the grid's range ``[0, n_axis]`` (the solid is clipped to the
grid, as every glvox result is).

:func:`ray_ties` is the tie set of docs/design.md for rays: the rays whose set of
crossed triangles can change when the mesh moves by at most ``eps`` voxel.
:func:`crossing_tolerance` bounds how far one crossing can move under such a
motion.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..grid import ldi_axes
from ._candidates import (check_axis, check_dims, check_eps, check_tris, expand, index_range, normals,
                          segment_distance)
from .solid import axis_signs, column_crossings
from .ties import TIE_EPS


@dataclass
class RayCrossings:
    """Sorted exact crossings of every pixel ray.

    Attributes
    ----------
    depths : (n_p, n_q, n_max) float64
        Crossing depths along the axis in voxel units, sorted per ray,
        clamped to ``[0, n_axis]``; NaN past each ray's count.
    counts : (n_p, n_q) int64
        Crossings per ray.
    slopes : (n_p, n_q, n_max) float64
        ``|n| / |n_axis|`` of the crossed triangle (1 for a face facing the
        ray, large for grazing ones); NaN past the count.  See
        :func:`crossing_tolerance`.
    axis : int
    """

    depths: np.ndarray
    counts: np.ndarray
    slopes: np.ndarray
    axis: int


def _column_pairs(tris: np.ndarray, dims: tuple[int, int, int], axis: int, pad: float):
    """(triangle, ju, jv) pairs: column centers within ``pad`` of each projected bounding box,
    in the cyclic frame ``(u, v) = ((axis + 1) % 3, (axis + 2) % 3)``."""
    u, v = (axis + 1) % 3, (axis + 2) % 3
    lo, hi = tris.min(axis=1), tris.max(axis=1)
    fu, lu = index_range(lo[:, u] - 0.5 - pad, hi[:, u] - 0.5 + pad, dims[u])
    fv, lv = index_range(lo[:, v] - 0.5 - pad, hi[:, v] - 0.5 + pad, dims[v])
    eu = np.maximum(lu - fu + 1, 0)
    ev = np.maximum(lv - fv + 1, 0)
    for tri, local in expand(eu * ev):
        yield tri, fu[tri] + local // ev[tri], fv[tri] + local % ev[tri]


def _pixel_index(ju: np.ndarray, jv: np.ndarray, dims: tuple[int, int, int], axis: int) -> np.ndarray:
    """Flat index ``p * n_q + q`` of cyclic-frame columns (ju, jv)."""
    u, v = (axis + 1) % 3, (axis + 2) % 3
    p, q = ldi_axes(axis)
    jp = ju if u == p else jv
    jq = jv if v == q else ju
    return jp * dims[q] + jq


def crossings(tris: np.ndarray, dims: Sequence[int], axis: int = 2) -> RayCrossings:
    """Every crossing of every pixel ray with the triangles, sorted per ray.

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Triangle vertices in voxel space.
    dims : (3,) int
        Grid size ``(nx, ny, nz)``; rays run along ``axis`` through the centers
        of the other two axes' voxels.
    axis : {0, 1, 2}

    Returns
    -------
    RayCrossings
    """
    tris = check_tris(tris)
    dims = check_dims(dims)
    axis = check_axis(axis)
    p_ax, q_ax = ldi_axes(axis)
    n_pix = dims[p_ax] * dims[q_ax]
    n = normals(tris)
    keep = axis_signs(tris, n, axis) != 0
    tris, n = tris[keep], n[keep]
    slope_t = np.linalg.norm(n, axis=1) / np.abs(n[:, axis]) if len(tris) else np.zeros(0)

    pix_parts, q_parts, s_parts = [], [], []
    for tri, ju, jv, q in column_crossings(tris, n, dims, axis):
        q = np.clip(q, 0.0, float(dims[axis]))
        pix_parts.append(_pixel_index(ju, jv, dims, axis))
        q_parts.append(q)
        s_parts.append(slope_t[tri])
    pix = np.concatenate(pix_parts) if pix_parts else np.zeros(0, np.int64)
    qs = np.concatenate(q_parts) if q_parts else np.zeros(0)
    ss = np.concatenate(s_parts) if s_parts else np.zeros(0)
    order = np.lexsort((qs, pix))
    pix, qs, ss = pix[order], qs[order], ss[order]
    counts = np.bincount(pix, minlength=n_pix).astype(np.int64)
    n_max = int(counts.max()) if n_pix else 0
    starts = np.cumsum(counts) - counts
    rank = np.arange(len(pix)) - starts[pix]
    depths = np.full((n_pix, n_max), np.nan)
    slopes = np.full((n_pix, n_max), np.nan)
    depths[pix, rank] = qs
    slopes[pix, rank] = ss
    shape = (dims[p_ax], dims[q_ax])
    return RayCrossings(depths.reshape(*shape, n_max), counts.reshape(shape),
                        slopes.reshape(*shape, n_max), axis)


def ray_ties(tris: np.ndarray, dims: Sequence[int], axis: int = 2, eps: float = TIE_EPS) -> np.ndarray:
    """Rays whose set of crossed triangles can change when the mesh moves by at most ``eps``.

    A ray crosses a triangle iff its center lies in the triangle's projection
    (with the fill rule on the boundary).  Moving every vertex by at most
    ``eps`` per coordinate moves the projected edges by at most
    ``sqrt(2) eps``, so a center farther than that from every projected edge
    keeps its verdict; the rays closer than that to some projected edge (of any
    triangle, including ones parallel to the rays, whose projection is a
    segment) are the ties.

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Voxel space.
    dims : (3,) int
    axis : {0, 1, 2}
    eps : float
        Vertex motion in voxels, 0 < eps < 0.5.

    Returns
    -------
    (n_p, n_q) bool
        Indexed like :attr:`RayCrossings.counts`.
    """
    tris = check_tris(tris)
    dims = check_dims(dims)
    axis = check_axis(axis)
    check_eps(eps)
    u, v = (axis + 1) % 3, (axis + 2) % 3
    p_ax, q_ax = ldi_axes(axis)
    reach = np.sqrt(2.0) * eps
    out = np.zeros(dims[p_ax] * dims[q_ax], dtype=bool)
    uv = tris[:, :, [u, v]]
    for tri, ju, jv in _column_pairs(tris, dims, axis, reach):
        c = np.stack([ju + 0.5, jv + 0.5], axis=1)
        d = np.full(len(tri), np.inf)
        for i in range(3):
            d = np.minimum(d, segment_distance(c, uv[tri, i], uv[tri, (i + 1) % 3]))
        close = d <= reach
        out[_pixel_index(ju[close], jv[close], dims, axis)] = True
    return out.reshape(dims[p_ax], dims[q_ax])


def crossing_tolerance(slopes: np.ndarray, eps: float = TIE_EPS) -> np.ndarray:
    """How far a crossing can move along the ray when the mesh moves by at most ``eps`` per coordinate.

    The crossing point X of a ray with a triangle, written with barycentric
    weights, moves with the vertices by at most ``sqrt(3) eps``; the moved
    point is then at most that far from the ray sideways, and sliding it back
    onto the ray within the (moved) plane changes its depth by that distance
    times the plane's slope ``|n_uv| / |n_axis| <= |n| / |n_axis|``.  So the
    depth moves by at most ``sqrt(3) eps (1 + slope) <= 2 sqrt(3) eps slope``
    (``slope >= 1``) to first order; twice that is returned, for the
    second-order terms (the plane also turns) and float64 rounding.

    Parameters
    ----------
    slopes : array
        :attr:`RayCrossings.slopes`.

    Returns
    -------
    array like ``slopes``, voxels.
    """
    return 4.0 * np.sqrt(3.0) * eps * np.asarray(slopes)
