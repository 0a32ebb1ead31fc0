"""Eisemann & Decoret XOR solid and OR surface voxelization (raster pipeline).

``eisemann-solid`` is checked against ``reference-solid`` with every mismatch a
proven tie (the voxel's center within TIE_EPS of the surface); none is
tolerated by count.  ``eisemann-surface`` samples the triangles at the column
centers, so it must be a subset of ``reference-conservative`` (up to its ties)
and, exactly, the voxels holding the crossings of column centers, which an
independent numpy model below brackets.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import trimesh
from conftest import SHARED_MESHES

import glvox
from glvox.errors import CapabilityError, LimitError, MethodError, NotWatertightError, NotWatertightWarning
from glvox.gl.timing import StageTimer
from glvox.gpu.buffers import buffer_pool, object_cache
from glvox.grid import GridSpec
from glvox.mesh import load_mesh
from glvox.methods import run_method
from glvox.methods.eisemann import passes as eisemann_passes
from glvox.metrics import check_against_reference, tie_set
from glvox.reference import TIE_EPS
from glvox.study.selftest import TIE_HULL, TIE_HULL_DIMS
from glvox.testing import harness, tie_probe
from glvox.testing.slices import off_slices

WATERTIGHT = ("cad_fandisk.off", "cad_featuretype.stl", "cad_rocker_arm.obj", "cad_wingnut.obj",
              "depth_reduced_diamond_lattice.stl", "stanford_armadillo_libigl_86k.obj")


def check_solid(mesh, spec, axes=(2,), allow_open=False, **opts):
    """eisemann-solid along each axis against the reference, ties proven."""
    ref = run_method("reference-solid", mesh, spec, allow_open=True)
    ties = tie_set("reference-solid", mesh, spec)
    out = {}
    for axis in axes:
        g = run_method("eisemann-solid", mesh, spec, axis=axis, allow_open=allow_open, **opts)
        c = check_against_reference(g, mesh, reference_grid=ref, ties=ties)
        assert c.ok, f"{mesh.name} {spec.dims} axis {axis} {opts}: {c.describe()}"
        out[axis] = g
    return out, ref


def check_surface_subset(mesh, spec, axes=(2,)):
    """eisemann-surface sets no voxel outside the conservative surface (up to its ties)."""
    ref = run_method("reference-conservative", mesh, spec).dense()
    ties = tie_set("reference-conservative", mesh, spec)
    out = {}
    for axis in axes:
        g = run_method("eisemann-surface", mesh, spec, axis=axis)
        extra = g.dense() & ~ref
        bad = np.argwhere(extra & ~ties)
        assert len(bad) == 0, (f"{mesh.name} {spec.dims} axis {axis}: {len(bad)} voxels outside the "
                               f"conservative surface and its ties, first {bad[:5].tolist()}")
        assert g.count > 0
        check_slices_formulation(g.dense(), mesh, spec, axis)
        out[axis] = g
    return out, ref


def check_slices_formulation(got, mesh, spec, axis):
    """eisemann-surface is its CPU formulation (glvox.testing.slices: the slice of each covered
    column center's crossing) on the vertices the GPU sees, voxel for voxel, up to what
    off_slices excuses (rounding near edge-on triangles, slice boundaries and projected edges)."""
    diff = off_slices(got, mesh, spec, axis)
    assert not diff.any(), f"{mesh.name} axis {axis}: {int(diff.sum())} voxels off eisemann_slices, " \
        f"first {np.argwhere(diff)[:3].tolist()}"


def box_mesh(lo, hi):
    box = trimesh.creation.box(bounds=[lo, hi])
    return load_mesh((box.vertices, box.faces), name="box")


# -- hand-worked ---------------------------------------------------------------

BOX_LO, BOX_HI = (1.2, 0.3, 2.6), (5.7, 4.4, 6.1)
UNIT = GridSpec((8, 8, 8), (0.0, 0.0, 0.0), 1.0)


def expected_box_solid():
    """Centers i + 0.5 strictly inside (1.2, 5.7) x (0.3, 4.4) x (2.6, 6.1):
    i = 1..5, j = 0..3, k = 3..5."""
    occ = np.zeros(UNIT.dims, bool)
    occ[1:6, 0:4, 3:6] = True
    return occ


def expected_box_surface(axis):
    """One voxel per covered column and face: the slice floor(q) of each face."""
    occ = np.zeros(UNIT.dims, bool)
    if axis == 2:    # faces z = 2.6, 6.1 over columns i = 1..5, j = 0..3
        occ[1:6, 0:4, [2, 6]] = True
    elif axis == 0:  # faces x = 1.2, 5.7 over columns j = 0..3, k = 3..5
        occ[[1, 5], 0:4, 3:6] = True
    else:            # faces y = 0.3, 4.4 over columns k = 3..5, i = 1..5
        occ[1:6, [0, 4], 3:6] = True
    return occ


@pytest.mark.parametrize("coverage", eisemann_passes.COVERAGES)
@pytest.mark.parametrize("masks", eisemann_passes.MASKS)
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_hand_worked_box(gl_context, axis, masks, coverage):
    mesh = box_mesh(BOX_LO, BOX_HI)
    opts = {"axis": axis, "masks": masks, "coverage": coverage}
    solid = run_method("eisemann-solid", mesh, UNIT, debug=True, **opts)
    assert np.array_equal(solid.dense(), expected_box_solid())
    surface = run_method("eisemann-surface", mesh, UNIT, debug=True, **opts)
    assert np.array_equal(surface.dense(), expected_box_surface(axis))


def test_mask_table_by_hand():
    xor = eisemann_passes.mask_table("xor", 8)
    assert xor.shape == (1025, 8, 4) and xor.dtype == np.uint32
    assert (xor[0] == 0xFFFFFFFF).all() and (xor[1024] == 0).all()
    # row 200: slices 200..1023 -> target 1 (128..255), channel 2 (192..223), bits 8..31
    assert xor[200, 1, 2] == 0xFFFFFF00 and (xor[200, 1, :2] == 0).all() and xor[200, 1, 3] == 0xFFFFFFFF
    assert (xor[200, 2:] == 0xFFFFFFFF).all() and (xor[200, 0] == 0).all()
    orr = eisemann_passes.mask_table("or", 2)
    assert orr.shape == (257, 2, 4)
    assert orr[37, 0, 1] == 1 << 5 and np.count_nonzero(orr[37]) == 1 and not orr[256].any()


# -- against the exact references ------------------------------------------------


@pytest.mark.parametrize("name", WATERTIGHT)
def test_watertight_shared_meshes(gl_context, shared_mesh, name):
    mesh = load_mesh(shared_mesh(name))
    assert mesh.watertight
    check_solid(mesh, glvox.grid_for(mesh, 64))


@pytest.mark.slow
@pytest.mark.parametrize("n", [128, 256])
@pytest.mark.parametrize("name", WATERTIGHT)
def test_watertight_shared_meshes_large(gl_context, shared_mesh, name, n):
    mesh = load_mesh(shared_mesh(name))
    check_solid(mesh, glvox.grid_for(mesh, n), axes=(0, 1, 2))


@pytest.mark.parametrize("name", SHARED_MESHES)
def test_surface_is_a_subset_of_the_conservative_surface(gl_context, shared_mesh, name):
    mesh = load_mesh(shared_mesh(name))
    check_surface_subset(mesh, glvox.grid_for(mesh, 64))


@pytest.mark.slow
@pytest.mark.parametrize("name", SHARED_MESHES)
def test_surface_is_a_subset_of_the_conservative_surface_large(gl_context, shared_mesh, name):
    mesh = load_mesh(shared_mesh(name))
    check_surface_subset(mesh, glvox.grid_for(mesh, 128), axes=(0, 1, 2))


def crumpled_sphere():
    """A closed sphere with jittered vertices: slivers and sharp corners of every shape."""
    m = trimesh.creation.icosphere(3, radius=1.0)
    rng = np.random.default_rng(5)
    v = m.vertices * (1.0 + 0.25 * rng.uniform(-1, 1, (len(m.vertices), 1)))
    return trimesh.Trimesh(v + 0.05 * rng.normal(size=v.shape), m.faces, process=False)


def fan_cylinder():
    """Caps fanned from their centers into 300 needles (corner angles of 1.2 degrees),
    tilted so no face is axis-aligned."""
    c = trimesh.creation.cylinder(radius=1.0, height=1.5, sections=300)
    c.apply_transform(trimesh.transformations.euler_matrix(0.2, 0.3, 0.1))
    return c


GENERATED = {
    "sphere": lambda: trimesh.creation.icosphere(4, radius=1.0),
    "torus": lambda: trimesh.creation.torus(1.0, 0.35),
    "rotated-box": lambda: trimesh.creation.box(
        extents=(2.0, 1.3, 0.7), transform=trimesh.transformations.euler_matrix(0.3, 0.5, 0.7)),
    "crumpled-sphere": crumpled_sphere,
    "fan-cylinder": fan_cylinder,
}


@pytest.mark.parametrize("shape", sorted(GENERATED))
def test_generated_solids(gl_context, shape):
    m = GENERATED[shape]()
    mesh = load_mesh((m.vertices, m.faces), name=shape)
    assert mesh.watertight
    check_solid(mesh, glvox.grid_for(mesh, 64), axes=(0, 1, 2))


@pytest.mark.slow
@pytest.mark.parametrize("n", [128, 256])
@pytest.mark.parametrize("shape", sorted(GENERATED))
def test_generated_solids_large(gl_context, shape, n):
    m = GENERATED[shape]()
    mesh = load_mesh((m.vertices, m.faces), name=shape)
    check_solid(mesh, glvox.grid_for(mesh, n), axes=(0, 1, 2))


def test_a_face_along_the_axis_through_column_centers(gl_context):
    """A hull the slow fuzz found: face [1, 3, 2] is parallel to z, and at 33 x 59 x 22 its
    projection, a segment, runs exactly through column centers, (14.5, 21.5) among them,
    collinear with edges of three other faces.  The float32 upload makes that face a
    sliver 1e-14 voxel wide.  With the edge functions in double, their rounding put
    centers inside all three of its edges and outside its neighbours' (26 voxels far from
    the surface flipped), and the plane's crossing formula in double put it 3 voxels below
    the face.  With coverage in integers and the barycentric crossing: reference-solid up to
    ties, along every axis (along x and y the face is an ordinary steep one)."""
    mesh = load_mesh(TIE_HULL, name="edge-on hull")
    spec = glvox.grid_for(mesh, dims=TIE_HULL_DIMS)
    assert np.ptp(TIE_HULL[0][TIE_HULL[1][4]][:, :2] @ [3, 2]) == 0  # along z: its xy on one line
    (v1, v3, v2) = mesh.triangles_voxel(spec)[4][:, :2]
    d = v2 - v3
    on = [(x + 0.5, y + 0.5) for x in range(33) for y in range(59)
          if abs(d[0] * (y + 0.5 - v3[1]) - d[1] * (x + 0.5 - v3[0])) < 1e-9]
    assert (14.5, 21.5) in on and len(on) >= 5
    check_solid(mesh, spec, axes=(0, 1, 2))


def test_the_determinant_is_exact(gl_context):
    """eisemann/column.glsl's eis_det, a b - c d from imulExtended's 64-bit products: its
    sign exactly and its value rounded once to a double, against Python's integers on
    operands up to 2^30 in magnitude: random ones, and pairs of products equal or 1 apart,
    or straddling a multiple of 2^32 (equal high words, low words on both sides of 2^31),
    where a difference without the low words' borrow, or the products in double, gets
    the sign wrong."""
    rng = np.random.default_rng(7)
    quads = [rng.integers(-(2 ** 30), 2 ** 30, 4) for _ in range(2000)]
    for _ in range(2000):
        a, b, c = (int(x) for x in rng.integers(2 ** 20, 2 ** 30, 3) * rng.choice([-1, 1], 3))
        target = a * b + int(rng.choice([0, 1, -1, 2 ** 31, -(2 ** 31), 2 ** 31 - 1, 5 * 2 ** 32]))
        d = target // c
        quads += [np.array([a, b, c, d + k]) for k in (-1, 0, 1) if abs(d + k) < 2 ** 30]
        quads.append(np.array([a, b // 2 * 2, b // 2, 2 * a]) if abs(a) < 2 ** 29 else np.array([a, b, b, a]))
    q = np.array(quads, np.int64)
    exact = [x * y - z * w for x, y, z, w in q.tolist()]
    got = harness.run_compute(gl_context, "testing/det_sign.comp", -(-len(q) // 64), read=["DetOut", "DetValue"],
                              buffers={"DetIn": q.astype(np.int32), "DetOut": (len(q), np.int32),
                                       "DetValue": (len(q), np.float64)}, uniforms={"u_n": len(q)})
    want = np.sign(np.array(exact))
    straddle = [(x * y) >> 32 == (z * w) >> 32 and ((x * y) >> 31 & 1) != ((z * w) >> 31 & 1)
                for x, y, z, w in q.tolist()]
    assert sum(straddle) > 100 and (want == 0).sum() > 100
    assert np.array_equal(got["DetOut"], want), np.flatnonzero(got["DetOut"] != want)[:5]
    assert np.array_equal(got["DetValue"], np.array([float(e) for e in exact]))


def test_the_crossing_of_a_sliver_stays_in_its_section(gl_context):
    """A sliver in the fixed point (2^-20 voxel) as thin as it gets: its long edge A -> C
    runs through the column center c, its midpoint, along w = (F40, F41) units (consecutive
    Fibonacci numbers, coprime), and B - A = (F39, F40), so its projected area is 2^-40
    voxel^2 (F39 F41 - F40^2 = 1).  The plane's crossing formula in double is voxels off
    there (in numpy 21.3, 53.1 or NaN by the vertex order, where the face holds c at
    33.5).  Any crossing between the one on A -> C (33.5) and the one on B -> C at c's
    position along the edge is a tie (the face's section there lies within 1e-11 voxel of
    the column); the barycentric one from the exact edge functions is 33.5 itself."""
    f39, f40, f41 = 63245986, 102334155, 165580141
    bits = 20
    c = np.array([300.5, 300.5])
    w = np.array([f40, f41]) / 2.0 ** bits
    a, cc = np.r_[c - w, 5.3], np.r_[c + w, 61.7]
    b = np.r_[c - w + np.array([f39, f40]) / 2.0 ** bits, 37.1]
    d = cc[:2] - a[:2]
    t = float(np.dot(c - b[:2], d) / np.dot(cc[:2] - b[:2], d))  # c's position on B -> C
    first = (int(np.floor((a[2] + cc[2]) / 2 + 0.5)), int(np.floor(b[2] + t * (cc[2] - b[2]) + 0.5)))
    assert first == (34, 44)
    for order in ((a, b, cc), (cc, b, a), (b, cc, a), (b, a, cc)):
        tris = np.array([order])
        for stage in ("compute", "fragment"):
            words = tie_probe.run_probe(gl_context, "eis", stage, tris, c[None].astype(np.float32), bits)[0]
            assert words[12] == 1 and np.int32(words[13]) == first[0], (stage, words.tolist())


def _setup_records(gl_context, tri, dims):
    """eisemann/setup.comp (XOR, exact coverage, axis z, F = 20) on one triangle (3, 3) in
    both windings: its two EisSetup records as 12 int32 words each (box_lo, box_hi,
    slices, then the corners' float bits)."""
    return [harness.run_compute(
        gl_context, "eisemann/setup.comp", 1, read=["EisSetups"],
        buffers={"EisVox": tri[order].reshape(-1), "EisFaces": np.arange(3, dtype=np.uint32),
                 "EisSetups": (12, np.int32)},
        uniforms={"u_triangles": 1, "u_dims": dims, "u_eis_fix_bits": 20},
        defines={"EIS_AXIS": 2, "EIS_OP": 0, "EIS_COVERAGE": 0, "EIS_TRACE": 0})["EisSetups"]
        for order in ([0, 1, 2], [2, 1, 0])]


def test_the_drawn_proxy_of_a_sliver_holds_it(gl_context):
    """The setup pass (eisemann/setup.comp) draws each triangle grown by 1/16 pixel, so that
    GL's rasterizer, whatever its snap (1/32 pixel at worst), makes a fragment over every
    center the triangle covers: a column center on the triangle lies in the drawn one with
    1/32 to spare.  A sliver of the fixed point (edges along consecutive Fibonacci vectors,
    2^-20 voxel units) has tips so sharp that their edges' unit normals a, b sum to exactly
    zero in double.  The miter's test of |a + b| against 1 + a.b, both zero, took such a tip
    for a gentle corner and left it unmoved: the center at its tip A lay 0.11 outside the
    drawn triangle.  Tested on 1 + a.b alone, the sliver falls back to a triangle around
    its bounding box."""
    f39, f40, f41 = 63245986, 102334155, 165580141
    a = np.array([300.5, 300.5])
    b = a + 2 * np.array([f39, f40]) / 2.0 ** 20
    c = a + (2 * np.array([f40, f41]) + [f39, f40]) / 2.0 ** 20
    tri = np.array([np.r_[a, 5.3], np.r_[b, 37.1], np.r_[c, 61.7]])
    for got in _setup_records(gl_context, tri, (1024, 1024, 64)):
        corner = got[6:12].view(np.float32).reshape(3, 2).astype(np.float64)
        edge, to_a = np.roll(corner, -1, axis=0) - corner, a - corner
        inside = (edge[:, 0] * to_a[:, 1] - edge[:, 1] * to_a[:, 0]) / np.linalg.norm(edge, axis=1)
        assert (inside * np.sign(inside.sum())).min() >= 1 / 32, corner.tolist()


def test_the_setup_culls_a_small_box_whose_centers_the_triangle_misses(gl_context):
    """A fine mesh has many triangles whose bounding box holds a column center that the
    triangle itself misses; the setup pass (eisemann/setup.comp) gives such a triangle an
    empty box, so no vertex of it reaches the rasterizer, where its box holds at most
    EIS_CULL_CENTERS (4) centers.  Hand-worked: the right triangle with legs from
    (10.125, 10.125) to x + y = 20.875 lies short of the center (10.5, 10.5) of its box:
    culled; with legs to x + y = 21.125 it covers that center: kept, box (10, 10)."""
    def setup(legs_end):
        lo, hi = 10.125, legs_end - 10.125
        tri = np.array([[lo, lo, 5.0], [hi, lo, 7.0], [lo, hi, 9.0]])
        return [got[:4].tolist() for got in _setup_records(gl_context, tri, (64, 64, 64))]

    for box_lo_x, box_lo_y, box_hi_x, box_hi_y in setup(20.875):
        assert box_hi_x < box_lo_x or box_hi_y < box_lo_y  # empty: culled
    assert setup(21.125) == [[10, 10, 10, 10]] * 2


def test_far_from_the_origin_and_non_cubic(gl_context, shared_mesh):
    """Vertices near 1e5 keep their precision (uploaded relative to the anchor);
    a non-cubic grid whose sides are not multiples of 32 exercises every pack path."""
    m = fan_cylinder()
    mesh = load_mesh((m.vertices * 3.0 + [1e5, -2e5, 3e5], m.faces), name="far-cylinder")
    check_solid(mesh, glvox.grid_for(mesh, dims=(50, 37, 45)), axes=(0, 1, 2))
    arm = load_mesh(shared_mesh("stanford_armadillo_libigl_86k.obj"))
    check_solid(arm, glvox.grid_for(arm, dims=(100, 70, 90)), axes=(0, 1, 2))


# -- the surface, exactly --------------------------------------------------------


def surface_bracket(tris, dims, axis, m=TIE_EPS):
    """An independent numpy model of the OR surface: the voxel floor(q) of every
    crossing of a column center with a triangle, bracketed against rounding.

    ``sure``: crossings whose center lies inside the projected triangle by more
    than ``m`` and whose q is more than ``m`` from an integer; ``maybe``: every
    voxel a crossing could reach when the center moves by ``m`` across the
    edges and q by ``m`` (1 + |grad q|).  The GPU's mesh is the float64 one
    moved by less than ``m``, so its result must lie between them.
    """
    u, v = (axis + 1) % 3, (axis + 2) % 3
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    keep = n[:, axis] != 0.0
    tris, n = tris[keep], n[keep]
    lo, hi = tris.min(1), tris.max(1)
    i0 = np.maximum(np.ceil(lo[:, u] - 0.5 - m), 0).astype(int)
    i1 = np.minimum(np.floor(hi[:, u] - 0.5 + m), dims[u] - 1).astype(int)
    j0 = np.maximum(np.ceil(lo[:, v] - 0.5 - m), 0).astype(int)
    j1 = np.minimum(np.floor(hi[:, v] - 0.5 + m), dims[v] - 1).astype(int)
    cu, cv = np.maximum(i1 - i0 + 1, 0), np.maximum(j1 - j0 + 1, 0)
    t = np.repeat(np.arange(len(tris)), cu * cv)
    local = np.arange(len(t)) - np.repeat(np.cumsum(cu * cv) - cu * cv, cu * cv)
    pu = i0[t] + local // cv[t] + 0.5
    pv = j0[t] + local % cv[t] + 0.5
    sgn = np.sign(n[t, axis])
    dist = np.full(len(t), np.inf)
    for e in range(3):
        a, b = tris[t, e], tris[t, (e + 1) % 3]
        eu, ev = b[:, u] - a[:, u], b[:, v] - a[:, v]
        length = np.hypot(eu, ev)
        f = (eu * (pv - a[:, v]) - ev * (pu - a[:, u])) * sgn
        dist = np.minimum(dist, np.where(length > 0, f / np.where(length > 0, length, 1), -np.inf))
    v0, nt = tris[t, 0], n[t]
    q = v0[:, axis] + (nt[:, u] * (v0[:, u] - pu) + nt[:, v] * (v0[:, v] - pv)) / nt[:, axis]
    q = np.clip(q, lo[t, axis], hi[t, axis])
    slack = m * (1.0 + np.hypot(nt[:, u], nt[:, v]) / np.abs(nt[:, axis]))
    sure = np.zeros(dims, bool)
    maybe = np.zeros(dims, bool)

    def put(out, sel, k):
        ok = sel & (k >= 0) & (k < dims[axis])
        idx = np.zeros((3, int(ok.sum())), int)
        idx[axis], idx[u], idx[v] = k[ok], (pu[ok] - 0.5).astype(int), (pv[ok] - 0.5).astype(int)
        out[tuple(idx)] = True

    put(sure, (dist > m) & (np.floor(q - m) == np.floor(q + m)), np.floor(q).astype(int))
    klo, khi = np.floor(q - slack).astype(int), np.floor(q + slack).astype(int)
    for d in range(int((khi - klo).max(initial=0)) + 1):
        put(maybe, (dist >= -m) & (klo + d <= khi), klo + d)
    return sure, maybe


@pytest.mark.parametrize("shape", ["sphere", "crumpled-sphere", "fan-cylinder"])
def test_surface_is_the_crossings_of_column_centers(gl_context, shape):
    m = GENERATED[shape]()
    mesh = load_mesh((m.vertices, m.faces), name=shape)
    spec = glvox.grid_for(mesh, dims=(60, 47, 53))
    tris = mesh.triangles_voxel(spec)
    for axis in (0, 1, 2):
        g = run_method("eisemann-surface", mesh, spec, axis=axis).dense()
        sure, maybe = surface_bracket(tris, spec.dims, axis)
        assert sure.sum() > 0.9 * maybe.sum()  # the bracket is tight
        assert not (sure & ~g).any(), f"{shape} axis {axis}: {np.argwhere(sure & ~g)[:5].tolist()} missing"
        assert not (g & ~maybe).any(), f"{shape} axis {axis}: {np.argwhere(g & ~maybe)[:5].tolist()} extra"


def test_surface_takes_one_voxel_per_column_of_a_steep_plane(gl_context):
    """Eisemann & Decoret 2006 is not conservative: a plane at 72 degrees to the
    image crosses ~3 voxels per column and the OR pass keeps one of them."""
    v = np.array([[1.3, 1.2, 2.0], [6.7, 1.2, 2.0 + 3 * 5.4], [6.7, 6.6, 2.0 + 3 * 5.4], [1.3, 6.6, 2.0]])
    mesh = load_mesh((v, np.array([[0, 1, 2], [0, 2, 3]])), name="steep-plane")
    spec = GridSpec((8, 8, 24), (0.0, 0.0, 0.0), 1.0)
    g = run_method("eisemann-surface", mesh, spec).dense()
    # columns with centers in (1.3, 6.7) x (1.2, 6.6): i = 1..6, j = 1..6, one voxel each
    per_column = g.sum(axis=2)
    assert (per_column[1:7, 1:7] == 1).all() and per_column.sum() == 36
    i = np.arange(1, 7)
    assert (np.argmax(g[1:7, 3], axis=1) == np.floor(2.0 + 3 * (i + 0.5 - 1.3))).all()
    cons = run_method("reference-conservative", mesh, spec).dense()
    assert not (g & ~cons).any() and cons.sum() > 3 * g.sum()


# -- passes, tiles, limits -------------------------------------------------------


def test_deep_grids_take_a_pass_per_1024_slices(gl_context):
    c = trimesh.creation.cylinder(radius=3.0, height=2300.0, sections=16)
    c.apply_transform(trimesh.transformations.rotation_matrix(0.004, [1, 0.3, 0]))
    mesh = load_mesh((c.vertices, c.faces), name="long-cylinder")
    spec = glvox.grid_for(mesh, voxel_size=1.0, padding=1)
    assert spec.dims[2] > 2048
    out, _ = check_solid(mesh, spec, axes=(2, 0))
    assert out[2].run.stats["passes"] == 3 and out[2].run.stats["slices_per_pass"] == 1024
    assert out[0].run.stats["passes"] == 1
    check_surface_subset(mesh, spec)


def test_fewer_targets_more_passes_same_words(gl_context):
    """render_slice_masks with 1 or 3 targets (128 or 384 slices per pass) packs
    the same words as with 8, along every axis, for XOR and OR, and counts them."""
    m = trimesh.creation.torus(1.0, 0.35)
    mesh = load_mesh((m.vertices, m.faces), name="torus")
    spec = glvox.grid_for(mesh, dims=(40, 36, 300))
    for op in ("xor", "or"):
        for axis in (0, 1, 2):
            words = {}
            for targets in (8, 3, 1):
                timer = StageTimer(gl_context)
                render = eisemann_passes.SliceRender(op, axis=axis, targets=targets)
                buf, count = eisemann_passes.render_slice_masks(gl_context, mesh, spec, render, timer=timer)
                words[targets] = np.frombuffer(buf.read(size=spec.n_words * 4), "<u4").copy()
                # the pack passes' count is the words' over every pass
                voxels = int(np.frombuffer(count.read(size=4), "<u4")[0])
                assert voxels == int(np.bitwise_count(words[targets]).sum()), (op, axis, targets)
                slices = 128 * targets
                assert timer.stats["passes"] == -(-spec.dims[axis] // slices)
            assert words[8].any()
            assert np.array_equal(words[8], words[3]) and np.array_equal(words[8], words[1]), (op, axis)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_tiling_at_a_forced_limit_gives_identical_results(gl_context, axis):
    """At a forced tile limit of 64 pixels: a 64-column grid is one tile, a
    65..100-column grid several; every tiling equals the untiled render."""
    m = crumpled_sphere()
    mesh = load_mesh((m.vertices, m.faces), name="crumpled")
    specs = [glvox.grid_for(mesh, dims=(64, 64, 64)), glvox.grid_for(mesh, dims=(100, 65, 90))]
    free = [(run_method("eisemann-solid", mesh, s, axis=axis),
             run_method("eisemann-surface", mesh, s, axis=axis)) for s in specs]
    for spec, (solid, surface) in zip(specs, free):
        n_u, n_v = spec.dims[(axis + 1) % 3], spec.dims[(axis + 2) % 3]
        g = run_method("eisemann-solid", mesh, spec, axis=axis, tile=64)
        assert g.run.stats["tile_limit"] == 64
        assert g.run.stats["tiles"] == [-(-n_u // 64), -(-n_v // 64)]
        assert g.equal(solid)
        assert run_method("eisemann-surface", mesh, spec, axis=axis, tile=64).equal(surface)
    assert run_method("eisemann-solid", mesh, specs[1], axis=axis, tile=64).run.stats["draws"] > 1
    # rounded down to whole words
    assert run_method("eisemann-solid", mesh, specs[1], axis=axis, tile=40).equal(free[1][0])
    with pytest.raises(LimitError, match=r"tiles of at least 32 x 32 pixels, but option tile is 16"):
        run_method("eisemann-solid", mesh, specs[0], axis=axis, tile=16)


def test_grid_over_the_ssbo_limit_is_refused(ssbo_limit):
    limit = ssbo_limit
    nz = (limit * 8 // (1024 * 1024)) + 1
    spec = GridSpec((1024, 1024, nz), (0, 0, 0), 1.0)
    if spec.n_voxels > glvox.grid.MAX_VOXELS:
        pytest.skip(f"GL_MAX_SHADER_STORAGE_BLOCK_SIZE is {limit}: no dense grid exceeds it")
    with pytest.raises(LimitError, match=r"bit grid needs a .* MiB shader storage buffer, over this "
                                         r"context's GL_MAX_SHADER_STORAGE_BLOCK_SIZE"):
        run_method("eisemann-solid", load_mesh("gen:box"), spec)


def test_bad_arguments_are_refused(gl_context):
    mesh = load_mesh("gen:box")
    spec = glvox.grid_for(mesh, 16)
    with pytest.raises(MethodError, match=r"option masks must be one of \['bits', 'texture'\], got 'lut'"):
        run_method("eisemann-solid", mesh, spec, masks="lut")
    with pytest.raises(MethodError, match=r"option coverage must be one of"):
        run_method("eisemann-surface", mesh, spec, coverage="conservative")
    with pytest.raises(MethodError, match=r"option tile must be 0 \(the context's limit\) or a positive number "
                                          r"of pixels, got -1"):
        run_method("eisemann-surface", mesh, spec, tile=-1)
    timer = StageTimer(gl_context)
    with pytest.raises(ValueError, match=r"op must be one of \['or', 'xor'\], got 'and'"):
        eisemann_passes.render_slice_masks(gl_context, mesh, spec, eisemann_passes.SliceRender("and"), timer=timer)
    with pytest.raises(ValueError, match=r"targets must be in 1..8, got 9"):
        eisemann_passes.render_slice_masks(gl_context, mesh, spec, eisemann_passes.SliceRender("xor", targets=9), timer=timer)


def test_missing_storage_blocks_in_the_vertex_stage_are_refused():
    """GL guarantees no shader storage block in vertex shaders; the render needs one."""
    ctx = SimpleNamespace(renderer="test renderer", mgl=SimpleNamespace(info={
        "GL_MAX_VERTEX_SHADER_STORAGE_BLOCKS": 0, "GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS": 8}))
    with pytest.raises(CapabilityError, match=r"reads the triangle setup from 1 shader storage block\(s\) "
                                              r"in its vertex shader, but GL_MAX_VERTEX_SHADER_STORAGE_BLOCKS "
                                              r"is 0 \(test renderer\)"):
        eisemann_passes._check_stage_storage(ctx)


# -- the paper's rasterization, measured -------------------------------------------


def test_raster_coverage_misplaces_faces_within_a_snap_step(gl_context):
    """coverage='raster' lets the rasterizer decide which column centers a
    triangle covers, on vertices snapped to 1/2^GL_SUBPIXEL_BITS pixel: a face a
    quarter step beyond a column center is snapped onto it and the fill rule
    takes the column.  Those voxels are 4e-4 voxel from the surface, not ties;
    the exact coverage (the default) gets them right.

    What is asserted is what GL guarantees: vertices may be snapped to 2^-SUBPIXEL_BITS
    pixel (GL 4.6 Sec. 14.6.1, Table 23.53), and a center on a polygon edge that no other
    polygon of the draw shares (here the box's projected outline x = 2.5, its side face
    being edge-on) may or may not be produced -- GL has no top-left rule.  So the raster
    coverage may differ from the exact set only in the column of centers within a snap
    step of that edge (i = 2), and there in whole voxels of it.  llvmpipe (8 subpixel
    bits) takes the column for both the bottom and the top face: 12 extra voxels, i = 2,
    j 1..3, k 1..4 (measured); another rasterizer may take none."""
    bits = gl_context.raw.get_integer(0x0D50)  # GL_SUBPIXEL_BITS
    offset = 0.25 / 2**bits
    mesh = box_mesh((2.5 + offset, 1.2, 1.3), (5.3, 4.4, 5.4))
    exact = run_method("eisemann-solid", mesh, UNIT)
    raster = run_method("eisemann-solid", mesh, UNIT, coverage="raster")
    expected = np.zeros(UNIT.dims, bool)
    expected[3:5, 1:4, 1:5] = True  # centers 3.5, 4.5 in x: 2.5 is outside
    assert np.array_equal(exact.dense(), expected)
    assert check_against_reference(exact, mesh).ok
    diff = raster.dense() ^ expected
    assert not diff[:2].any() and not diff[3:].any()  # only the column within a snap step of the edge
    assert not (expected & ~raster.dense()).any()
    c = check_against_reference(raster, mesh)
    assert len(c.unexplained) == int(diff.sum()) and set(c.unexplained[:, 0].tolist()) <= {2}


def test_raster_coverage_on_the_shared_meshes_is_measured(gl_context, shared_mesh):
    """Measured here (llvmpipe, 8 subpixel bits) at 128^3: coverage='raster'
    leaves 40 voxels that are not ties on cad_featuretype.stl (faces on voxel
    planes put many vertices near column centers) and 1 on the armadillo; the
    exact coverage none.  Pinned as bounds."""
    for name, bound in (("cad_featuretype.stl", 60), ("stanford_armadillo_libigl_86k.obj", 5)):
        mesh = load_mesh(shared_mesh(name))
        spec = glvox.grid_for(mesh, 128)
        ref = run_method("reference-solid", mesh, spec)
        ties = tie_set("reference-solid", mesh, spec)
        raster = run_method("eisemann-solid", mesh, spec, coverage="raster")
        c = check_against_reference(raster, mesh, reference_grid=ref, ties=ties)
        assert len(c.unexplained) <= bound, c.describe()
        assert check_against_reference(run_method("eisemann-solid", mesh, spec), mesh,
                                       reference_grid=ref, ties=ties).ok


# -- open meshes -----------------------------------------------------------------


def test_open_mesh_is_refused_then_warned_and_parity_per_column(gl_context, shared_mesh):
    """A box without its top face: refused by default; with allow_open a warning
    and the parity of crossings along the render axis.  Along z every column
    through the box crosses only the bottom face: a streak to the top of the
    grid.  Along x the rays cross both side faces: the box."""
    box = trimesh.creation.box(bounds=[BOX_LO, BOX_HI])
    faces = np.delete(box.faces, np.flatnonzero(box.face_normals[:, 2] > 0.5), axis=0)
    mesh = load_mesh((box.vertices, faces), name="open-box")
    assert not mesh.watertight
    with pytest.raises(NotWatertightError, match="not watertight.*allow_open"):
        run_method("eisemann-solid", mesh, UNIT)
    with pytest.warns(NotWatertightWarning, match="parity of ray crossings"):
        along_z = run_method("eisemann-solid", mesh, UNIT, allow_open=True, axis=2)
    streak = np.zeros(UNIT.dims, bool)
    streak[1:6, 0:4, 3:] = True
    assert np.array_equal(along_z.dense(), streak)
    with pytest.warns(NotWatertightWarning):
        along_x = run_method("eisemann-solid", mesh, UNIT, allow_open=True)  # x: the default
    assert np.array_equal(along_x.dense(), expected_box_solid())
    # the surface methods take open meshes as they are
    assert run_method("eisemann-surface", mesh, UNIT).count == 20  # the bottom face only
    # the bunny (holes in its base): the parity along z, as the reference counts it
    bunny = load_mesh(shared_mesh("stanford_bunny_bun_zipper.ply"))
    spec = glvox.grid_for(bunny, 64)
    with pytest.warns(NotWatertightWarning):
        g = run_method("eisemann-solid", bunny, spec, allow_open=True, axis=2)
        ref = run_method("reference-solid", bunny, spec, allow_open=True, axis=2)
    c = check_against_reference(g, bunny, reference_grid=ref)
    assert c.ok, c.describe()


# -- interface -------------------------------------------------------------------


def test_registry_entries():
    solid = glvox.methods.get_method("eisemann-solid").info
    surface = glvox.methods.get_method("eisemann-surface").info
    assert (solid.kind, solid.pipeline, solid.reference, solid.exact) == (
        "solid", "raster", "reference-solid", True)
    assert (surface.kind, surface.pipeline, surface.reference, surface.exact) == (
        "surface", "raster", "reference-conservative", False)
    # the solid along x (its pack a copy), the surface along z as the paper draws it
    assert solid.options["axis"].default == 0 and surface.options["axis"].default == 2
    assert surface.options["masks"].default == eisemann_passes.DEFAULT_MASKS


def test_stages_and_stats(gl_context):
    mesh = load_mesh("gen:torus")
    g = run_method("eisemann-solid", mesh, glvox.grid_for(mesh, 64))
    assert [s.name for s in g.run.timings.stages] == ["transform", "setup", "render", "pack", "readback"]
    assert all(s.gpu_s is not None and s.gpu_s >= 0 for s in g.run.timings.stages[:-1])
    st = g.run.stats
    # 64 slices: one pass with one target of the eight
    assert (st["passes"], st["tiles"], st["draws"], st["slices_per_pass"], st["render_targets"]) == (
        1, [1, 1], 1, 1024, 1)
    assert (st["axis"], st["coverage"], st["masks"]) == (0, "exact", eisemann_passes.DEFAULT_MASKS)
    deep = run_method("eisemann-solid", mesh, glvox.grid_for(mesh, dims=(16, 16, 2100)), axis=2)
    names = [s.name for s in deep.run.timings.stages]
    assert names == ["transform", "setup"] + ["render", "pack"] * 3 + ["readback"]
    assert deep.run.stats["draws"] == 3 and deep.run.stats["render_targets"] == 8


def test_masks_texture_and_bits_agree_and_runs_reuse_buffers(gl_context):
    m = crumpled_sphere()
    mesh = load_mesh((m.vertices, m.faces), name="crumpled")
    spec = glvox.grid_for(mesh, dims=(48, 40, 1100))  # two passes
    for name in ("eisemann-solid", "eisemann-surface"):
        bits = run_method(name, mesh, spec, masks="bits")
        pool = buffer_pool(gl_context, name)
        ids = {k: b.glo for k, b in pool._bufs.items()}
        targets = object_cache(gl_context, "eisemann", None)["targets"].textures[0].glo
        assert run_method(name, mesh, spec, masks="texture").equal(bits)
        assert run_method(name, mesh, spec, masks="bits").equal(bits)
        assert {k: b.glo for k, b in pool._bufs.items()} == ids  # no reallocation when warm
        assert object_cache(gl_context, "eisemann", None)["targets"].textures[0].glo == targets
