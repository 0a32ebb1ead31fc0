"""Tie sets: voxels whose exact verdict sits on a knife edge, and the check that uses them.

GPU methods work in float32 on vertices transformed to voxel space, the
references in float64.  A mismatch between them is acceptable only where it
is proven to be a tie (docs/design.md, "Ties"):

- surfaces: the voxel's verdict changes when the tested box half-size goes
  from ``0.5 - TIE_EPS`` to ``0.5 + TIE_EPS``, along the axes where rounding
  can move the triangle (:func:`rounding_perturbation`);
- solids: the voxel's verdict can change when the mesh moves by at most
  ``TIE_EPS``.
- binvox's solid: :mod:`.binvox_ties`.

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
from ._candidates import check_dims, check_eps, check_tris, pruned_candidates, scatter
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


def snap_ambiguous(unsnapped: np.ndarray, dims: Sequence[int], eps: float = SNAP_EPS) -> np.ndarray:
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
    eps : float
        The snap distance, voxels (``SNAP_EPS`` unless the grid's snap is another's).
    """
    u = check_tris(unsnapped)
    extent = float(np.ptp(u.reshape(-1, 3), axis=0).max()) if len(u) else 0.0
    motion = 2.0 ** -23 * max(extent, max(int(d) for d in dims))
    d = np.abs(u - np.floor(2.0 * u + 0.5) * 0.5)
    return np.abs(d - eps) <= motion


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
                 eps: float = TIE_EPS, unsnapped: np.ndarray | None = None,
                 gpu: np.ndarray | None = None) -> np.ndarray:
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

    Given ``gpu``, the voxels whose verdict differs between these triangles and
    the GPU's float32 copy of them are ties too.  The half-size models a
    translation; the rounding of a sliver's vertices also turns its plane,
    and at a voxel a fraction of a voxel away the plane then moves by that
    rounding times the distance over the sliver's width (a triangle 3.5e-4
    voxel wide, its vertices rounded by 1e-6: 6e-4 voxel at the voxel beside
    it, where the half-size ties reach 1e-4).

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
    gpu : (T, 3, 3) float64, optional
        The same triangles as the GPU methods compute them (float32 values,
        :func:`glvox.gpu.transform.gpu_vertices_voxel`).

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
    if gpu is not None:
        gpu = check_tris(gpu)
        if gpu.shape != tris.shape:
            raise ValueError(f"gpu must have the triangles' shape {tris.shape}, got {gpu.shape}")
        moved = (gpu != tris).any(axis=(1, 2))
        if moved.any():
            ties |= f(tris[moved], dims, 0.5) ^ f(gpu[moved], dims, 0.5)
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
        Largest motion of the mesh, in voxels, > 0.  The distance argument above
        holds for any motion, so a band of half a voxel or more (a method's
        documented rounding of a whole sample cell, say) is a valid request.
    unsnapped : (T, 3, 3) float64, optional
        The same triangles before the snap.

    Returns
    -------
    (nx, ny, nz) bool
    """
    tris = check_tris(tris)
    dims = check_dims(dims)
    check_eps(eps, below_half=False)
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
