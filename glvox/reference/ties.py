"""Tie sets: voxels whose exact verdict sits on a knife edge, and the check that uses them.

GPU methods work in float32 on vertices transformed to voxel space, the
references in float64.  A mismatch between them is acceptable only where it
is proven to be a tie (docs/design.md, "Ties"):

- surfaces: the voxel's verdict changes when the tested box half-size goes
  from ``0.5 - TIE_EPS`` to ``0.5 + TIE_EPS``, along the axes where rounding
  can move the triangle (:func:`rounding_perturbation`);
- solids: the voxel's verdict can change when the mesh moves by at most
  ``TIE_EPS``.

Every method and reference sees the vertices snapped to the voxel face and
center planes (:func:`glvox.grid.snap_to_planes`), so a triangle lying in a
voxel plane with its coordinates on those planes is decided exactly by the
float32 GPU methods and the float64 references alike: such geometry yields no
ties.  What rounding can still decide is the snap itself for a coordinate
within rounding of the snap distance (:func:`snap_ambiguous`); given the
unsnapped coordinates, the tie sets add what that changes.
"""

from __future__ import annotations

from typing import Literal, Sequence

import numpy as np

from ..tolerances import SHORT_EDGE_MOTIONS, SNAP_EPS, TIE_EPS
from ._candidates import (check_dims, check_eps, check_tris, column_candidates, normals, pruned_candidates,
                          scatter)
from .binvox import axis_crossings, view_to_grid
from .solid import column_crossings
from .surface import conservative_surface, six_separating_surface


def flat_axes(tris: np.ndarray) -> np.ndarray:
    """(T, 3) bool: the axes ``c`` along which a triangle's three coordinates are equal
    (the triangle lies in the plane ``x_c = const``).  Equal float64 coordinates stay
    equal in float32, so such a triangle's normal has exact zeros on both sides."""
    tris = check_tris(tris)
    return (tris[:, 0] == tris[:, 1]) & (tris[:, 1] == tris[:, 2])


def rounding_perturbation(tris: np.ndarray, eps: float = TIE_EPS) -> tuple[np.ndarray, np.ndarray]:
    """Where rounding can move a snapped triangle relative to the voxels, as box half-size
    perturbations per axis and edge shifts: ``(half (T, 3), edge (T, 3, 3))``, each 0 or eps.

    A slanted triangle: every axis (docs/design.md's definition).  A triangle lying in a
    plane ``x_c = const`` (:func:`flat_axes`) is decided exactly, by float32 and float64
    alike, except where a coordinate is off the snap planes: its verdicts turn where
    the plane or an extreme coordinate meets a voxel face plane, or where one of its
    slanted edges passes a voxel corner.  After the snap a coordinate is on a plane
    (a multiple of 1/2: exact in float32, and every test multiplies it by the exact
    zeros of the normal or by small integers) or farther than SNAP_EPS (> eps) from
    every plane; so only an axis with a coordinate within ``2 eps`` of a voxel face
    plane but not on it is perturbed (unsnapped input), and in the triangle's own
    projection each slanted edge with an end coordinate off the snap planes is
    shifted.  A face on a voxel plane, its edges on voxel lines, its corners on
    voxel corners: no ties.

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Voxel-space triangles (snapped, as every method sees them).
    eps : float
        The perturbation, voxels.

    Returns
    -------
    half : (T, 3) float64
        Box half-size perturbation per triangle and axis (0 or ``eps``), for
        ``half=0.5 +/- half`` of the reference surface functions.
    edge : (T, 3, 3) float64
        Edge shifts per triangle, projection (yz, zx, xy) and edge (0 or
        ``eps``), for their ``edge_shift=+/- edge``.
    """
    tris = check_tris(tris)
    flat = flat_axes(tris).any(axis=1)
    off = np.abs(tris - np.round(tris))  # distance to the nearest voxel face plane
    near = ((off > 0.0) & (off <= 2.0 * eps)).any(axis=1)
    half = np.where(flat[:, None] & ~near, 0.0, eps)
    edge = np.zeros((len(tris), 3, 3))
    on_planes = np.floor(2.0 * tris) == 2.0 * tris  # (T, 3 vertices, 3 axes)
    e = np.roll(tris, -1, axis=1) - tris
    exact_ends = on_planes & np.roll(on_planes, -1, axis=1)  # per edge (from vertex i) and axis
    for p, (a, b, w) in enumerate(((1, 2, 0), (2, 0, 1), (0, 1, 2))):
        mine = flat & flat_axes(tris)[:, w]
        slanted = (e[:, :, a] != 0.0) & (e[:, :, b] != 0.0)
        inexact = ~(exact_ends[:, :, a] & exact_ends[:, :, b])
        edge[:, p] = np.where(mine[:, None] & slanted & inexact, eps, 0.0)
    return half, edge


def snap_ambiguous(unsnapped: np.ndarray, dims: Sequence[int]) -> np.ndarray:
    """(T, 3, 3) bool: coordinates whose snap the GPU's rounding could decide otherwise.

    The GPU snaps its own value of a coordinate, computed in double from the
    float32 upload relative to the mesh's center: within 2^-25 of the model's
    extent (in voxels) of the float64 one.  A coordinate whose distance to the
    nearest multiple of 1/2 is within four times that (or of ``2^-23 N`` for a
    grid of N voxels, whichever is larger) of ``SNAP_EPS`` may be snapped on
    one side and not on the other.

    Parameters
    ----------
    unsnapped : (T, 3, 3) float64
        Voxel-space triangles before :func:`glvox.grid.snap_to_planes` (the
        whole mesh: its extent sets the rounding).
    dims : (3,) int
    """
    u = check_tris(unsnapped)
    extent = float(np.ptp(u.reshape(-1, 3), axis=0).max()) if len(u) else 0.0
    motion = 2.0 ** -23 * max(extent, max(int(d) for d in dims))
    d = np.abs(u - np.floor(2.0 * u + 0.5) * 0.5)
    return np.abs(d - SNAP_EPS) <= motion


def _other_snap(tris: np.ndarray, unsnapped: np.ndarray, amb: np.ndarray) -> np.ndarray:
    """``tris`` with each ambiguous coordinate snapped the other way."""
    r = np.floor(2.0 * unsnapped + 0.5) * 0.5
    other = np.where(np.abs(unsnapped - r) <= SNAP_EPS, unsnapped, r)
    return np.where(amb, other, tris)


def _check_unsnapped(unsnapped, tris: np.ndarray) -> np.ndarray:
    u = check_tris(unsnapped)
    if u.shape != tris.shape:
        raise ValueError(f"unsnapped must have the shape of tris {tris.shape}, got {u.shape}")
    return u


def surface_ties(tris: np.ndarray, dims: Sequence[int],
                 criterion: Literal["conservative", "6sep"] = "conservative",
                 eps: float = TIE_EPS, unsnapped: np.ndarray | None = None) -> np.ndarray:
    """Voxels whose surface verdict differs between box half-sizes ``0.5 - eps`` and ``0.5 + eps``
    along the inexact axes, or with the orientation of a nearly edge-on projection.

    Both criteria are monotone in the half-size (a larger box or cross only
    meets more), so the first part is the set accepted at ``0.5 + eps`` but
    not at ``0.5 - eps``: voxels that a triangle touches or misses by at most
    about ``eps`` voxel (docs/design.md's definition), perturbed only where rounding
    can move the triangle (:func:`rounding_perturbation`: a face on a voxel
    plane touches both layers exactly, no tie).  The second part extends it
    to what the float32 copy of the mesh on the GPU can legitimately change:
    for a projection whose orientation is ambiguous under an ``eps`` motion of
    the vertices (:func:`orientation_ambiguous`), the voxels whose verdict
    differs when that orientation is flipped; for a sliver whose whole normal
    is within rounding of zero, every voxel it could set with no plane test
    and any orientation; for the 6-separating criterion, which depends on edge
    directions, and a projection with an edge too short for float32 to keep
    its direction (:func:`short_edges`), every voxel the triangle could set
    without that projection's test.  A float32 result that differs from the float64
    reference only on these voxels is correct up to rounding.

    Given ``unsnapped``, a triangle with a :func:`snap_ambiguous` coordinate
    adds the voxels whose verdict differs between its two snaps, and the
    ties of the other snap.

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Triangle vertices in voxel space, snapped (:meth:`glvox.mesh.Mesh.triangles_voxel`).
    dims : (3,) int
        Grid size ``(nx, ny, nz)``.
    criterion : {'conservative', '6sep'}
        :func:`conservative_surface` or :func:`six_separating_surface`.
    eps : float
        Half-size perturbation, in voxels; 0 < eps < 0.5.
    unsnapped : (T, 3, 3) float64, optional
        The same triangles before the snap.

    Returns
    -------
    (nx, ny, nz) bool
    """
    funcs = {"conservative": conservative_surface, "6sep": six_separating_surface}
    if criterion not in funcs:
        raise ValueError(f"criterion must be 'conservative' or '6sep', got {criterion!r}")
    check_eps(eps)
    f = funcs[criterion]
    tris = check_tris(tris)
    ties = _rounding_ties(f, tris, dims, criterion, eps)
    if unsnapped is not None:
        amb = snap_ambiguous(_check_unsnapped(unsnapped, tris), dims)
        some = amb.any(axis=(1, 2))
        if some.any():
            mine = tris[some]
            other = _other_snap(mine, np.asarray(unsnapped, np.float64)[some], amb[some])
            ties |= f(mine, dims, 0.5) ^ f(other, dims, 0.5)
            ties |= _rounding_ties(f, other, dims, criterion, eps)
    return ties


def _rounding_ties(f, tris: np.ndarray, dims, criterion: str, eps: float) -> np.ndarray:
    """:func:`surface_ties` without the snap: half-size (and edge), orientation and short-edge ties."""
    half, edge = rounding_perturbation(tris, eps)
    ties = f(tris, dims, 0.5 + half, edge_shift=edge) ^ f(tris, dims, 0.5 - half, edge_shift=-edge)
    _add_orientation_ties(ties, f, tris, dims, criterion, eps)
    if criterion == "6sep":
        _add_short_edge_ties(ties, f, tris, dims, eps)
    return ties


def _add_orientation_ties(ties: np.ndarray, f, tris: np.ndarray, dims, criterion: str, eps: float) -> None:
    """Orientation ties, into ``ties``: where a projection's orientation is ambiguous
    under an eps motion of the vertices, every voxel whose verdict depends on it.
    A triangle lying in a plane ``x_c = const`` has ``n_w = 0`` exactly in the other
    two projections, in float32 and float64 alike (its ``c`` coordinates are equal
    numbers on both sides): those orientations are not ambiguous."""
    amb = orientation_ambiguous(tris, eps)
    flat = (tris[:, 0] == tris[:, 1]) & (tris[:, 1] == tris[:, 2])  # (T, 3): the plane's axis c
    # projection p (yz, zx, xy) is along axis p; it is edge-on when the triangle is flat along another axis
    amb &= ~(flat.any(axis=1, keepdims=True) & ~flat)
    some = amb.any(axis=1)
    if not some.any():
        return
    sub, amb = tris[some], amb[some]
    base = f(sub, dims, 0.5)
    flips = [amb]
    if (amb.sum(axis=1) > 1).any():  # also each ambiguous plane alone
        flips += [amb & (np.arange(3) == p) for p in range(3)]
    for flip in flips:
        ties |= base ^ f(sub, dims, 0.5, flip=flip)
    # Slivers whose whole normal is within rounding of zero: their plane is
    # undefined, so every voxel they could set under any orientation is a tie.
    free = amb.all(axis=1)
    if free.any():
        sliver = sub[free]
        no_plane = np.ones(len(sliver), dtype=bool)
        for bits in range(8):
            flip = np.array([(bits >> p) & 1 for p in range(3)], dtype=bool)[None, :].repeat(len(sliver), 0)
            ties |= f(sliver, dims, 0.5 + eps, flip=flip, no_plane=no_plane)
        if criterion == "6sep":
            # the 6-separating criterion of a segment-like triangle depends on
            # a dominant axis that rounding picks: any voxel the sliver touches
            # (found by the fuzz tests: a collinear triangle at a 1e6 offset)
            ties |= conservative_surface(sliver, dims, 0.5 + eps)


def _add_short_edge_ties(ties: np.ndarray, f, tris: np.ndarray, dims, eps: float) -> None:
    """6-separating ties, into ``ties``: projected edges too short for float32 to keep
    their direction leave the projection test they belong to undecided near them.
    (The conservative test decides whether the triangle meets the box, a geometric
    question that no edge direction changes.)"""
    short = short_edges(tris, dims)
    if not short.any():
        return
    sub = short.any(axis=1)
    ties |= f(tris[sub], dims, 0.5, no_proj=short[sub])
    # A triangle short in every projection is smaller than float32's
    # spacing can shape: its plane and edges are both rounding, so every
    # voxel its bounding box touches within eps is a tie (found by the
    # fuzz tests: a 1e-6 triangle at y = 32 lands on the face y = 32 in
    # float32 and sets the voxels on both sides).
    for tri in tris[short.all(axis=1)]:
        lo = np.maximum(np.ceil(tri.min(axis=0) - eps).astype(np.int64) - 1, 0)
        hi = np.minimum(np.floor(tri.max(axis=0) + eps).astype(np.int64), np.array(dims) - 1)
        if (lo <= hi).all():
            ties[lo[0]:hi[0] + 1, lo[1]:hi[1] + 1, lo[2]:hi[2] + 1] = True


def float32_motion(dims: Sequence[int]) -> float:
    """How far float32 voxel-space vertices can sit from the float64 ones, in voxels.

    The GPU methods upload vertices relative to the mesh's center in float32
    (a relative error of 2^-24 of at most half the model, i.e. N/2 voxels) and
    round the voxel-space result to float32 once more (2^-24 of at most N + 2
    voxels): together below 2^-23 * N; twice that is returned.
    """
    return 2.0 ** -22 * max(int(d) for d in dims)


def short_edges(tris: np.ndarray, dims: Sequence[int]) -> np.ndarray:
    """(T, 3) bool: projections (yz, zx, xy) with an edge of length in
    (0, SHORT_EDGE_MOTIONS * float32_motion(dims)].  Zero-length edges stay
    exactly zero in float32 and are not short in this sense."""
    tris = check_tris(tris)
    limit = SHORT_EDGE_MOTIONS * float32_motion(dims)
    e = np.roll(tris, -1, axis=1) - tris
    out = np.empty((len(tris), 3), dtype=bool)
    for p, (a, b, _) in enumerate(((1, 2, 0), (2, 0, 1), (0, 1, 2))):
        length = np.hypot(e[:, :, a], e[:, :, b])
        out[:, p] = ((length > 0) & (length <= limit)).any(axis=1)
    return out


def orientation_ambiguous(tris: np.ndarray, eps: float = TIE_EPS) -> np.ndarray:
    """Projections whose orientation can flip when the vertices move by at most ``eps``.

    The S&S edge normals of the projection onto a coordinate plane are
    oriented by the sign of the normal's component ``n_w`` across that plane
    (Eq. 2).  For a triangle seen nearly edge-on, ``n_w`` is close to zero and
    its sign, hence the side that a short edge keeps, can flip under a motion
    far below a voxel; a float32 copy of the mesh (what the GPU sees) may then
    orient it the other way.  With edges ``e0, e1`` and vertex motions of at
    most ``eps`` per coordinate, ``n_w = e0_a e1_b - e0_b e1_a`` moves by at most
    ``2 eps (|e0_a| + |e0_b| + |e1_a| + |e1_b|) + 8 eps^2``.

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Voxel space.
    eps : float
        Vertex motion, voxels.

    Returns
    -------
    (T, 3) bool
        For the planes yz, zx, xy (``_PLANES`` order of :mod:`.surface`).
    """
    e0 = tris[:, 1] - tris[:, 0]
    e1 = tris[:, 2] - tris[:, 0]
    out = np.empty((len(tris), 3), dtype=bool)
    for p, (a, b, w) in enumerate(((1, 2, 0), (2, 0, 1), (0, 1, 2))):
        nw = e0[:, a] * e1[:, b] - e0[:, b] * e1[:, a]
        bound = 2.0 * eps * (np.abs(e0[:, a]) + np.abs(e0[:, b]) + np.abs(e1[:, a]) + np.abs(e1[:, b]))
        out[:, p] = np.abs(nw) <= bound + 8.0 * eps * eps
    return out


def point_triangle_distance(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Euclidean distance from points to triangles, pairwise.

    Parameters
    ----------
    p : (M, 3) float64
        Points.
    tri : (M, 3, 3) float64
        One triangle per point.

    Returns
    -------
    (M,) float64
        Distance from ``p[m]`` to the closed triangle ``tri[m]``.  Zero-area
        triangles are measured as the segments (or point) they are.
    """
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, c - a)
    nn = np.einsum("ij,ij->i", n, n)
    # Projection inside the triangle iff p is on the inner side of all three
    # edge planes (each containing the edge and n).
    inside = nn > 0.0
    for s, t in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("ij,ij->i", np.cross(t - s, p - s), n) >= 0.0
    d = np.full(len(p), np.inf)
    for s, t in ((a, b), (b, c), (c, a)):
        st = t - s
        ll = np.einsum("ij,ij->i", st, st)
        w = np.einsum("ij,ij->i", p - s, st) / np.where(ll > 0.0, ll, 1.0)
        w = np.clip(w, 0.0, 1.0)
        d = np.minimum(d, np.linalg.norm(p - (s + w[:, None] * st), axis=1))
    plane = np.abs(np.einsum("ij,ij->i", p - a, n)) / np.sqrt(np.where(inside, nn, 1.0))
    return np.where(inside, np.minimum(plane, d), d)


def solid_ties(tris: np.ndarray, dims: Sequence[int], eps: float = TIE_EPS,
               unsnapped: np.ndarray | None = None) -> np.ndarray:
    """Voxels whose solid verdict can change when the mesh moves by at most ``eps``.

    These are exactly the voxels whose center lies within Euclidean distance
    ``eps`` of the surface (some triangle):

    - if ``dist(center, surface) <= eps``, translating the mesh by the vector
      from the nearest surface point to the center (length <= eps) puts the
      center on the surface, and a slightly different translation of length
      <= eps (towards the other side, when dist < eps) flips it;
    - if ``dist > eps``, moving every vertex by at most ``eps`` moves every
      surface point by at most ``eps`` (convex combinations), so along the
      straight-line motion the surface never passes through the center and
      its crossing parity cannot change.

    Centers exactly on a shared edge or vertex, where the fill rule decides,
    have distance 0 and are ties too.

    Only centers inside a triangle's bounding box grown by ``eps`` can be
    that close to it, and along the triangle's dominant axis only those near
    its plane; the point/triangle distances are computed for those candidate
    pairs only, a plane-distance test first.

    A face snapped onto a voxel face plane leaves every center half a voxel
    away; one snapped onto a center plane puts centers exactly on it, where
    the half-open and top-left rules decide, and those depend on the ray
    direction (a method along another axis than its reference legitimately
    differs there): they stay ties.  Given ``unsnapped``, the triangles with a
    :func:`snap_ambiguous` coordinate add the centers within the snap's motion
    of them.

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Triangle vertices in voxel space, snapped (:meth:`glvox.mesh.Mesh.triangles_voxel`).
    dims : (3,) int
        Grid size ``(nx, ny, nz)``.
    eps : float
        Largest motion of the mesh, in voxels; 0 < eps < 0.5.
    unsnapped : (T, 3, 3) float64, optional
        The same triangles before the snap.

    Returns
    -------
    (nx, ny, nz) bool
    """
    tris = check_tris(tris)
    dims = check_dims(dims)
    check_eps(eps)
    out = _near_surface(tris, dims, eps)
    if unsnapped is not None:
        some = snap_ambiguous(_check_unsnapped(unsnapped, tris), dims).any(axis=(1, 2))
        if some.any():
            # the other snap moves a vertex by at most SNAP_EPS + rounding per coordinate
            motion = np.sqrt(3.0) * (SNAP_EPS + float32_motion(dims))
            out |= _near_surface(tris[some], dims, eps + motion)
    return out


def _near_surface(tris: np.ndarray, dims: tuple[int, int, int], eps: float) -> np.ndarray:
    """Voxels whose center lies within Euclidean distance ``eps`` of a triangle."""
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    nlen = np.linalg.norm(n, axis=1)
    out = np.zeros(dims, dtype=bool)
    # A center within eps of a triangle lies in its bounding box grown by
    # eps, i.e. the cube of half-size eps around the center meets the
    # bounding box: the candidates of pad = eps.
    for tri, ijk in pruned_candidates(tris, dims, eps):
        c = ijk + 0.5
        plane = np.abs(np.einsum("ij,ij->i", c - tris[tri, 0], n[tri]))
        near = plane <= eps * nlen[tri]
        tri, ijk, c = tri[near], ijk[near], c[near]
        close = point_triangle_distance(c, tris[tri]) <= eps
        scatter(out, ijk[close])
    return out


def mismatch_is_tie(result: np.ndarray, reference: np.ndarray,
                    ties: np.ndarray) -> tuple[bool, np.ndarray]:
    """Check that a voxelization differs from its exact reference only on ties.

    Parameters
    ----------
    result : (nx, ny, nz) bool
        The voxelization under test (e.g. a GPU method's dense result).
    reference : (nx, ny, nz) bool
        The exact float64 reference of the same kind on the same grid.
    ties : (nx, ny, nz) bool
        The tie set for that kind: :func:`surface_ties` (with the matching
        criterion) for surfaces, :func:`solid_ties` for solids.

    Returns
    -------
    ok : bool
        True iff every voxel where ``result != reference`` lies in ``ties``
        (in particular when they are equal).
    unexplained : (M, 3) int64
        Voxel indices ``(i, j, k)`` of the mismatches outside ``ties``, in
        C order; empty, shape (0, 3), when ``ok``.

    Examples
    --------
    >>> ok, bad = mismatch_is_tie(gpu, ref, surface_ties(tris, dims))
    >>> assert ok, f"{len(bad)} mismatches are not ties, first {bad[:5].tolist()}"
    """
    result = np.asarray(result, dtype=bool)
    reference = np.asarray(reference, dtype=bool)
    ties = np.asarray(ties, dtype=bool)
    if result.ndim != 3 or result.shape != reference.shape or ties.shape != reference.shape:
        raise ValueError("result, reference and ties must be 3D arrays of one shape, got "
                         f"{result.shape}, {reference.shape} and {ties.shape}")
    unexplained = np.argwhere((result != reference) & ~ties).astype(np.int64)
    return len(unexplained) == 0, unexplained


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
      its exact distance to every center away from its ends.  Near the inside of an edge shared by two triangles that face the same way along the
      view beyond what the motion can flip, one of them owns the center either way (the
      top-left rule): the column is a tie only if their planes give the center different
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
        some = snap_ambiguous(_check_unsnapped(unsnapped, tris) * f, fine).any(axis=(1, 2))
        motion[some] += SNAP_EPS + float32_motion(fine)
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
            near = _segment_distance(c, a, b) <= r
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
    keep = np.flatnonzero(na != 0.0)
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
    flip = _lex_less(ends[:, 1], ends[:, 0])[:, None]
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


def _lex_less(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(M,) bool: row ``a`` < row ``b`` lexicographically, rows of 3."""
    lt = a < b
    eq = a == b
    return lt[:, 0] | (eq[:, 0] & (lt[:, 1] | (eq[:, 1] & lt[:, 2])))


def _segment_distance(c: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(M,) Euclidean distances of the 2D points ``c`` to the segments ``a b``."""
    e = b - a
    ee = np.einsum("ij,ij->i", e, e)
    t = np.clip(np.einsum("ij,ij->i", c - a, e) / np.where(ee > 0.0, ee, 1.0), 0.0, 1.0)
    return np.linalg.norm(c - (a + t[:, None] * e), axis=1)


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
