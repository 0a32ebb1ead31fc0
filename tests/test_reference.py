"""Tests of the exact CPU references (glvox.reference).

Every expectation here is worked out by hand (with the reasoning next to it)
or comes from an independent formulation: the separating-axis test for the
Schwarz & Seidel triangle/box test, rays along the other two axes and a
generalized winding number for the solid, brute-force distances for the tie
sets.  None is a recorded output of the code under test.
"""

from __future__ import annotations


import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull

import glvox
from glvox.grid import snap_to_planes
from glvox.metrics import separation_leaks
from glvox.reference import (TIE_EPS, conservative_surface, conservative_surface_sat, float32_motion,
                             mismatch_is_tie, orientation_ambiguous, point_triangle_distance, short_edges,
                             rounding_perturbation, six_separating_surface, solid, solid_ties, surface_ties)
from glvox.testing.plugin import mesh_or_skip



# ----------------------------------------------------------------------------
# helpers

def load_mesh(name: str) -> trimesh.Trimesh:
    return trimesh.load(mesh_or_skip(name), force="mesh")


def fit(mesh: trimesh.Trimesh, n: int):
    """Default grid fit: cubic n^3 grid of voxel size max_extent / n centered on the bounding box.

    Returns the (T, 3, 3) triangles in voxel space, dims, world origin and voxel size.
    """
    lo, hi = mesh.bounds
    h = float((hi - lo).max()) / n
    origin = 0.5 * (lo + hi) - h * n / 2
    return (mesh.triangles - origin) / h, (n, n, n), origin, h


def box_tris(lo: float, hi: float) -> np.ndarray:
    """The 12 outward-facing triangles of the cube [lo, hi]^3, (12, 3, 3)."""
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    return (box.triangles + 0.5) * (hi - lo) + lo


def octahedron_tris(center, r: float) -> np.ndarray:
    """The 8 triangles of the octahedron |x-c|_1 <= r, (8, 3, 3)."""
    c = np.asarray(center, dtype=float)
    tris = []
    for sx in (-1, 1):
        for sy in (-1, 1):
            for sz in (-1, 1):
                a = c + [sx * r, 0, 0]
                b = c + [0, sy * r, 0]
                d = c + [0, 0, sz * r]
                # outward orientation: flip when the octant has odd parity
                tris.append([a, b, d] if sx * sy * sz > 0 else [a, d, b])
    return np.array(tris, dtype=float)


def voxel_set(mask: np.ndarray) -> set:
    return set(map(tuple, np.argwhere(mask).tolist()))


def winding_number(points: np.ndarray, tris: np.ndarray, chunk: int = 1 << 20) -> np.ndarray:
    """Generalized winding number of a closed mesh at ``points`` (van Oosterom & Strackee solid angles).

    points : (P, 3), tris : (T, 3, 3) -> (P,) float64, ~1 inside, ~0 outside.
    """
    out = np.zeros(len(points))
    step = max(chunk // len(tris), 1)
    v = [[tris[None, :, k, a] for a in range(3)] for k in range(3)]
    for s in range(0, len(points), step):
        p = points[s:s + step]
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = (
            [v[k][a] - p[:, a, None] for a in range(3)] for k in range(3))
        la = np.sqrt(ax * ax + ay * ay + az * az)
        lb = np.sqrt(bx * bx + by * by + bz * bz)
        lc = np.sqrt(cx * cx + cy * cy + cz * cz)
        det = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
        den = (la * lb * lc + (ax * bx + ay * by + az * bz) * lc
               + (bx * cx + by * cy + bz * cz) * la + (cx * ax + cy * ay + cz * az) * lb)
        out[s:s + step] = np.arctan2(det, den).sum(axis=1) / (2 * np.pi)
    return out


def centers(dims) -> np.ndarray:
    """(N, 3) voxel centers of the whole grid, C order, voxel space."""
    return np.stack(np.meshgrid(*[np.arange(n) + 0.5 for n in dims], indexing="ij"),
                    axis=-1).reshape(-1, 3)


@pytest.fixture(scope="module")
def bunny():
    return load_mesh("stanford_bunny_bun_zipper.ply")


@pytest.fixture(scope="module")
def armadillo():
    return load_mesh("stanford_armadillo_libigl_86k.obj")


@pytest.fixture(scope="module")
def sphere():
    # Off-center and slightly squashed so that no symmetry lines up with the grid.
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    m.apply_transform(np.diag([1.0, 0.93, 0.87, 1.0]))
    m.apply_translation([0.0123, -0.0271, 0.0319])
    return m


SURFACES = {
    "conservative": conservative_surface,
    "sat": conservative_surface_sat,
    "6sep": six_separating_surface,
}


# ----------------------------------------------------------------------------
# input handling

def test_rejects_bad_input():
    tri = np.zeros((1, 3, 3))
    with pytest.raises(ValueError, match=r"tris must have shape \(T, 3, 3\), got \(3, 3\)"):
        conservative_surface(np.zeros((3, 3)), (4, 4, 4))
    with pytest.raises(ValueError, match="tris must be finite"):
        solid(np.full((1, 3, 3), np.nan), (4, 4, 4))
    with pytest.raises(ValueError, match=r"dims must be three positive integers, got \(4, 0, 4\)"):
        six_separating_surface(tri, (4, 0, 4))
    with pytest.raises(ValueError, match="dims must be three positive integers"):
        solid(tri, (4, 4))
    with pytest.raises(ValueError, match="half must be a positive finite box half-size, got -0.5"):
        conservative_surface_sat(tri, (4, 4, 4), half=-0.5)
    with pytest.raises(ValueError, match="axis must be 0, 1 or 2, got 3"):
        solid(tri, (4, 4, 4), axis=3)
    with pytest.raises(ValueError, match="criterion must be 'conservative' or '6sep', got 'thin'"):
        surface_ties(tri, (4, 4, 4), criterion="thin")
    with pytest.raises(ValueError, match=r"eps must be in \(0, 0.5\) voxel, got 0.7"):
        surface_ties(tri, (4, 4, 4), eps=0.7)
    with pytest.raises(ValueError, match=r"eps must be a positive length in voxels, got 0.0"):
        solid_ties(tri, (4, 4, 4), eps=0.0)
    with pytest.raises(ValueError, match=r"one shape, got \(2, 2, 2\), \(2, 2, 3\)"):
        mismatch_is_tie(np.zeros((2, 2, 2)), np.zeros((2, 2, 3)), np.zeros((2, 2, 3)))


def test_empty_input_gives_empty_grids():
    none = np.zeros((0, 3, 3))
    for f in (*SURFACES.values(), solid, surface_ties, solid_ties):
        out = f(none, (3, 4, 5))
        assert out.shape == (3, 4, 5) and out.dtype == bool and not out.any()


# ----------------------------------------------------------------------------
# hand-worked cases

def test_box_with_faces_inside_voxels():
    # Cube [1.25, 6.75]^3 in an 8^3 grid.  Each face lies strictly inside one
    # layer of voxels (1.25 in voxel 1, 6.75 in voxel 6) and spans voxels
    # 1..6 in its other two axes (1.25 and 6.75 are interior to voxels 1 and
    # 6), so the conservative shell is the boundary of the 6^3 block
    # [1..6]^3: 6^3 - 4^3 = 152 voxels.  The 6-separating criterion keeps the
    # same voxels: each face plane is 0.25 from the centers of layer 1 (or 6)
    # and 0.75 from the neighbours, and every edge is 0.25 from a center row.
    # Centers inside: i + .5 in (1.25, 6.75)  <=>  i in 1..6, 216 voxels.
    tris = box_tris(1.25, 6.75)
    dims = (8, 8, 8)
    block = np.zeros(dims, bool)
    block[1:7, 1:7, 1:7] = True
    shell = block.copy()
    shell[2:6, 2:6, 2:6] = False
    assert shell.sum() == 152
    for name, f in SURFACES.items():
        np.testing.assert_array_equal(f(tris, dims), shell, err_msg=name)
    for axis in range(3):
        np.testing.assert_array_equal(solid(tris, dims, axis), block)
    # Nothing is within 1e-4 of a knife edge.
    assert not surface_ties(tris, dims).any()
    assert not surface_ties(tris, dims, "6sep").any()
    assert not solid_ties(tris, dims).any()


def test_box_with_faces_on_voxel_planes():
    # Cube [2, 6]^3 in an 8^3 grid.  The face x = 2 is the common face of
    # voxel layers 1 and 2, which both touch it; its edges y, z = 2 and 6
    # are likewise touched by voxels 1, 2 and 5, 6.  So face x = 2 sets
    # {1, 2} x [1..6] x [1..6], and the union of the six faces is the block
    # [1..6]^3 minus the voxels touching no face, [3..4]^3: 216 - 8 = 208,
    # a shell two voxels thick.  Every one of them only touches the surface:
    # with boxes shrunk to half-size 0.5 - eps nothing is hit.  But the faces
    # lie exactly on voxel planes (multiples of 1/2, exact in float32 too), and
    # every method decides them exactly: no ties (the old isotropic rule made
    # all 208 ties, and excused a dropped wall).  Solid: centers in (2, 6), i.e.
    # 2..5 -> 64, no ties.
    tris = box_tris(2.0, 6.0)
    dims = (8, 8, 8)
    shell = np.zeros(dims, bool)
    shell[1:7, 1:7, 1:7] = True
    shell[3:5, 3:5, 3:5] = False
    assert shell.sum() == 208
    for name, f in SURFACES.items():
        np.testing.assert_array_equal(f(tris, dims), shell, err_msg=name)
        assert not f(tris, dims, half=0.5 - TIE_EPS).any(), name
        np.testing.assert_array_equal(f(tris, dims, 0.5 + TIE_EPS) ^ f(tris, dims, 0.5 - TIE_EPS), shell)
    assert not any(x.any() for x in rounding_perturbation(tris))
    assert not surface_ties(tris, dims).any()
    assert not surface_ties(tris, dims, "6sep").any()
    inner = np.zeros(dims, bool)
    inner[2:6, 2:6, 2:6] = True
    for axis in range(3):
        np.testing.assert_array_equal(solid(tris, dims, axis), inner)
    assert not solid_ties(tris, dims).any()


def test_single_triangle_corner_cut():
    # Triangle (3.25,0,0), (0,3.25,0), (0,0,3.25) in a 3^3 grid (it leaves
    # the grid; the rest is clipped).  It is the part of the plane
    # x + y + z = 3.25 in the octant x, y, z >= 0, and every voxel of the
    # grid lies in that octant, so a voxel meets the triangle iff it meets
    # the plane: its coordinate sums range over [s, s + 3] with s = i+j+k,
    # and 3.25 is in there iff s in {1, 2, 3} (never at an end: no touching).
    expected_conservative = {
        (1, 0, 0), (0, 1, 0), (0, 0, 1),                        # s = 1
        (2, 0, 0), (0, 2, 0), (0, 0, 2),                        # s = 2
        (1, 1, 0), (1, 0, 1), (0, 1, 1),
        (2, 1, 0), (2, 0, 1), (1, 2, 0), (0, 2, 1), (1, 0, 2),  # s = 3
        (0, 1, 2), (1, 1, 1),
    }
    # 6-separating: n = (1,1,1) (up to scale), dominant |n_x| = 1, so the
    # center sum s + 1.5 must be within 0.5 of 3.25: s in [1.25, 2.25], s = 2.
    # The projected edge tests hold with room to spare there (e.g. in xy,
    # c_x + c_y <= 3.25 + 0.5 since c_x + c_y <= 3 for s = 2).
    expected_6sep = {(2, 0, 0), (0, 2, 0), (0, 0, 2), (1, 1, 0), (1, 0, 1), (0, 1, 1)}
    tri = np.array([[[3.25, 0, 0], [0, 3.25, 0], [0, 0, 3.25]]])
    dims = (3, 3, 3)
    assert voxel_set(conservative_surface(tri, dims)) == expected_conservative
    assert voxel_set(conservative_surface_sat(tri, dims)) == expected_conservative
    assert voxel_set(six_separating_surface(tri, dims)) == expected_6sep
    assert not surface_ties(tri, dims).any()
    assert not surface_ties(tri, dims, "6sep").any()


def test_single_triangle_touching_corners():
    # Triangle (3,0,0), (0,3,0), (0,0,3): plane x + y + z = 3 in the octant.
    # A voxel meets it iff 3 in [s, s + 3], s = i+j+k in {0, 1, 2, 3}:
    # 1 + 3 + 6 + 7 = 17 voxels (with s = 3 there are 10 - 3 triples in
    # 0..2, the three (3,0,0)-like ones being outside the grid).  For s = 0
    # the plane only touches voxel (0,0,0) at its corner (1,1,1), for s = 3 at
    # the min corner: those 8 voxels are the conservative ties.
    # 6-separating: |s + 1.5 - 3| <= 0.5 gives s in {1, 2} (9 voxels), each
    # exactly at the limit, so all 9 are 6-sep ties.
    tri = np.array([[[3.0, 0, 0], [0, 3.0, 0], [0, 0, 3.0]]])
    dims = (3, 3, 3)
    idx = np.indices(dims).sum(axis=0)
    np.testing.assert_array_equal(conservative_surface(tri, dims), idx <= 3)
    assert (idx <= 3).sum() == 17
    np.testing.assert_array_equal(surface_ties(tri, dims), (idx == 0) | (idx == 3))
    np.testing.assert_array_equal(six_separating_surface(tri, dims), (idx == 1) | (idx == 2))
    np.testing.assert_array_equal(surface_ties(tri, dims, "6sep"), (idx == 1) | (idx == 2))


def test_degenerate_triangles_are_segments_or_points():
    # Zero-area triangles do not reach the references through glvox's mesh
    # input, but must not break them: the box test reduces to box/segment
    # (box/point) overlap, the solid ignores them, nothing divides by zero.
    segment = np.array([[[0.5, 0.5, 0.5], [2.5, 0.5, 0.5], [1.5, 0.5, 0.5]]])
    point = np.array([[[2.0, 1.5, 1.5]] * 3])   # on the face between voxels 1 and 2
    dims = (3, 3, 3)
    with np.errstate(all="raise"):
        for name in ("conservative", "sat"):
            assert voxel_set(SURFACES[name](segment, dims)) == {(0, 0, 0), (1, 0, 0), (2, 0, 0)}
            assert voxel_set(SURFACES[name](point, dims)) == {(1, 1, 1), (2, 1, 1)}
        assert voxel_set(six_separating_surface(segment, dims)) <= {(0, 0, 0), (1, 0, 0), (2, 0, 0)}
        assert not solid(np.concatenate([segment, point]), dims).any()
        ties = solid_ties(np.concatenate([segment, point]), dims)
        # The segment passes through the centers of (0..2, 0, 0).
        assert voxel_set(ties) == {(0, 0, 0), (1, 0, 0), (2, 0, 0)}
        surface_ties(segment, dims)


# ----------------------------------------------------------------------------
# tessellation independence (S&S Fig. 5)

def _quad_splits(a, u, v):
    a, u, v = (np.asarray(x, dtype=float) for x in (a, u, v))
    p0, p1, p2, p3 = a, a + u, a + u + v, a + v
    return np.array([[p0, p1, p2], [p0, p2, p3]]), np.array([[p0, p1, p3], [p1, p2, p3]])


# Coordinates are multiples of 1/8, so every quantity both tests compute is
# exact in float64 and the comparisons can be exact.
AXIS_ALIGNED_QUADS = [
    ((0.75, 1.25, 2.5), (3.5, 0, 0), (0, 2.75, 0)),      # in z = 2.5, inside a layer
    ((1.0, 0.5, 2.0), (0, 3.0, 0), (0, 0, 2.5)),         # in x = 1, on a voxel plane
    ((0.375, 5.125, 3.0), (4.25, 0, 0), (0, 0, -2.5)),   # in y = 5.125, partly outside
]
TILTED_QUADS = [
    ((0.75, 1.25, 0.5), (3.5, 0.75, 1.25), (-0.5, 2.75, 1.5)),
    ((1.125, 0.5, 4.0), (2.0, 2.5, -1.5), (1.5, 0.25, 2.0)),
    ((5.5, 0.25, 0.75), (-3.0, 1.0, 0.5), (1.0, 2.0, 3.0)),
]


@pytest.mark.parametrize("quad", AXIS_ALIGNED_QUADS + TILTED_QUADS)
def test_conservative_independent_of_quad_diagonal(quad):
    one, other = _quad_splits(*quad)
    dims = (7, 7, 7)
    for f in (conservative_surface, conservative_surface_sat):
        np.testing.assert_array_equal(f(one, dims), f(other, dims))
    for half in (0.5 - TIE_EPS, 0.5 + TIE_EPS):
        np.testing.assert_array_equal(conservative_surface(one, dims, half),
                                      conservative_surface(other, dims, half))


def test_conservative_independent_of_quad_diagonal_random():
    rng = np.random.default_rng(5)
    dims = (8, 8, 8)
    for _ in range(40):
        a, u, v = (np.round(rng.uniform(lo, hi, 3) * 8) / 8 for lo, hi in ((0, 5), (-3, 3), (-3, 3)))
        one, other = _quad_splits(a, u, v)
        np.testing.assert_array_equal(conservative_surface(one, dims), conservative_surface(other, dims))


# Rectangles whose edges follow at least one grid axis: the 4-separating
# edge tests then meet no acute corner beyond which they over-reach.
SIXSEP_RECTANGLES = AXIS_ALIGNED_QUADS + [
    ((0.625, 1.5, 1.25), (4.5, 0, 0), (0, 2.25, 1.75)),   # plane tilted about x
    ((1.5, 0.75, 1.0), (0, 1.5, 1.5), (3.25, 0, 0)),
]


@pytest.mark.parametrize("quad", SIXSEP_RECTANGLES)
def test_six_separating_independent_of_rectangle_diagonal(quad):
    one, other = _quad_splits(*quad)
    dims = (7, 7, 7)
    np.testing.assert_array_equal(six_separating_surface(one, dims),
                                  six_separating_surface(other, dims))


def test_six_separating_depends_on_diagonal_at_acute_corner():
    # The S&S Sec. 3.4 criterion is not tessellation independent for general
    # quads, and the GPU method must reproduce that.  Quad A=(2,1), B=(3.5,3),
    # C=(3.5,4), D=(1.5,1.5) in the plane z = 0.5 of a 4x4x1 grid; pixel
    # (1, 0), center (1.5, 0.5):
    # - split ABC + ACD: in ABC (counter-clockwise, inward normals
    #   (-e_y, e_x)) edge AB: n=(-2, 1.5), n.(c-A) = 1 - 0.75 = 0.25 >= -0.5*2;
    #   edge BC: n=(-1, 0), n.(c-B) = 2 >= 0; edge CA: n=(3, -1.5),
    #   n.(c-C) = -6 + 5.25 = -0.75 >= -0.5*3.  The pixel touches ABC's
    #   bounding box at (2, 1) and the plane test holds (layer 0): set.
    # - split ABD + BCD: in ABD edge DA: n = (0.5, 0.5), n.(c-D) = -0.5
    #   < -0.5*0.5: rejected; BCD's bounding box starts at y = 1.5: not a
    #   candidate.  Not set.
    # The pixel's diamond (the 4-separating reach) does not even touch the
    # quad: it lies beyond vertex A, where ABC's angle is acute.
    a, b, c, d = ([x, y, 0.5] for x, y in ((2, 1), (3.5, 3), (3.5, 4), (1.5, 1.5)))
    one = np.array([[a, b, c], [a, c, d]], dtype=float)
    other = np.array([[a, b, d], [b, c, d]], dtype=float)
    dims = (4, 4, 1)
    diff = six_separating_surface(one, dims) ^ six_separating_surface(other, dims)
    assert voxel_set(diff) == {(1, 0, 0)}
    assert six_separating_surface(one, dims)[1, 0, 0]
    # The conservative result has it in both: the pixel's corner touches A.
    np.testing.assert_array_equal(conservative_surface(one, dims), conservative_surface(other, dims))
    assert conservative_surface(one, dims)[1, 0, 0]


# ----------------------------------------------------------------------------
# S&S test against the separating-axis test

@settings(max_examples=150, deadline=None)
@given(coords=st.integers(1, 4).flatmap(lambda t: st.lists(st.integers(-16, 80), min_size=9 * t,
                                                           max_size=9 * t)),
       half=st.sampled_from([0.25, 0.375, 0.5, 0.75]))
def test_ss_equals_sat_on_dyadic_triangles(coords, half):
    # Multiples of 1/8 put vertices, edges and faces exactly on voxel planes
    # and centers; all arithmetic of both tests is exact for them (and for
    # these dyadic half-sizes), so they must agree voxel for voxel, touches
    # included.
    tris = np.array(coords, dtype=float).reshape(-1, 3, 3) / 8.0
    dims = (8, 8, 8)
    np.testing.assert_array_equal(conservative_surface(tris, dims, half),
                                  conservative_surface_sat(tris, dims, half))


def test_ss_equals_sat_on_random_triangles():
    # Generic coordinates: both tests round differently, so they may only
    # disagree on ties (none occurred when this was written).
    rng = np.random.default_rng(7)
    dims = (10, 10, 10)
    for scale in (0.3, 2.0, 8.0):
        c = rng.uniform(-1, 11, (150, 1, 3))
        tris = c + rng.normal(0, scale, (150, 3, 3))
        ok, bad = mismatch_is_tie(conservative_surface_sat(tris, dims),
                                  conservative_surface(tris, dims), surface_ties(tris, dims))
        assert ok, bad[:10]


@pytest.mark.parametrize("n", [32, 64])
def test_ss_equals_sat_on_bunny(bunny, n):
    tris, dims, _, _ = fit(bunny, n)
    ref = conservative_surface(tris, dims)
    ok, bad = mismatch_is_tie(conservative_surface_sat(tris, dims), ref, surface_ties(tris, dims))
    assert ok, bad[:10]
    assert ref.sum() > 0


def test_results_do_not_depend_on_vertex_or_triangle_order():
    rng = np.random.default_rng(11)
    tris = np.round(rng.uniform(-1, 9, (60, 3, 3)) * 8) / 8
    shuffled = tris[rng.permutation(len(tris))][:, [2, 0, 1]]
    flipped = tris[:, ::-1]
    dims = (8, 8, 8)
    for f in (*SURFACES.values(), solid):
        ref = f(tris, dims)
        np.testing.assert_array_equal(f(shuffled, dims), ref)
        np.testing.assert_array_equal(f(flipped, dims), ref)


# ----------------------------------------------------------------------------
# 6-separating vs conservative, separability

def test_six_separating_is_subset_of_conservative(bunny):
    rng = np.random.default_rng(3)
    tris = rng.uniform(-1, 9, (200, 3, 3))
    for half in (0.5, 0.5 + TIE_EPS, 0.3):
        assert not (six_separating_surface(tris, (8, 8, 8), half)
                    & ~conservative_surface(tris, (8, 8, 8), half)).any()
    btris, dims, _, _ = fit(bunny, 64)
    thin = six_separating_surface(btris, dims)
    thick = conservative_surface(btris, dims)
    assert not (thin & ~thick).any()
    assert thin.sum() < 0.75 * thick.sum()


@pytest.mark.parametrize("which", ["sphere", "armadillo"])
def test_separability_on_closed_meshes(which, request):
    mesh = request.getfixturevalue(which)
    tris, dims, _, _ = fit(mesh, 32 if which == "sphere" else 64)
    inside = solid(tris, dims)
    assert inside.sum() > 0
    thick = conservative_surface(tris, dims)
    thin = six_separating_surface(tris, dims)
    assert len(separation_leaks(thick, inside, 26)) == 0
    assert len(separation_leaks(thin, inside, 6)) == 0
    # The check has teeth: the 6-separating surface is thin enough for
    # diagonal (26-connected) paths to slip through it.
    assert len(separation_leaks(thin, inside, 26)) > 0


# ----------------------------------------------------------------------------
# solid

@pytest.mark.parametrize("which,n", [("sphere", 24), ("sphere", 37), ("armadillo", 64)])
def test_solid_axes_agree_up_to_ties(which, n, request):
    tris, dims, _, _ = fit(request.getfixturevalue(which), n)
    ties = solid_ties(tris, dims)
    ref = solid(tris, dims, 0)
    assert ref.sum() > 0
    for axis in (1, 2):
        ok, bad = mismatch_is_tie(solid(tris, dims, axis), ref, ties)
        assert ok, bad[:10]


@pytest.mark.parametrize("which", ["sphere", "featuretype"])
def test_solid_matches_winding_number(which, sphere):
    mesh = sphere if which == "sphere" else load_mesh("cad_featuretype.stl")
    tris, dims, _, _ = fit(mesh, 24)
    inside = winding_number(centers(dims), tris).reshape(dims) > 0.5
    assert inside.sum() > 0
    ok, bad = mismatch_is_tie(solid(tris, dims), inside, solid_ties(tris, dims))
    assert ok, bad[:10]


def test_solid_matches_trimesh_contains(sphere):
    pytest.importorskip("rtree", reason="trimesh.Trimesh.contains needs the rtree package")
    tris, dims, origin, h = fit(sphere, 24)
    world = centers(dims) * h + origin
    inside = sphere.contains(world).reshape(dims)
    ok, bad = mismatch_is_tie(solid(tris, dims), inside, solid_ties(tris, dims))
    assert ok, bad[:10]


def test_solid_matches_convex_hull_inequalities():
    # Convex hulls of random points on the half-voxel lattice: vertices sit
    # on voxel centers and planes, and many edges run through centers, the
    # hard cases for the fill rule.  A center is inside a convex polytope iff
    # it satisfies every facet inequality, a test that shares nothing with
    # ray parity; centers on the boundary are ties.
    rng = np.random.default_rng(4)
    dims = (10, 10, 10)
    c = centers(dims)
    for _ in range(10):
        pts = rng.integers(1, 20, (12, 3)) / 2.0
        hull = ConvexHull(pts)
        tris = pts[hull.simplices]
        inside = (c @ hull.equations[:, :3].T + hull.equations[:, 3] < 0).all(axis=1).reshape(dims)
        ties = solid_ties(tris, dims)
        for axis in range(3):
            ok, bad = mismatch_is_tie(solid(tris, dims, axis), inside, ties)
            assert ok, bad[:10]


#: Hulls with a face parallel to x in world space (y + z constant) that is a sliver in
#: voxel space, float64: its vertices leave the plane by rounding (2^-48 in the first).
#: The first, found by the closed-solid fuzz test, has column centers on the sliver's long
#: edge; the second, from a search over such hulls, has centers within rounding of its
#: edges, where only an exact edge sign makes the exact crossing the right one.
PARALLEL_FACE_HULLS = [
    ([(1, .75, 0), (0, 0, -.75), (0, .5, .25), (0, 0, .75), (0, -1, 0)], (17, 29, 42)),
    ([(-.25, -1, 2), (.25, .75, .25), (-.25, 1, 0), (-.875, 1.3, -.3), (.375, -.75, -.25), (.125, .25, .375)],
     (14, 30, 34)),
]


@pytest.mark.parametrize("pts, dims", PARALLEL_FACE_HULLS)
def test_solid_is_exact_on_a_face_parallel_to_the_rays_in_floating_point(pts, dims):
    """A face parallel to the rays only up to rounding: float64 edge functions and a
    crossing divided by a normal component of 1e-14 set voxels 0.05 voxel and more
    outside the hull, along x (far from every tie).  A sign within rounding of an
    edge, and the crossing of a triangle that nearly parallel, are now computed
    exactly; the hull's own inequalities decide every voxel off the ties."""
    hull = trimesh.convex.convex_hull(np.array(pts, float))
    mesh = glvox.load_mesh((hull.vertices, hull.faces), name="hull")
    tris = mesh.triangles_voxel(glvox.grid_for(mesh, dims=dims))
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 1])
    assert 0.0 < abs(n[:, 0]).min() < 1e-12  # the sliver is there, in float64
    inside = np.ones(dims, bool)
    c = centers(dims).reshape(*dims, 3)
    mid = tris.reshape(-1, 3).mean(axis=0)
    for t, nt in zip(tris, n):
        side = np.sign(np.dot(mid - t[0], nt))
        inside &= side * ((c - t[0]) @ nt) > 0.0
    ties = solid_ties(tris, dims)
    for axis in range(3):
        ok, bad = mismatch_is_tie(solid(tris, dims, axis), inside, ties)
        assert ok, (axis, bad[:10])


def test_fill_rule_octahedron_through_centers():
    # Octahedron |x - c|_1 <= 2 with c = (3.5, 3.5, 3.5), a voxel center, in a
    # 7^3 grid: its vertices are voxel centers and every edge runs through
    # centers.  Offsets (a, b, s) of centers from c are integers.  A ray
    # along the axis at offset (b, c) in the other two axes with
    # s = |b| + |c| <= 1 enters at a = -(2 - s) and leaves at 2 - s, through a
    # vertex (s = 0) or an edge shared by two front (back) faces (s = 1),
    # which the top-left rule counts once each; a voxel flips iff its center
    # is beyond the crossing, so the centers a in (-(2-s), 2-s] are set:
    # 4 for the one s = 0 column, 2 for each of the four s = 1 columns.  Rays
    # with s = 2 graze the silhouette edge or vertex: counted 0 or 2 times,
    # nothing set.  Total 4 + 4 * 2 = 12 (7 centers strictly inside plus 5 on
    # the exit side of the surface).
    tris = octahedron_tris((3.5, 3.5, 3.5), 2.0)
    dims = (7, 7, 7)
    for axis in range(3):
        expected = np.zeros(dims, bool)
        u, v = (axis + 1) % 3, (axis + 2) % 3
        for b in range(-2, 3):
            for c in range(-2, 3):
                s = abs(b) + abs(c)
                if s > 1:
                    continue
                for a in range(-(2 - s) + 1, 2 - s + 1):
                    idx = [0, 0, 0]
                    idx[axis], idx[u], idx[v] = 3 + a, 3 + b, 3 + c
                    expected[tuple(idx)] = True
        assert expected.sum() == 12
        np.testing.assert_array_equal(solid(tris, dims, axis), expected)
    # Ties: the 18 centers on the surface (offsets with |a|+|b|+|c| = 2).
    offsets = np.abs(np.indices(dims) - 3).sum(axis=0)
    np.testing.assert_array_equal(solid_ties(tris, dims), offsets == 2)


def test_fill_rule_box_through_centers():
    # Cube [1.5, 5.5]^3 in a 7^3 grid: faces through planes of centers.
    # Along axis 0 the columns are (y, z) centers; the front face x = 1.5
    # projects to the square [1.5, 5.5]^2 whose edges at y = 1.5 (left,
    # inward normal +y) and z = 5.5 (top, inward normal -z) are kept, the
    # others not: columns y in [1.5, 5.5), z in (1.5, 5.5], i.e. j in 1..4,
    # k in 2..5.  The face diagonals are shared and count once.  In each
    # column the crossings at x = 1.5 and 5.5 flip voxels whose centers are
    # beyond them: i in 2..5.  For axis 1 (u, v) = (z, x), for axis 2 (x, y).
    tris = box_tris(1.5, 5.5)
    dims = (7, 7, 7)
    slices = {0: np.s_[2:6, 1:5, 2:6], 1: np.s_[2:6, 2:6, 1:5], 2: np.s_[1:5, 2:6, 2:6]}
    for axis, sl in slices.items():
        expected = np.zeros(dims, bool)
        expected[sl] = True
        np.testing.assert_array_equal(solid(tris, dims, axis), expected)
    # Ties: the 5^3 - 3^3 = 98 centers on the surface.
    on_surface = np.zeros(dims, bool)
    on_surface[1:6, 1:6, 1:6] = True
    on_surface[2:5, 2:5, 2:5] = False
    np.testing.assert_array_equal(solid_ties(tris, dims), on_surface)


def test_clipping_matches_a_larger_grid(sphere):
    # A closed mesh sticking out of the grid on every side: the small grid
    # must equal the matching block of a grid large enough to hold it all
    # (columns entering from below flip entirely: q_bar < 0).  The shift is
    # an integer, so voxel-space coordinates stay exact.
    tris, _, _, _ = fit(sphere, 12)
    small = (9, 8, 7)
    tris = tris - np.array([1.0, 3.0, 2.0])     # now spans about [-1, 11] x [-3, 9] x [-2, 10]
    big_tris = tris + 4.0
    big = (20, 20, 20)
    block = np.s_[4:4 + small[0], 4:4 + small[1], 4:4 + small[2]]
    for f in (*SURFACES.values(), solid, lambda t, d: solid(t, d, 1), lambda t, d: solid(t, d, 2),
              surface_ties, solid_ties):
        np.testing.assert_array_equal(f(tris, small), f(big_tris, big)[block])
    assert solid(tris, small).any() and not solid(tris, small).all()


# ----------------------------------------------------------------------------
# tie sets

#: A triangle in the plane x = 3 + 1e-5, generic in y and z: closer to the
#: voxel plane x = 3 than rounding can tell apart, farther than nothing.
OFF_PLANE = np.array([[[3.00001, 0.3, 0.4], [3.00001, 4.6, 0.7], [3.00001, 1.2, 4.8]]])


def test_surface_ties_of_a_triangle_near_and_on_a_voxel_plane():
    # Near the plane: the voxel layers 2 and 3 are within 1e-5 of touching it,
    # so with the box shrunk along x by eps nothing is set and grown by eps
    # both layers are: all ties, all in layers 2, 3, the touched set of the
    # triangle moved onto the plane.
    tri = OFF_PLANE
    dims = (6, 6, 6)
    on = snap_to_planes(tri)
    assert (on[..., 0] == 3.0).all() and (on[..., 1:] == tri[..., 1:]).all()
    ties = surface_ties(tri, dims)
    np.testing.assert_array_equal(ties, conservative_surface(on, dims))
    assert {i for i, _, _ in voxel_set(ties)} == {2, 3}
    # Its yz projection is the same for both layers.
    np.testing.assert_array_equal(ties[2], ties[3])
    np.testing.assert_array_equal(surface_ties(tri, dims, "6sep"), six_separating_surface(on, dims))
    # Snapped onto the plane (what every method sees), both layers touch it
    # exactly and no tie remains: the face keeps both layers for everyone.
    # Only its slanted edges (off the snap planes) stay movable by rounding.
    half, edge = rounding_perturbation(on)
    assert not half.any() and edge[0, 0].all() and not edge[0, 1:].any()
    assert not surface_ties(on, dims).any() and not surface_ties(on, dims, "6sep").any()
    # Moved off the plane, no ties remain.
    assert not surface_ties(tri + [0.25, 0, 0], dims).any()


def test_mismatch_is_tie_reports_unexplained_voxels():
    tri = OFF_PLANE
    dims = (6, 6, 6)
    ref = conservative_surface(tri, dims)
    ties = surface_ties(tri, dims)
    ok, bad = mismatch_is_tie(ref, ref, ties)
    assert ok and bad.shape == (0, 3)
    # Dropping a tie voxel is explained ...
    inside = tuple(np.argwhere(ties)[0])
    result = ref.copy()
    result[inside] = False
    assert mismatch_is_tie(result, ref, ties)[0]
    # ... setting a voxel far from the triangle is not.
    result[0, 5, 5] = True
    result[5, 0, 5] = True
    ok, bad = mismatch_is_tie(result, ref, ties)
    assert not ok
    np.testing.assert_array_equal(bad, [[0, 5, 5], [5, 0, 5]])


def test_point_triangle_distance_hand_cases():
    tri = np.array([[0.0, 0, 0], [4, 0, 0], [0, 4, 0]])
    p = np.array([
        [1, 1, 3],      # above the interior: plane distance 3
        [-3, -4, 0],    # nearest the vertex (0,0,0): 5
        [2, -1, 2],     # nearest the edge y = 0 at (2,0,0): sqrt(5)
        [3, 3, 0],      # beyond the hypotenuse x + y = 4 in-plane: sqrt(2)
        [1, 1, 0],      # on the triangle
    ], dtype=float)
    expected = [3, 5, np.sqrt(5), np.sqrt(2), 0]
    np.testing.assert_allclose(point_triangle_distance(p, np.repeat(tri[None], len(p), 0)),
                               expected, rtol=0, atol=1e-12)
    segment = np.array([[[0.0, 0, 0], [2, 0, 0], [1, 0, 0]]])
    np.testing.assert_allclose(point_triangle_distance(np.array([[3.0, 0, 1]]), segment), [np.sqrt(2)])


def test_solid_ties_equal_brute_force_distances(sphere):
    # A large eps makes many ties; the candidate search must find exactly the
    # centers a brute-force distance to every triangle finds.
    tris, dims, _, _ = fit(sphere, 12)
    eps = 0.15
    c = centers(dims)
    dist = np.full(len(c), np.inf)
    for t in tris:
        dist = np.minimum(dist, point_triangle_distance(c, np.repeat(t[None], len(c), 0)))
    expected = (dist <= eps).reshape(dims)
    assert 0 < expected.sum() < expected.size
    np.testing.assert_array_equal(solid_ties(tris, dims, eps), expected)


def test_solid_ties_cover_every_flip_under_small_motions(sphere):
    # Definition check: moving the mesh by at most eps flips only tie voxels,
    # and with eps this large some voxels do flip.
    tris, dims, _, _ = fit(sphere, 16)
    eps = 0.1
    ties = solid_ties(tris, dims, eps)
    ref = solid(tris, dims)
    rng = np.random.default_rng(2)
    flipped = np.zeros(dims, bool)
    for _ in range(12):
        d = rng.normal(size=3)
        d *= eps * rng.uniform(0.5, 1.0) / np.linalg.norm(d)
        moved = solid(tris + d, dims)
        assert mismatch_is_tie(moved, ref, ties)[0]
        flipped |= moved != ref
    assert flipped.any()


# ----------------------------------------------------------------------------
# orientation ties (nearly edge-on projections)

def test_orientation_ambiguity_is_flagged_only_for_edge_on_projections():
    wall = np.array([[[1.2, 1.3, 0.5], [1.2, 1.3, 5.5], [1.9, 3.4, 5.5]]])  # vertical: xy projection is a segment
    tilted = np.array([[[1.2, 1.3, 0.5], [4.2, 1.9, 2.5], [1.9, 3.4, 5.5]]])
    amb = orientation_ambiguous(np.concatenate([wall, tilted]), TIE_EPS)
    assert amb.tolist() == [[False, False, True], [False, False, False]]  # planes yz, zx, xy


def test_orientation_ties_cover_a_flip_of_a_sliver():
    """A sliver seen edge-on in xy whose short edge decides a voxel: the verdict
    with the projection flipped differs, and exactly those voxels are ties."""
    sliver = np.array([[[1.9722, 3.0474, 2.5], [1.7049, 2.9698, 0.98], [1.97221, 3.0474, 0.98]]])
    flip = np.zeros((1, 3), bool)
    flip[0, 2] = True
    for f, crit in ((six_separating_surface, "6sep"), (conservative_surface, "conservative")):
        base = f(sliver, (5, 5, 5))
        flipped = f(sliver, (5, 5, 5), flip=flip)
        ties = surface_ties(sliver, (5, 5, 5), crit)
        assert not ((base ^ flipped) & ~ties).any()
    assert (six_separating_surface(sliver, (5, 5, 5)) ^ six_separating_surface(sliver, (5, 5, 5), flip=flip)).any()


def test_short_projected_edges_make_6sep_ties_and_moving_them_changes_only_ties():
    """An edge of 2e-5 voxel (from depth_cycloidal_drive.ply at 128^3): moving
    its end points by float32 rounding turns it and changes 6-sep verdicts,
    all of them ties; the conservative verdicts do not depend on it."""
    tri = np.array([[[3.9444945317456868, 6.09485665599304, 25.0309510063754],
                     [3.944516911290884, 6.09486072500125, 7.96429763180225],
                     [4.5013647548929585, 6.10640043230669, 25.0309510063754]]])
    dims = (9, 12, 30)
    assert short_edges(tri, dims)[0, 2]  # its xy projection has the short edge
    rng = np.random.default_rng(5)
    m = float32_motion(dims) / 2
    for f, crit in ((six_separating_surface, "6sep"), (conservative_surface, "conservative")):
        ties = surface_ties(tri, dims, crit)
        base = f(tri, dims)
        changed = np.zeros(dims, bool)
        for _ in range(100):
            changed |= base ^ f(tri + rng.uniform(-m, m, tri.shape), dims)
        assert not (changed & ~ties).any(), crit
        if crit == "6sep":
            assert changed.any()  # the check has teeth
