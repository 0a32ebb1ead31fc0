"""The tie set of binvox's rules (``reference-binvox``, :mod:`glvox.reference.binvox`).

:func:`binvox_ties` gives the voxels whose binvox verdict a motion of the mesh by at most
``eps`` can change, :func:`binvox_axis_ties` those of one axis's parts; the tie sets of
the other references, and the helpers shared with them, are in :mod:`.ties`.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..tolerances import TIE_EPS
from ._candidates import (check_dims, check_eps, check_tris, column_candidates, lex_greater, normals,
                          segment_distance)
from .binvox import axis_crossings, fine_snap_eps, view_to_grid
from .solid import axis_signs, column_crossings
from .ties import _check_unsnapped, flat_axes, float32_motion, snap_ambiguous


def binvox_ties(tris: np.ndarray, dims: Sequence[int], *, wire: bool = False, surface: bool = False,
                down: int = 0, dilated: bool = False, eps: float = TIE_EPS,
                unsnapped: np.ndarray | None = None) -> np.ndarray:
    """Voxels whose binvox verdict (:func:`glvox.reference.binvox.binvox_solid`) can change
    when the mesh moves by at most ``eps`` per coordinate.

    Every part of binvox's solid along an axis (the carving interval, the two parity
    votes, the voxels holding a crossing) is a function of one column of that axis: the
    crossings of its pixel-center ray and, with ``wire``, the wireframe pixels drawn into
    it.  A voxel's verdict can therefore change only when one of its three columns
    changes, and a column changes only at a tie of one of its decisions:

    - coverage: the center lies within ``2 eps`` of a projected triangle edge (a vertex
      moves by at most ``eps sqrt(2)`` in the view's plane, and so does the boundary of
      the projected triangle); triangles whose projection stays a segment in float32
      (two equal coordinates across the view: :func:`flat_axes`) cover nothing either way,
      and an edge along a snap line (both ends on one multiple of 1/2 across it) keeps
      its exact distance to every center away from its ends.  Near the inside of an edge
      shared by two triangles that face the same way along the view beyond what the
      motion can flip, one of them owns the center either way (the top-left rule): the
      column is a tie only if their planes give the center different
      slots, or a slot near a rounding boundary;
    - depth: a crossing ``q`` within ``tol = 2 eps sqrt(3) (1 + |grad|)`` of a rounding
      boundary of ``slot = floor(q + 1/2)`` (and of ``floor(q)`` with ``surface``), where
      ``|grad|`` is the slope of the triangle's plane along the view; a triangle lying in a
      plane of the view's axis on a snap plane (a multiple of 1/2) has its exact ``q`` in
      float32 as well, and no depth tie;
    - wireframe (``wire``): an edge whose major axis can flip (``||du| - |dv|| <= 4 eps``:
      every pixel of both choices), or a pixel whose center is within ``2 eps`` of
      the edge's extent, whose line position is within ``4 eps`` of a pixel boundary or
      whose depth is within ``4 eps (1 + |dw / d major|)`` of a slot boundary (the pixels
      holding the line within ``4 eps`` of its position).  The wireframe counts for
      carving only, and carving only through the column's nearest and farthest slots:
      with its other hits certain (the crossings and the untied wire pixels), a tied
      wire pixel moves them only between the certain extremes and its own slot range,
      so the ties are the voxels between (each end moved by one with ``dilated``), and
      the whole column only where no hit is certain.

    The set is whole columns where a crossing is tied, and so coarse: on the Stanford
    bunny at 64^3, 6.3 % of the voxels with ShapeNet's recipe (6.1 % without ``-aw``,
    1.4 % with binvox's own defaults; most of it from ``-down``'s finer columns);
    tests/test_binvox.py also checks binvox-solid voxel for voxel against these rules run
    on its own float32 vertices.

    With ``down`` (binvox ``-down``) the ties are those of the finer grid (``tris``
    snapped on it, as binvox-solid and reference-binvox draw them), ``eps`` scaled
    with it, and a voxel is a tie when one of the fine voxels it halves is.  The
    carving modes, ``dilated`` and ``dmin`` do not move them: they act on the columns'
    decisions.  Given ``unsnapped``, triangles with a :func:`snap_ambiguous` coordinate are
    perturbed by the snap's motion as well.

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Voxel-space triangles, snapped on the grid binvox draws (with ``down``, the
        finer one's :meth:`glvox.mesh.Mesh.triangles_voxel` divided by ``2**down``).
    dims : (3,) int
    wire, surface : bool
        binvox ``-aw``; the surface voxels (not a binvox step).
    down : int
        binvox ``-down`` repeated (0 to 2).
    dilated : bool
        binvox ``-dc`` (moves the carving's ends by one voxel, and so the wire ties).
    eps : float
        Largest motion of a vertex coordinate, in voxels of ``dims``; 0 < eps < 0.5.
    unsnapped : (T, 3, 3) float64, optional
        The same triangles before the snap.

    Returns
    -------
    (nx, ny, nz) bool
    """
    tris = check_tris(tris)
    dims = check_dims(dims)
    check_eps(eps)
    f = 2 ** int(down)
    fine = tuple(d * f for d in dims)
    ftris = tris * f
    motion = np.full(len(tris), float(eps) * f)
    exact = np.ones(len(tris), dtype=bool)  # its coordinates on the snap planes are the GPU's too
    if unsnapped is not None:  # the snap is the finer grid's, where binvox draws
        some = snap_ambiguous(_check_unsnapped(unsnapped, tris) * f, fine, fine_snap_eps(down)).any(axis=(1, 2))
        motion[some] += fine_snap_eps(down) + float32_motion(fine)
        exact &= ~some
    out = np.zeros(fine, dtype=bool)
    flat = flat_axes(ftris)
    for axis in range(3):
        out |= view_to_grid(_axis_view_ties(ftris, flat, fine, axis, motion, exact, wire, surface, dilated), axis)
    for _ in range(int(down)):
        nx, ny, nz = (d // 2 for d in out.shape)
        out = out.reshape(nx, 2, ny, 2, nz, 2).any(axis=(1, 3, 5))
    return out


def _on_lattice(x: np.ndarray) -> np.ndarray:
    """Coordinates on a snap plane (a multiple of 1/2): the same exact value in float32."""
    return np.floor(2.0 * x) == 2.0 * x


def binvox_axis_ties(tris: np.ndarray, dims: Sequence[int], axis: int, *, wire: bool = False,
                     surface: bool = False, dilated: bool = False, eps: float = TIE_EPS) -> np.ndarray:
    """The ties of one axis's parts (:func:`glvox.reference.binvox.axis_parts`), in the
    view's order (k along ``axis``, then the columns): the voxels whose carving, votes or
    surface along ``axis`` a motion of ``eps`` can change (:func:`binvox_ties` is the OR
    of the three axes, on the grid binvox draws)."""
    tris = check_tris(tris)
    dims = check_dims(dims)
    check_eps(eps)
    motion = np.full(len(tris), float(eps))
    return _axis_view_ties(tris, flat_axes(tris), dims, axis, motion, np.ones(len(tris), dtype=bool), wire,
                           surface, dilated)


def _axis_view_ties(tris, flat, dims, axis, motion, exact, wire, surface, dilated) -> np.ndarray:
    """:func:`binvox_axis_ties` with per-triangle motions and exactness."""
    cols, wire_ties = _binvox_column_ties(tris, flat, dims, axis, motion, exact, wire, surface)
    view = np.zeros((dims[axis], *cols.shape), dtype=bool)  # (k along axis, ju, jv)
    view[:, cols] = True
    if wire_ties is not None:
        view |= _carve_end_ties(tris, dims, axis, cols, wire_ties, 1 if dilated else 0)
    return view


def _carve_end_ties(tris: np.ndarray, dims: tuple[int, int, int], axis: int, whole: np.ndarray,
                    wire_ties: tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]], d: int) -> np.ndarray:
    """(n, n_u, n_v) bool: the voxels whose carving verdict along ``axis`` a tied wire
    pixel can change (:func:`binvox_ties`), in the columns not ``whole``-ly tied.

    ``wire_ties``: the certain wire hits (ju, jv, slot) and the tied wire pixels (ju, jv,
    slot_lo, slot_hi) of :func:`_wire_pixel_ties`.  Certain: every crossing (its column
    is not tied) and every certain wire hit."""
    n = dims[axis]
    nu, nv = dims[(axis + 1) % 3], dims[(axis + 2) % 3]
    (wu, wv, wslot), (tu, tv, tlo, thi) = wire_ties
    tied = np.zeros((nu, nv), dtype=bool)
    tied[tu, tv] = True
    tied &= ~whole
    cu, cv, cq = axis_crossings(tris, dims, axis)
    su, sv = np.concatenate([cu, wu]), np.concatenate([cv, wv])
    slot = np.concatenate([np.clip(np.floor(cq + 0.5), 0, n).astype(np.int64), wslot])
    lo_max = np.full((nu, nv), n + 1, dtype=np.int64)  # the nearest certain slot
    hi_min = np.full((nu, nv), -1, dtype=np.int64)  # the farthest
    np.minimum.at(lo_max, (su, sv), slot)
    np.maximum.at(hi_min, (su, sv), slot)
    lo_min, hi_max = lo_max.copy(), hi_min.copy()
    np.minimum.at(lo_min, (tu, tv), tlo)
    np.maximum.at(hi_max, (tu, tv), thi)
    k = np.arange(n)[:, None, None]
    near = (k >= np.maximum(lo_min - d, 0)[None]) & (k < np.maximum(lo_max - d, 0)[None])
    far = (k >= (hi_min + d)[None]) & (k < (hi_max + d)[None])
    none_sure = (hi_min < 0)[None]  # the column may have hits or none: all of it
    return (near | far | none_sure) & tied[None]


def _binvox_column_ties(tris: np.ndarray, flat: np.ndarray, dims: tuple[int, int, int], axis: int,
                        motion: np.ndarray, exact: np.ndarray, wire: bool, surface: bool):
    """The columns along ``axis`` with a tie of their crossings ((n_u, n_v) bool,
    :func:`binvox_ties`) and, with ``wire``, the wireframe's certain hits and tied pixels
    (:func:`_wire_pixel_ties`), else None; ``exact`` (T,): the triangle's coordinates on
    snap planes are exactly the GPU's."""
    u, v = (axis + 1) % 3, (axis + 2) % 3
    out = np.zeros((dims[u], dims[v]), dtype=bool)
    n = normals(tris)
    na = n[:, axis]
    grad = np.hypot(n[:, u], n[:, v]) / np.where(na != 0.0, np.abs(na), 1.0)
    exact_q = exact & flat[:, axis] & _on_lattice(tris[:, 0, axis])
    tol = np.where(exact_q, 0.0, 2.0 * np.sqrt(3.0) * motion * (1.0 + grad))

    def depth_tie(tri, q):
        t = tol[tri]
        near = np.abs(q + 0.5 - np.round(q + 0.5)) <= t
        if surface:
            near |= np.abs(q - np.round(q)) <= t
        return near & (t > 0.0)

    # coverage: centers near a projected edge (projections that stay segments cover nothing),
    # except near the inside of an edge across which the projection continues (smooth[t, i]:
    # its two triangles face the same way robustly), where one of the two owns the center
    # either way: there the column is a tie only if the two planes' depths differ in slot
    robust = _robust_orientation(tris, na, motion)
    smooth, other = _smooth_edges(tris, na, robust)
    live = np.flatnonzero(~(flat[:, u] | flat[:, v]))
    for tri, ju, jv in column_candidates(tris[live], dims, axis, pad=float(2.0 * motion.max())):
        tri = live[tri]
        c = np.stack([ju + 0.5, jv + 0.5], axis=1)
        p = tris[tri][:, :, [u, v]]
        r = 2.0 * motion[tri]
        tie = np.zeros(len(tri), dtype=bool)
        for i in range(3):
            a, b = p[:, i], p[:, (i + 1) % 3]
            near = segment_distance(c, a, b) <= r
            off_ends = (np.linalg.norm(c - a, axis=1) > r) & (np.linalg.norm(c - b, axis=1) > r)
            # an edge along a snap line keeps its exact distance to every center (and the
            # top-left rule its verdict there, while the triangle's orientation holds)
            fixed = exact[tri] & robust[tri] & (((a[:, 0] == b[:, 0]) & _on_lattice(a[:, 0]))
                                  | ((a[:, 1] == b[:, 1]) & _on_lattice(a[:, 1])))
            near &= ~(fixed & off_ends)
            inner = smooth[tri, i] & off_ends
            tie |= near & ~inner
            both = near & inner
            if both.any():
                t1, t2, cc = tri[both], other[tri[both], i], c[both]
                q1, q2 = _plane_depth(tris, n, t1, cc, axis), _plane_depth(tris, n, t2, cc, axis)
                slot_differs = np.floor(q1 + 0.5) != np.floor(q2 + 0.5)
                if surface:
                    slot_differs |= np.floor(q1) != np.floor(q2)
                tie[np.flatnonzero(both)] |= slot_differs | depth_tie(t1, q1) | depth_tie(t2, q2)
        out[ju[tie], jv[tie]] = True
    # depth: crossings near a rounding boundary of their slot (or holder)
    keep = np.flatnonzero(axis_signs(tris, n, axis) != 0)
    for tri, ju, jv, q in column_crossings(tris[keep], n[keep], dims, axis):
        near = depth_tie(keep[tri], q)
        out[ju[near], jv[near]] = True
    return out, (_wire_pixel_ties(tris, dims, axis, motion, exact) if wire else None)


def _plane_depth(tris: np.ndarray, n: np.ndarray, tri: np.ndarray, c: np.ndarray, axis: int) -> np.ndarray:
    """The depth along ``axis`` of triangle ``tri``'s plane at the view points ``c`` (M, 2)."""
    u, v = (axis + 1) % 3, (axis + 2) % 3
    v0, nt = tris[tri, 0], n[tri]
    return v0[:, axis] + (nt[:, u] * (v0[:, u] - c[:, 0]) + nt[:, v] * (v0[:, v] - c[:, 1])) / nt[:, axis]


def _robust_orientation(tris: np.ndarray, na: np.ndarray, motion: np.ndarray) -> np.ndarray:
    """(T,) bool: ``|n_axis|`` beyond what moving the vertices by ``motion`` can change
    (:func:`orientation_ambiguous`'s bound), so the projection keeps its orientation."""
    e0, e1 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    slack = 4.0 * motion * (np.abs(e0).sum(axis=1) + np.abs(e1).sum(axis=1)) + 16.0 * motion * motion
    return np.abs(na) > slack


def _smooth_edges(tris: np.ndarray, na: np.ndarray, robust: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``smooth`` (T, 3) bool: edge i of a triangle (from vertex i to i + 1) is shared with
    exactly one other triangle, ``other`` (T, 3) int64, and both face the same way along the
    view, ``robust``-ly (:func:`_robust_orientation`), so the projection continues across it."""
    t = len(tris)
    ends = np.stack([tris, np.roll(tris, -1, axis=1)], axis=2).reshape(3 * t, 2, 3)  # (tri, edge) order
    flip = lex_greater(ends[:, 0], ends[:, 1])[:, None]
    first, second = np.where(flip, ends[:, 1], ends[:, 0]), np.where(flip, ends[:, 0], ends[:, 1])
    _, inverse, counts = np.unique(np.concatenate([first, second], axis=1), axis=0, return_inverse=True,
                                   return_counts=True)
    inverse = inverse.reshape(-1)
    pair = counts[inverse] == 2
    order = np.argsort(inverse, kind="stable")
    mate = np.empty(3 * t, dtype=np.int64)
    grouped = order[np.isin(inverse[order], np.flatnonzero(counts == 2))].reshape(-1, 2)
    mate[grouped[:, 0]], mate[grouped[:, 1]] = grouped[:, 1], grouped[:, 0]
    other = np.where(pair, mate, -1) // 3
    tri_of = np.repeat(np.arange(t), 3)
    ok = pair & robust[tri_of]
    ok[pair] &= robust[other[pair]] & (np.sign(na[tri_of[pair]]) == np.sign(na[other[pair]]))
    return ok.reshape(t, 3), np.where(ok, other, -1).reshape(t, 3)


def _wire_pixel_ties(tris: np.ndarray, dims: tuple[int, int, int], axis: int, motion: np.ndarray,
                     exact: np.ndarray):
    """The wireframe of :func:`glvox.reference.binvox.wire_hits`, split: its certain hits
    (ju, jv, slot), those no motion of ``motion`` changes, and the pixels where a hit can
    appear, vanish or change its slot (:func:`binvox_ties`) with the slots it can have
    there (ju, jv, slot_lo, slot_hi).  The same centers, lines and depths as wire_hits."""
    u, v = (axis + 1) % 3, (axis + 2) % 3
    n = dims[axis]
    found: list[tuple[np.ndarray, ...]] = []
    certain: list[tuple[np.ndarray, ...]] = []
    ends = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    r = 2.0 * np.tile(motion, 3)
    fixed = np.tile(exact, 3)[:, None, None] & _on_lattice(ends)  # (edge, end, coordinate) exact
    du, dv = ends[:, 1, u] - ends[:, 0, u], ends[:, 1, v] - ends[:, 0, v]
    drawn = (du != 0.0) | (dv != 0.0)
    # the major axis may flip: every pixel of both choices counts
    ambiguous = drawn & (np.abs(np.abs(du) - np.abs(dv)) <= 2.0 * r) & ~fixed[:, :, [u, v]].all(axis=(1, 2))
    for major, minor, sel in ((u, v, np.abs(du) >= np.abs(dv)), (v, u, np.abs(du) < np.abs(dv))):
        idx = np.flatnonzero(drawn & (sel | ambiguous))
        if not len(idx):
            continue
        e, rr, fx = ends[idx], r[idx], fixed[idx]
        swap = e[:, 0, major] > e[:, 1, major]
        s = np.where(swap[:, None], e[:, 1], e[:, 0])
        f = np.where(swap[:, None], e[:, 0], e[:, 1])
        fs = np.where(swap[:, None], fx[:, 1], fx[:, 0])
        ff = np.where(swap[:, None], fx[:, 0], fx[:, 1])
        # exact in float32 as well: an end on a snap plane (the range), a line along one
        # (its position), a constant depth on one (the slot)
        same_minor = fs[:, minor] & ff[:, minor] & (s[:, minor] == f[:, minor])
        same_depth = fs[:, axis] & ff[:, axis] & (s[:, axis] == f[:, axis])
        fs, ff = fs[:, major], ff[:, major]
        i0 = np.maximum(np.ceil(s[:, major] - rr - 0.5).astype(np.int64), 0)
        i1 = np.minimum(np.floor(f[:, major] + rr - 0.5).astype(np.int64) + 1, dims[major])
        cnt = np.maximum(i1 - i0, 0)
        which = np.repeat(np.arange(len(idx)), cnt)
        i = i0[which] + np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        s, f, rr, w = s[which], f[which], rr[which], which
        fs, ff, same_minor, same_depth = fs[which], ff[which], same_minor[which], same_depth[which]
        c = i + 0.5
        span = f[:, major] - s[:, major]  # 0 only for an ambiguous edge seen end-on: tied anyway
        t = (c - s[:, major]) / np.where(span > 0.0, span, 1.0)
        p = s[:, minor] + t * (f[:, minor] - s[:, minor])
        q = s[:, axis] + t * (f[:, axis] - s[:, axis])
        qtol = 2.0 * rr * (1.0 + np.abs(f[:, axis] - s[:, axis]) / np.where(span > 0.0, span, np.inf))
        tie = (ambiguous[idx][w] | ((np.abs(c - s[:, major]) <= rr) & ~fs) | ((np.abs(c - f[:, major]) <= rr) & ~ff)
               | ((np.abs(p - np.round(p)) <= 2.0 * rr) & ~same_minor)
               | ((np.abs(q + 0.5 - np.round(q + 0.5)) <= qtol) & ~same_depth))
        # untied: the hit wire_hits makes (centers in [first, last)) is certain
        drawn_here = ~tie & (c >= s[:, major]) & (c < f[:, major])
        j = np.floor(p[drawn_here]).astype(np.int64)
        ok = (j >= 0) & (j < dims[minor])
        ci = i[drawn_here][ok]
        cslot = np.clip(np.floor(q[drawn_here][ok] + 0.5), 0, n).astype(np.int64)
        certain.append(((ci, j[ok]) if major == u else (j[ok], ci)) + (cslot,))
        # tied: the moved line's minor position lies within 2 r of p, so the pixels holding
        # those positions (every pixel of the line, for an edge whose major axis may flip)
        i, p, rr, q, qtol = i[tie], p[tie], rr[tie], q[tie], qtol[tie]
        slo = np.clip(np.floor(q + 0.5 - qtol), 0, n).astype(np.int64)
        shi = np.clip(np.floor(q + 0.5 + qtol), 0, n).astype(np.int64)
        for jj in (np.floor(p - 2.0 * rr), np.floor(p + 2.0 * rr)):
            jj = jj.astype(np.int64)
            ok = (jj >= 0) & (jj < dims[minor])
            pix = (i[ok], jj[ok]) if major == u else (jj[ok], i[ok])
            found.append((*pix, slo[ok], shi[ok]))
    z = np.zeros(0, dtype=np.int64)
    sure = tuple(np.concatenate([z] + [h[c] for h in certain]) for c in range(3))
    tied = tuple(np.concatenate([z] + [h[c] for h in found]) for c in range(4))
    return sure, tied
