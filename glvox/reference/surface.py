"""Exact CPU surface voxelizations (float64, voxel space).

Three formulations of two criteria:

- :func:`conservative_surface`: Schwarz & Seidel's triangle/box test (S&S
  Sec. 3.1, Eq. 1-3) over each triangle's touched voxels (Sec. 3.2).
- :func:`conservative_surface_sat`: the same set by Akenine-Moller's
  separating-axis test, written independently to cross-check the first.
- :func:`six_separating_surface`: the thinner 6-separating criterion of S&S
  Sec. 3.4.

Voxel ``(i, j, k)`` is tested as the axis-aligned box centered at
``(i+.5, j+.5, k+.5)`` with half-size ``half`` (0.5 is the voxel itself; the
tie sets of :mod:`glvox.reference.ties` use ``0.5 +/- TIE_EPS``, per triangle
and axis).  All comparisons are inclusive, so boxes that merely touch a
triangle count.

Zero-area triangles (which callers normally drop) are harmless: with a zero
normal the plane test of Eq. 1 always passes and the 2D edge tests with
edges running both ways along the line reduce to the exact box/segment (or
box/point) test, which is also what the separating-axis test computes for
them.  No NaN can arise: nothing divides by a normal.
"""

from __future__ import annotations

from typing import Callable, Iterator, Sequence

import numpy as np

from ._candidates import (bbox_candidates, check_dims, check_half, check_tris, normals,
                          pruned_candidates, scatter)



def _halves(half, n_tris: int) -> np.ndarray:
    """``half`` as (T, 3) float64 half-sizes per triangle and axis (a float: the same
    for all), each positive and finite."""
    if np.ndim(half) == 0:
        return np.full((n_tris, 3), check_half(half))
    h = np.asarray(half, dtype=np.float64)
    if h.shape != (n_tris, 3):
        raise ValueError(f"half must be a float or a (T, 3) array with T = {n_tris}, got shape {h.shape}")
    if not (np.isfinite(h).all() and (h > 0.0).all()):
        raise ValueError("half must be positive and finite on every axis")
    return h

# Projection planes as (a, b, w): the 2D axes and the axis normal to them, in
# cyclic order so that n_w is the signed area of the projection in (a, b).
# With the paper's "xz" written as (z, x) the same edge-normal formula
# (-e_b, e_a) * sign(n_w) points inwards in all three planes.
_PLANES = ((1, 2, 0), (2, 0, 1), (0, 1, 2))

Test = Callable[[np.ndarray, np.ndarray], np.ndarray]


def _edge_normals(tris: np.ndarray, n: np.ndarray, flip: np.ndarray | None = None) -> np.ndarray:
    """Inward 2D edge normals of the three projections, (T, 3 planes, 3 edges, 2) float64 (S&S Eq. 2).

    ``flip`` (T, 3) bool inverts the orientation of the marked projections
    (planes in ``_PLANES`` order); the orientation tie sets use it.
    """
    e = np.roll(tris, -1, axis=1) - tris  # e_i = v_{i+1 mod 3} - v_i
    out = np.empty((len(tris), 3, 3, 2))
    for p, (a, b, w) in enumerate(_PLANES):
        sgn = np.where(n[:, w] >= 0.0, 1.0, -1.0)
        if flip is not None:
            sgn = np.where(flip[:, p], -sgn, sgn)
        sgn = sgn[:, None]
        out[:, p, :, 0] = -e[:, :, b] * sgn
        out[:, p, :, 1] = e[:, :, a] * sgn
    return out


def _planar_test(tris: np.ndarray, n: np.ndarray, o1: np.ndarray, o2: np.ndarray,
                 ne: np.ndarray, oe: np.ndarray, shift: np.ndarray, halves: np.ndarray,
                 no_plane: np.ndarray | None = None, no_proj: np.ndarray | None = None) -> Test:
    """Per-pair test shared by both S&S criteria.

    With ``x = ijk + shift`` (``shift`` (T, 3) per triangle and axis: the
    box's minimum corner for the conservative test, its center for the
    6-separating one) the pair passes iff
    ``s = <n, x - v0>`` has ``(s + o1)(s + o2) <= 0`` (Eq. 1) and
    ``<n_e, x_ab - v_i,ab> + o_e >= 0`` for all 9 projected edges (Eq. 3).
    This is Eq. 1-3 with the paper's ``d = -<n, v> + offset`` split so that
    the vertex is subtracted from ``x`` before multiplying: the same value in
    exact arithmetic, but without the cancellation of the large terms
    ``<n, v>`` and ``<n, x>``, so that, e.g., a box touching a triangle that
    lies on a voxel plane is found exactly (as the separating-axis test finds
    it).  Pairs are dropped as soon as one test fails.

    The bounding-box part of the test is the candidate set (voxels whose box
    of the largest half-size in ``halves`` meets the triangle's bounding box);
    where the half-sizes differ between triangles or axes, the box of each
    pair's own half-size is checked against the bounding box too.
    """
    lo_t, hi_t = tris.min(axis=1), tris.max(axis=1)
    uneven = halves.size > 0 and halves.min() != halves.max()

    def test(tri: np.ndarray, ijk: np.ndarray) -> np.ndarray:
        keep = np.arange(len(tri))
        t = tri
        if uneven:
            c, r = ijk + 0.5, halves[t]
            ok = ((c + r >= lo_t[t]) & (c - r <= hi_t[t])).all(axis=1)
            keep, ijk, t = keep[ok], ijk[ok], t[ok]
        x = ijk + shift[t]
        s = np.einsum("ij,ij->i", n[t], x - tris[t, 0])
        lo = s + o1[t]
        hi = s + o2[t]
        # Sign test instead of the product of Eq. 1: same verdict, no underflow.
        ok = np.minimum(lo, hi) <= 0.0
        ok &= np.maximum(lo, hi) >= 0.0
        if no_plane is not None:
            ok |= no_plane[t]
        keep, x, t = keep[ok], x[ok], t[ok]
        for q, (a, b, _) in enumerate(_PLANES):
            ra = x[:, a][:, None] - tris[t, :, a]
            rb = x[:, b][:, None] - tris[t, :, b]
            nq = ne[t, q]
            val = nq[..., 0] * ra + nq[..., 1] * rb + oe[t, q]
            ok = (val >= 0.0).all(axis=1)
            if no_proj is not None:
                ok |= no_proj[t, q]
            keep, x, t = keep[ok], x[ok], t[ok]
        mask = np.zeros(len(tri), dtype=bool)
        mask[keep] = True
        return mask
    return test


def _edge_shift(shift, n_tris: int) -> np.ndarray:
    s = np.asarray(shift, dtype=np.float64)
    if s.shape != (n_tris, 3, 3) or not np.isfinite(s).all():
        raise ValueError(f"edge_shift must be a finite (T, 3, 3) array with T = {n_tris}, got shape {s.shape}")
    return s


def _pad(halves: np.ndarray) -> float:
    """The candidates' half-size: the largest of ``halves`` (a superset for the others)."""
    return float(halves.max()) if halves.size else 0.5


def _run(tris: np.ndarray, dims: tuple[int, int, int],
         candidates: Iterator[tuple[np.ndarray, np.ndarray]], test: Test) -> np.ndarray:
    out = np.zeros(dims, dtype=bool)
    for tri, ijk in candidates:
        scatter(out, ijk[test(tri, ijk)])
    return out


def conservative_surface(tris: np.ndarray, dims: Sequence[int], half: float | np.ndarray = 0.5, *,
                         edge_shift: np.ndarray | None = None,
                         flip: np.ndarray | None = None,
                         no_plane: np.ndarray | None = None,
                         no_proj: np.ndarray | None = None) -> np.ndarray:
    """Conservative (26-separating) surface voxelization by the Schwarz & Seidel test.

    A voxel is set iff some triangle overlaps or touches its box: the
    triangle's plane meets the box (Eq. 1, with the critical point ``c``) and
    the triangle's projections onto the yz, zx and xy planes meet the box's
    (three edge functions each, evaluated at the most interior box corner,
    Eq. 2-3).  The bounding-box part of the test is implied by the candidate
    set: only voxels whose box meets the triangle's closed bounding box are
    tested, so touched voxels outside it count too (S&S Sec. 3.2, Fig. 5a).
    Candidates are further restricted to the few voxels per column along the
    normal's dominant axis that the plane can reach (the specialization of
    S&S Sec. 3.2); that changes the cost, never the result.  The edge
    functions are evaluated relative to the edge's vertex (see
    ``_planar_test``), identical to Eq. 2-3 in exact arithmetic.

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Triangle vertices in voxel space.  Triangles may extend outside the
        grid; voxels outside are clipped.
    dims : (3,) int
        Grid size ``(nx, ny, nz)``.
    half : float or (T, 3) float64
        Half-size of the box tested for each voxel, in voxels, or one per
        triangle and axis.  0.5 is the voxel itself; ``0.5 +/- TIE_EPS`` on
        the axes that rounding can move gives the tie sets.
    edge_shift : (T, 3, 3) float64, optional
        Move the lines of the marked projected edges (yz, zx, xy; edges
        v0v1, v1v2, v2v0) outwards by this much (inwards when negative), in
        voxels along the edge normal's largest component; only the tie sets
        use it (slanted edges of a triangle lying in a voxel plane).
    flip : (T, 3) bool, optional
        Invert the orientation of the marked projections (yz, zx, xy) of the
        marked triangles; only the tie sets use it (see
        :func:`glvox.reference.ties.orientation_ambiguous`).
    no_plane : (T,) bool, optional
        Skip the plane test for the marked triangles (their plane is
        undefined up to rounding); only the tie sets use it.
    no_proj : (T, 3) bool, optional
        Skip the marked projection tests (yz, zx, xy); only the tie sets use
        it (edges too short for rounding to keep their direction).

    Returns
    -------
    (nx, ny, nz) bool
        ``out[i, j, k]`` is True iff voxel (i, j, k) is set.
    """
    tris, dims, halves, test = _conservative_setup(tris, dims, half, edge_shift, flip, no_plane, no_proj)
    return _run(tris, dims, pruned_candidates(tris, dims, _pad(halves)), test)


def _conservative_setup(tris, dims, half, edge_shift=None, flip=None, no_plane=None, no_proj=None):
    """Checked ``tris``, ``dims``, the (T, 3) half-sizes and the pair test of
    :func:`conservative_surface` (its parameters)."""
    tris = check_tris(tris)
    dims = check_dims(dims)
    halves = _halves(half, len(tris))
    dp = 2.0 * halves  # box extent per triangle and axis
    n = normals(tris)
    # <n, c> and <n, dp - c> for the critical point c of Eq. 1.
    o1 = (dp * np.maximum(n, 0.0)).sum(axis=1)
    o2 = (dp * np.minimum(n, 0.0)).sum(axis=1)
    ne = _edge_normals(tris, n, flip)
    # Eq. 2 without the -<n_e, v_i> term: the most interior box corner.
    oe = np.empty(ne.shape[:3])
    for p, (a, b, _) in enumerate(_PLANES):
        oe[:, p] = (np.maximum(0.0, dp[:, a, None] * ne[:, p, :, 0])
                    + np.maximum(0.0, dp[:, b, None] * ne[:, p, :, 1]))
    if edge_shift is not None:
        oe += _edge_shift(edge_shift, len(tris)) * np.abs(ne).max(axis=-1)
    test = _planar_test(tris, n, o1, o2, ne, oe, 0.5 - halves, halves, no_plane, no_proj)
    return tris, dims, halves, test


def conservative_pairs(tris: np.ndarray, dims: Sequence[int],
                       half: float = 0.5) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The (triangle, voxel) pairs of :func:`conservative_surface`: every triangle
    with every voxel whose box of half-size ``half`` it overlaps or touches.

    Yields
    ------
    tri : (P,) int64
        Triangle indices into ``tris``.
    ijk : (P, 3) int64
        The voxels, inside the grid.
    """
    tris, dims, halves, test = _conservative_setup(tris, dims, half)
    for tri, ijk in pruned_candidates(tris, dims, _pad(halves)):
        keep = test(tri, ijk)
        yield tri[keep], ijk[keep]


def six_separating_surface(tris: np.ndarray, dims: Sequence[int], half: float | np.ndarray = 0.5, *,
                           edge_shift: np.ndarray | None = None,
                           flip: np.ndarray | None = None,
                           no_plane: np.ndarray | None = None,
                         no_proj: np.ndarray | None = None) -> np.ndarray:
    """6-separating surface voxelization by the criterion of S&S Sec. 3.4.

    The plane test keeps voxels whose center is within
    ``half * |n_dom|`` of the plane along the normal (Huang et al.'s
    6-separating plane criterion; S&S write it as the offsets
    ``d1, d2 = <n, half - v0> +/- half |n_dom|`` with the box's minimum corner,
    ``dom`` the dominant axis of ``n``), and each projected edge test keeps
    pixels whose center is within ``half * max(|n_e,a|, |n_e,b|)`` of the
    inner side of the edge (the 4-separating line criterion).  Candidates are
    the voxels whose box meets the triangle's bounding box, as for the
    conservative test; since every offset is at most the conservative one,
    the result is a subset of :func:`conservative_surface` at the same
    ``half``.  Comparisons are inclusive, so a plane exactly between two
    voxel centers sets both.

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Triangle vertices in voxel space.
    dims : (3,) int
        Grid size ``(nx, ny, nz)``.
    half : float or (T, 3) float64
        Half the voxel extent ``Delta p / 2`` used by the criterion, in
        voxels, or one per triangle and axis: the plane test uses the
        normal's dominant axis, each edge test the dominant axis of its
        edge normal.
    edge_shift, flip, no_plane, no_proj : optional
        As in :func:`conservative_surface` (tie sets only).

    Returns
    -------
    (nx, ny, nz) bool
    """
    tris = check_tris(tris)
    dims = check_dims(dims)
    halves = _halves(half, len(tris))
    n = normals(tris)
    # Offsets of Sec. 3.4 relative to the box center: +/- half |n_dom| for the
    # plane, half * max(|n_e,a|, |n_e,b|) for the edges (half along the
    # dominant axis of each normal).
    absn = np.abs(n)
    rows = np.arange(len(tris))
    t = halves[rows, np.argmax(absn, axis=1)] * absn.max(axis=1)
    ne = _edge_normals(tris, n, flip)
    ane = np.abs(ne)
    oe = np.empty(ne.shape[:3])
    for p, (a, b, _) in enumerate(_PLANES):
        h = np.where(ane[:, p, :, 0] >= ane[:, p, :, 1], halves[:, a, None], halves[:, b, None])
        oe[:, p] = h * ane[:, p].max(axis=-1)
    if edge_shift is not None:
        oe += _edge_shift(edge_shift, len(tris)) * ane.max(axis=-1)
    test = _planar_test(tris, n, t, -t, ne, oe, np.full_like(halves, 0.5), halves, no_plane, no_proj)
    return _run(tris, dims, pruned_candidates(tris, dims, _pad(halves)), test)


def conservative_surface_sat(tris: np.ndarray, dims: Sequence[int], half: float = 0.5) -> np.ndarray:
    """Conservative surface voxelization by the separating-axis test (Akenine-Moller 2001).

    Independent of :func:`conservative_surface` on purpose: it evaluates the
    13 candidate separating axes (3 box normals, the triangle normal, and the
    9 cross products of the box axes with the triangle edges) on every voxel
    whose box meets the triangle's bounding box, without the column pruning.
    A triangle and a box overlap (or touch) iff no axis separates them
    strictly.

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Triangle vertices in voxel space.
    dims : (3,) int
        Grid size ``(nx, ny, nz)``.
    half : float
        Half-size of the box tested for each voxel, in voxels.

    Returns
    -------
    (nx, ny, nz) bool
    """
    tris = check_tris(tris)
    dims = check_dims(dims)
    half = check_half(half)
    f = np.roll(tris, -1, axis=1) - tris  # edges f_i = v_{i+1} - v_i, (T, 3, 3)
    n = np.cross(f[:, 0], f[:, 1])

    def separated(p: np.ndarray, r: np.ndarray) -> np.ndarray:
        # p: (M, 3) projections of the three vertices, r: (M,) box radius.
        return (p.min(axis=1) > r) | (p.max(axis=1) < -r)

    def test(tri: np.ndarray, ijk: np.ndarray) -> np.ndarray:
        w = tris[tri] - (ijk + 0.5)[:, None, :]  # vertices relative to the box center
        sep = np.zeros(len(tri), dtype=bool)
        for a in range(3):
            sep |= separated(w[:, :, a], np.full(len(tri), half))
        nt = n[tri]
        pn = np.einsum("ij,ij->i", nt, w[:, 0])
        rn = half * np.abs(nt).sum(axis=1)
        sep |= (pn > rn) | (pn < -rn)
        for i in range(3):
            fi = f[tri, i]
            # unit axis e_a x f_i, written out: e_x x f = (0, -f_z, f_y), etc.
            for axis_vec in ((np.zeros_like(fi[:, 0]), -fi[:, 2], fi[:, 1]),
                             (fi[:, 2], np.zeros_like(fi[:, 0]), -fi[:, 0]),
                             (-fi[:, 1], fi[:, 0], np.zeros_like(fi[:, 0]))):
                ax = np.stack(axis_vec, axis=1)
                p = np.einsum("mj,mkj->mk", ax, w)
                r = half * np.abs(ax).sum(axis=1)
                sep |= separated(p, r)
        return ~sep

    # Smaller chunks: this test keeps (M, 3, 3) temporaries alive.
    return _run(tris, dims, bbox_candidates(tris, dims, half, chunk=1 << 19), test)
