"""Generalized winding numbers at voxel centers (float64, voxel space).

The generalized winding number (Jacobson, Kavan, Sorkine-Hornung 2013) of a
triangle soup at a point p is ``w(p) = sum_t Omega_t(p) / (4 pi)``, the
signed solid angles of its triangles seen from p (Van Oosterom & Strackee
1983).  Summed directly that is (voxels x triangles) evaluations: 1e10 and
more for a real mesh at 128^3.  :func:`winding` computes the same number
exactly (in exact arithmetic; float64 rounding apart) from a decomposition
along the grid's rows, which run along +x (``d``):

    Omega_t(p) = -4 pi sign(n_x) [the ray p - s d, s > 0, crosses t]
                 + sum over t's directed edges (u -> v) of Omega_strip(u - p, v - p),

    Omega_strip(a, b) = 2 atan2(a . (b x d), (|a| + a.d)(|b| + b.d) + a_yz . b_yz),

the solid angle of the half-infinite strip the edge sweeps along +d (the
Van Oosterom formula of the triangle (a, b, infinity * d)).  Summed over a
mesh, ``w = C + F``:

* ``C(p)``, an integer: the crossings of the ray from p towards -x, each
  counted ``-sign(n_x)``.  It is :func:`glvox.reference.solid`'s parity
  count with signs, on the same crossings decided by the same float64
  arithmetic and top-left fill rule (:func:`crossing_counts`);
* ``F(p)``: the strips of the half-edges that do not cancel.  An edge u -> v
  and an edge v -> u at the same two vertex positions have the same strip with
  opposite signs, so only the boundary chain of the mesh is left
  (:func:`boundary_edges`): none on a closed, consistently oriented mesh
  (also a self-intersecting, nested or inside-out one: ``w = C`` is then an
  integer), a few hundred on the shared open meshes.

Consistency of the two parts.  Along a row (fixed y, z) the numerator
``a . (b x d)`` is the 2D edge function of the edge's (y, z) projection at the
row's center, constant along the row, so a strip never jumps along a row; it
jumps by 4 pi across the rows where that edge function changes sign ahead of
the edge (p_x beyond it), exactly where the owning triangle starts or stops
crossing the row's ray and ``C`` jumps by one.  The edge function is
evaluated here with the very float64 expression that decides the triangle's
crossing in :func:`glvox.reference.solid` (from the lexicographically
smaller endpoint), and a zero takes the sign it has at the center nudged the
way the top-left rule nudges it (+y, then -z).  So ``C + F`` is the limit of
``w`` from that nudged side, bit-consistent where ``C`` jumps, and rounding
only touches ``F``'s continuous part.  Centers exactly on the surface have no
winding number (``w`` jumps there); they are ties.

:func:`winding_direct` is the independent check: the direct float64 sum over
all triangles at given points.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..tolerances import TIE_EPS, WINDING_TIE
from ._candidates import check_dims, check_tris, normals
from .solid import DET_BOUND, axis_signs, exact_edge_sign, first_flips
from .ties import solid_ties

#: Voxels per slab of :func:`strip_field`: each temporary of a slab is 8 bytes a voxel.
SLAB_VOXELS = 1 << 20

#: Points x triangles evaluated at once by :func:`winding_direct` (a few dozen bytes each).
DIRECT_PAIRS = 1 << 22


def boundary_edges(tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The directed edges of ``tris`` that do not cancel.

    Edges are keyed by the exact positions of their end points.  For every
    pair of positions {A, B}, the edges A -> B count +1 and B -> A count -1;
    a pair whose count is not zero is returned once, directed so that its
    multiplicity is positive (two triangles running A -> B give one edge of
    multiplicity 2; a non-manifold edge of three triangles leaves one).

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Triangles (any space; voxel space for :func:`winding`).

    Returns
    -------
    edges : (E, 2, 3) float64
        Start and end point of each edge.
    mult : (E,) int64
        Multiplicity, >= 1.
    """
    tris = check_tris(tris)
    pts, ids = np.unique(tris.reshape(-1, 3) + 0.0, axis=0, return_inverse=True)  # -0.0 -> 0.0
    ids = ids.reshape(-1, 3)
    start = ids.ravel()
    end = np.roll(ids, -1, axis=1).ravel()
    lo, hi = np.minimum(start, end), np.maximum(start, end)
    key = lo * len(pts) + hi
    keys, inv = np.unique(key, return_inverse=True)
    net = np.bincount(inv.ravel(), weights=np.where(start < end, 1.0, -1.0), minlength=len(keys))
    net = np.rint(net).astype(np.int64)
    keep = net != 0
    a, b, m = keys[keep] // len(pts), keys[keep] % len(pts), net[keep]
    # positive: runs a -> b (a < b) m times; negative: b -> a, -m times
    first = np.where(m > 0, a, b)
    second = np.where(m > 0, b, a)
    edges = np.stack([pts[first], pts[second]], axis=1)
    return edges, np.abs(m)


def crossing_counts(tris: np.ndarray, dims: Sequence[int]) -> np.ndarray:
    """``C``: at every voxel center, the signed crossings of the ray towards -x.

    Each crossing counts ``-sign(n_x)``: +1 through a face that faces -x (an
    outward face where the ray leaves a closed shell), -1 through one that
    faces +x.  The crossings are those of :func:`glvox.reference.solid`
    (same arithmetic, same fill rule), so on a closed, outward-oriented mesh
    ``C`` is 1 exactly where the parity solid is set and 0 elsewhere.

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Voxel-space triangles.
    dims : (3,) int

    Returns
    -------
    (nx, ny, nz) int32
    """
    tris = check_tris(tris)
    dims = check_dims(dims)
    n = normals(tris)
    signs = axis_signs(tris, n, 0)
    keep = np.flatnonzero(signs != 0)
    hits, tri = first_flips(tris[keep], n[keep], dims, 0)
    sign = -signs[keep][tri].astype(np.float64)
    steps = np.bincount(hits, weights=sign, minlength=int(np.prod(dims)))
    return np.cumsum(np.rint(steps).reshape(dims), axis=0, dtype=np.int64).astype(np.int32)


def _row_edge_function(u: np.ndarray, v: np.ndarray, cy: np.ndarray, cz: np.ndarray) -> np.ndarray:
    """The 2D edge function of the (y, z) projection of the edge u -> v at the
    row centers ``(cy[:, None], cz[None, :])``, with zeros replaced by +-0.0
    carrying the sign at the center nudged by the top-left rule.

    Evaluated as :func:`glvox.reference.solid.column_crossings` evaluates it,
    from the lexicographically smaller end point and exactly where rounding
    could decide the sign, so its sign is the one that decided the owning
    triangle's crossings.  Nudged by +y (then, infinitesimally less, -z),
    ``f = e_y (c_z - u_z) - e_z (c_y - u_y)`` moves by ``-e_z`` (then ``-e_y``).

    Returns
    -------
    (ny, nz) float64
    """
    p, q = u[1:], v[1:]
    swap = p[0] > q[0] or (p[0] == q[0] and p[1] > q[1])
    a, b = (q, p) if swap else (p, q)
    left = (b[0] - a[0]) * (cz[None, :] - a[1])
    right = (b[1] - a[1]) * (cy[:, None] - a[0])
    f = left - right
    if swap:
        f = -f
    bound = DET_BOUND * (np.abs(left) + np.abs(right))
    for j, k in zip(*np.nonzero((np.abs(f) <= bound) & (bound > 0.0))):
        # within rounding of the edge: the sign exactly (0 takes the top-left nudge below)
        f[j, k] = exact_edge_sign(cy[j], cz[k], p, q) * max(abs(f[j, k]), 5e-324)
    e = q - p
    nudge = -e[1] if e[1] != 0.0 else -e[0]
    return np.where(f == 0.0, np.copysign(0.0, nudge), f)


def _plus_x(d: float, cx: np.ndarray, rho2: np.ndarray) -> np.ndarray:
    """``|a| + a_x`` at every voxel of a slab for an end point at ``x = d``:
    ``a_x = d - cx`` along the rows, ``rho2 = a_y^2 + a_z^2`` per row.

    Where ``a_x < 0`` (the voxels past the end point) it is evaluated as
    ``rho2 / (|a| - a_x)``: no cancellation.  The x centers are sorted, so the
    two forms split the rows at one index.

    Returns
    -------
    (nx, ny, nz_slab) float64
    """
    dx = (d - cx)[:, None, None]
    out = np.sqrt(dx * dx + rho2[None])
    k = int(np.searchsorted(cx, d, side="right"))  # cx[:k] <= d: a_x >= 0
    out[:k] += dx[:k]
    np.divide(rho2[None], out[k:] - dx[k:], out=out[k:])  # |a| - a_x >= 2 |a_x| > 0 there
    return out


def _through_vertex(num, den, mask, e, x_sign):
    """Numerator and denominator of a strip at the voxels of a row that passes
    exactly through an end point of its edge, ahead of it (``mask``).

    There p lies on the strip's boundary ray (the end point swept along +x),
    where the strip's solid angle has no limit: it depends on the direction
    from which p is approached.  The top-left rule approaches from the nudge
    ``n = (-1, delta)`` in (y, z) relative to the end point (the center moves
    by +y, then -z), and to first order in the nudge the numerator is
    ``n x e`` and the denominator ``+-(n . e)`` (``x_sign`` -1 for the start
    point, +1 for the end point), ``e`` the edge's (y, z) projection;
    ``delta``'s terms decide only where a component of ``e`` is zero.
    """
    ey, ez = float(e[1]), float(e[2])
    y = -ez if ez != 0.0 else np.copysign(0.0, -ey)
    x = x_sign * (ey if ey != 0.0 else np.copysign(0.0, -ez))
    return np.where(mask, y, num), np.where(mask, x, den)


def strip_field(edges: np.ndarray, mult: np.ndarray, dims: Sequence[int]) -> np.ndarray:
    """``F``: the strips of ``edges`` at every voxel center, in turns (solid angle / 4 pi).

    Parameters
    ----------
    edges : (E, 2, 3) float64
        Voxel-space directed edges (:func:`boundary_edges`).
    mult : (E,) int
        Their multiplicities.
    dims : (3,) int

    Returns
    -------
    (nx, ny, nz) float64
    """
    dims = check_dims(dims)
    nx, ny, nz = dims
    out = np.zeros(dims, dtype=np.float64)
    cx = np.arange(nx) + 0.5
    cy = np.arange(ny) + 0.5
    slab = max(1, SLAB_VOXELS // (nx * ny))
    for k0 in range(0, nz, slab):
        k1 = min(nz, k0 + slab)
        cz = np.arange(k0, k1) + 0.5
        acc = np.zeros((nx, ny, k1 - k0))
        for (u, v), m in zip(np.asarray(edges, np.float64), np.asarray(mult)):
            if u[1] == v[1] and u[2] == v[2]:
                continue  # parallel to x: a strip of zero area
            num = _row_edge_function(u, v, cy, cz)
            ay, az = u[1] - cy[:, None], u[2] - cz[None, :]
            by, bz = v[1] - cy[:, None], v[2] - cz[None, :]
            ra2, rb2 = ay * ay + az * az, by * by + bz * bz
            den = _plus_x(u[0], cx, ra2)
            den *= _plus_x(v[0], cx, rb2)
            den += (ay * by + az * bz)[None]
            num = np.broadcast_to(num, den.shape)
            for r2, dx, x in ((ra2, u[0] - cx, -1.0), (rb2, v[0] - cx, 1.0)):
                if (r2 == 0.0).any():
                    num, den = _through_vertex(num, den, (r2 == 0.0)[None] & (dx < 0.0)[:, None, None], v - u, x)
            h = np.arctan2(num, den, out=den) if den.flags.writeable else np.arctan2(num, den)
            if m != 1:
                h *= m
            acc += h
        out[:, :, k0:k1] = acc * (2.0 / (4.0 * np.pi))
    return out


def winding(tris: np.ndarray, dims: Sequence[int]) -> np.ndarray:
    """Generalized winding number ``w = C + F`` at every voxel center.

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Voxel-space triangles (any soup: open, non-manifold, overlapping).
    dims : (3,) int

    Returns
    -------
    (nx, ny, nz) float64
        ``w`` at the centers; an integer wherever the mesh's boundary chain is
        empty (closed meshes: 1 inside, 2 inside two overlapping shells, -1
        inside an inside-out one).  At a center exactly on the surface, the
        limit from the side the top-left rule picks.
    """
    tris = check_tris(tris)
    dims = check_dims(dims)
    c = crossing_counts(tris, dims).astype(np.float64)
    edges, mult = boundary_edges(tris)
    if len(edges):
        c += strip_field(edges, mult, dims)
    return c


def winding_direct(tris: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The direct sum of Van Oosterom-Strackee solid angles over all triangles.

    The independent check of :func:`winding` (and what libigl's
    ``winding_number`` computes): O(points x triangles).

    Parameters
    ----------
    tris : (T, 3, 3) float64
    points : (P, 3) float64
        Same space as ``tris``.

    Returns
    -------
    (P,) float64
        ``w`` at each point (0 contribution from a triangle the point lies on).
    """
    tris = check_tris(tris)
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    out = np.zeros(len(pts))
    step = max(1, DIRECT_PAIRS // max(1, len(tris)))
    for s in range(0, len(pts), step):
        r = tris[None, :, :, :] - pts[s:s + step, None, None, :]
        a, b, c = r[:, :, 0], r[:, :, 1], r[:, :, 2]
        la, lb, lc = (np.sqrt(np.einsum("ptk,ptk->pt", x, x)) for x in (a, b, c))
        num = np.einsum("ptk,ptk->pt", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("ptk,ptk->pt", a, b) * lc + np.einsum("ptk,ptk->pt", b, c) * la
               + np.einsum("ptk,ptk->pt", c, a) * lb)
        out[s:s + step] = (2.0 * np.arctan2(num, den)).sum(axis=1) / (4.0 * np.pi)
    return out


def winding_ties(tris: np.ndarray, dims: Sequence[int], w: np.ndarray, threshold: float = 0.5,
                 eps: float = TIE_EPS, w_eps: float = WINDING_TIE) -> np.ndarray:
    """Voxels whose winding-number verdict (``w >= threshold``) is a tie.

    Two kinds: centers within ``eps`` voxel of the surface, where ``w`` jumps
    by an integer and a mesh moved by ``eps`` (float32 rounding) puts the
    center on the other side (:func:`glvox.reference.solid_ties`); and
    centers whose ``w`` lies within ``w_eps`` of the threshold
    (:data:`glvox.tolerances.WINDING_TIE`: float32 evaluation).

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Voxel-space triangles.
    dims : (3,) int
    w : (nx, ny, nz) float
        :func:`winding` of ``tris`` on ``dims``.
    threshold : float
    eps : float
        Mesh motion, voxels.
    w_eps : float
        Winding-number tolerance, turns.

    Returns
    -------
    (nx, ny, nz) bool
    """
    return solid_ties(tris, dims, eps) | (np.abs(np.asarray(w) - threshold) <= w_eps)
