"""Zhang et al. 2018 projected optimal scanline voxelization: CPU implementation and shaders.

What is checked, and against what:

* line voxelizations against hand-derived paths and a brute-force super
  cover in exact rational arithmetic;
* a lattice triangle scanned by hand (Eq. 8-9, with the counts of Table 1);
* SLV is the conservative set (exactly, in rational arithmetic, on triangles
  full of singular points); RLV differs from it exactly on voxels touched
  only at singular points; on meshes without singular points RLV = SLV =
  conservative;
* the GPU equals the CPU implementation: voxel for voxel for ILV, and for
  RLV/SLV up to proven float ties (the conservative tie set for tunnel 26,
  plus :func:`glvox.reference.scanline.float_variant_ties` for the thin
  variants), including the overflow passes that split large triangles on
  llvmpipe;
* separation on closed meshes: 26 is 26-tunnel-free, 18 18-tunnel-free, 6
  6-tunnel-free, each thinner than the one before (ILV with respect to its
  lattice surface, the mesh with its vertices snapped to voxel centres); ILV
  (26) also against the mesh itself on the watertight meshes, and where ILV
  (6) leaks through the mesh;
* ILV's line ties (one shift of the lattice) and base-edge ties (the side
  where the triangle meets the slicing plane), by hand and in exact
  arithmetic;
* ILV's voxel count against the paper's Table 3 bound, against the cover of
  its own lattice surface, and why the bound fails on three dense scans;
* bad input: degenerate and outside triangles, ILV's coordinate limit.
"""

from __future__ import annotations

import itertools
import math
from fractions import Fraction

import numpy as np
import pytest
import trimesh
from conftest import SHARED_MESHES
from scipy import ndimage

import glvox
from glvox.errors import LimitError, MethodError
from glvox.grid import GridSpec
from glvox.mesh import load_mesh
from glvox.methods import get_method, run_method, validate_options
from glvox.methods.scanline.voxelize import gpu_voxel_coords
from glvox.metrics import check_against_reference, separation_leaks, tie_set
from glvox.reference import TIE_EPS, conservative_surface, solid, surface_ties
from glvox.reference.scanline import (OpCounts, float_variant_ties, ilv_line, lattice_points, rlv_line,
                                      scanline_surface, slv_line)
from glvox.study import zhang

MODES = ("rlv", "slv", "ilv")
TUNNELS = (26, 18, 6)


# ----------------------------------------------------------------------------
# helpers

def rotated_box(extents=(2.0, 1.3, 0.9), angle=0.4, axis=(1, 2, 3)):
    """A closed box in generic orientation: 12 large triangles."""
    b = trimesh.creation.box(extents=extents)
    b.apply_transform(trimesh.transformations.rotation_matrix(angle, axis))
    return load_mesh((b.vertices, b.faces), name="rotated box")


def generic_sphere():
    """An icosphere off-centre and squashed: no vertex, edge or face in special position."""
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    m.apply_transform(np.diag([1.0, 0.93, 0.87, 1.0]))
    m.apply_translation([0.0123, -0.0271, 0.0319])
    return load_mesh((m.vertices, m.faces), name="generic sphere")


def leaks(surface, inside, connectivity):
    """Inside voxels reached from outside through unset voxels (6, 18 or 26-paths)."""
    if connectivity in (6, 26):
        return len(separation_leaks(surface, inside, connectivity))
    free = np.pad(~np.asarray(surface, bool), 1, constant_values=True)
    labels, _ = ndimage.label(free, structure=ndimage.generate_binary_structure(3, 2))
    outside = (labels == labels[0, 0, 0])[1:-1, 1:-1, 1:-1]
    return int((outside & inside & ~surface).sum())


def box_meets_segment(ijk, p, q, open_box=False):
    """Exact slab test: does segment p-q meet voxel ijk's closed (or open) box?"""
    t0, t1 = Fraction(0), Fraction(1)
    for i in range(3):
        lo, hi = Fraction(ijk[i]), Fraction(ijk[i] + 1)
        d = q[i] - p[i]
        if d == 0:
            inside = lo < p[i] < hi if open_box else lo <= p[i] <= hi
            if not inside:
                return False
            continue
        a, b = sorted(((lo - p[i]) / d, (hi - p[i]) / d))
        t0, t1 = max(t0, a), min(t1, b)
    return t0 < t1 if open_box else t0 <= t1


def six_connected(path):
    return all(sum(abs(x - y) for x, y in zip(u, v)) == 1 for u, v in zip(path, path[1:]))


# ----------------------------------------------------------------------------
# line voxelization (Sec. 4.1)

def test_ilv_line_follows_algorithm_1_by_hand():
    # (0,0,0) -> (3,1,0): M = (|dY|, |dX|) = (1, 3), L starts at M.  Steps:
    # L=(1,3) x; L=(2,2) tie: x first (both move up: lowest axis); L=(2,0) y; L=(2,6) x.
    # Geometrically the centre-to-centre line passes the voxel corner (2, 1): the tie.
    assert ilv_line((0, 0, 0), (3, 1, 0)) == [(0, 0, 0), (1, 0, 0), (2, 0, 0), (2, 1, 0), (3, 1, 0)]
    # the other tie order takes the other side of that corner
    assert ilv_line((0, 0, 0), (3, 1, 0), order=(1, 0, 2)) == [
        (0, 0, 0), (1, 0, 0), (1, 1, 0), (2, 1, 0), (3, 1, 0)]
    # x moving down loses the tie: the lattice shifted by +e_x passes the corner on the +x side
    assert ilv_line((3, 0, 0), (0, 1, 0)) == [(3, 0, 0), (2, 0, 0), (2, 1, 0), (1, 1, 0), (0, 1, 0)]


def test_ilv_line_with_zero_deltas_terminates():
    # Alg. 1 as printed scales by 2|dX||dY||dZ| = 0 here and would step x forever
    assert ilv_line((2, 5, 7), (2, 5, 3)) == [(2, 5, 7), (2, 5, 6), (2, 5, 5), (2, 5, 4), (2, 5, 3)]
    path = ilv_line((0, 0, 4), (5, -3, 4))
    assert path[0] == (0, 0, 4) and path[-1] == (5, -3, 4) and len(path) == 9
    assert six_connected(path) and {c[2] for c in path} == {4}
    assert ilv_line((1, 1, 1), (1, 1, 1)) == [(1, 1, 1)]


def _shifted_path(p, q, shift):
    """The voxels a segment between voxel centres p + 1/2, q + 1/2 moved by
    ``shift`` passes through, in order (exact: Fractions, no ties left)."""
    a = [Fraction(x) + Fraction(1, 2) + s for x, s in zip(p, shift)]
    b = [Fraction(x) + Fraction(1, 2) + s for x, s in zip(q, shift)]
    events = []
    for i in range(3):
        lo, hi = sorted((a[i], b[i]))
        for k in range(math.floor(lo) + 1, math.floor(hi) + 1):
            events.append(((k - a[i]) / (b[i] - a[i]), i))
    cur = [math.floor(x) for x in a]
    out = [tuple(cur)]
    for _, i in sorted(events):
        cur[i] += 1 if b[i] > a[i] else -1
        out.append(tuple(cur))
    return out


def test_ilv_line_ties_are_those_of_one_shift_of_the_lattice():
    """Every ILV line is the exact voxel traversal of its centre-to-centre
    segment moved by one small shift e1 >> e2 >> e3 > 0, the same for all
    lines: so reversing a line reverses its path, and lines through a common
    voxel corner pass it on the same side."""
    shift = (Fraction(1, 10**3), Fraction(1, 10**6), Fraction(1, 10**9))
    rng = np.random.default_rng(3)
    ties = 0
    for _ in range(400):
        p, q = (tuple(int(x) for x in rng.integers(-6, 7, 3)) for _ in range(2))
        fwd = ilv_line(p, q)
        assert fwd == _shifted_path(p, q, shift), (p, q)
        assert ilv_line(q, p)[::-1] == fwd
        assert six_connected(fwd) and len(fwd) == sum(abs(a - b) for a, b in zip(p, q)) + 1
        ties += any(fwd != ilv_line(p, q, order=o) for o in itertools.permutations(range(3)))
    assert ties > 50  # many of the lines met a voxel edge or corner


def test_slv_is_the_super_cover_and_rlv_a_6_path_inside_it():
    """On a quarter-voxel lattice (edges, corners, faces hit all the time), exactly."""
    rng = np.random.default_rng(11)
    singular = 0
    for _ in range(150):
        p, q = ([Fraction(int(x), 4) for x in rng.integers(0, 20, 3)] for _ in range(2))
        slv = slv_line(p, q)
        rlv = rlv_line(p, q)
        lo = [min(math.floor(a), math.floor(b)) - 1 for a, b in zip(p, q)]
        hi = [max(math.floor(a), math.floor(b)) + 1 for a, b in zip(p, q)]
        cover = {c for c in itertools.product(*(range(l, h + 1) for l, h in zip(lo, hi)))
                 if box_meets_segment(c, p, q)}
        crossed = {c for c in cover if box_meets_segment(c, p, q, open_box=True)}
        assert slv == cover
        assert crossed <= set(rlv) <= cover  # RLV: every voxel the segment enters, some it touches
        assert six_connected(rlv) and rlv[0] == tuple(math.floor(x) for x in p)
        singular += len(cover) > len(rlv)
    assert singular > 10  # the test met many singular segments


# ----------------------------------------------------------------------------
# triangle voxelization (Sec. 4.2), CPU

def test_ilv_triangle_scanned_by_hand():
    """Lattice triangle (0,0,0), (4,0,0), (0,4,0) in one layer.

    Sorted on (z, lexicographic): Q0 = (0,0), Q1 = (0,4), Q2 = (4,0) in (x, y);
    V_A = the x axis, V_B = the y axis then the staircase (1,4),(1,3),(2,3),...,(4,0).
    Scan: apex (A = B, one entry each) -> line (1,0)-(0,1); Eq. 8 for it
    (dX = 1, dY = -1, C0 = -1, d < d^ <=> |F + 1| < 2) takes (2,0) and (0,2), the
    first entry always, then stops at (3,0) and (0,3) (|F + 1| = 2) -> line
    (2,0)-(0,2); then (dX = dY... ) and so on up to (4,0).  The union is every
    voxel with x + y <= 4, plus the staircase of the hypotenuse (x + y = 5),
    which is exactly the conservative set of the triangle through the centres.
    """
    tri = np.array([[[0, 0, 0], [4, 0, 0], [0, 4, 0]]], float) + 0.5
    counts = OpCounts()
    got = scanline_surface(tri, (6, 6, 1), "ilv", counts=counts)
    want = np.zeros((6, 6, 1), bool)
    for x in range(5):
        for y in range(5):
            want[x, y, 0] = x + y <= 5
    assert (got == want).all()
    assert (got == conservative_surface(tri, (6, 6, 1))).all()
    assert counts.end_candidates > 0 and counts.comparisons > 0 and counts.additions > 0


def test_ilv_base_edge_ties_follow_the_slicing_plane():
    """Lattice triangle (4,3,2), (2,4,3), (3,2,4): plane x + y + z = 9 (voxel
    indices, centres at +1/2), normal (1,1,1), sliced along z.

    Layer 2 holds the apex (4,3) of V_A and V_B's (4,3), (3,3), (3,4); its top
    base edge (4,3) -> (3,4) passes the corner between (3,3) and (4,4).  The
    triangle meets the slicing plane z = 2.5 (index) on x + y = 6.5, through
    (3,3); the plane lies at z = 3 at the centre of column (3,3) and at z = 1
    at (4,4), so the base edge steps through (3,3), not (4,4), in layer 2
    and, as the bottom base edge, in layer 3 (the shift rule alone, y moving
    up, would take (4,4), which the triangle reaches in neither layer).  The
    whole result is then exactly the cover of the lattice triangle."""
    tri = np.array([[[4, 3, 2], [2, 4, 3], [3, 2, 4]]], float) + 0.5
    got = scanline_surface(tri, (7, 7, 7), "ilv")
    assert not got[4, 4, 2] and not got[4, 4, 3] and got[3, 3, 2] and got[3, 3, 3]
    cover = conservative_surface(tri + np.array([1e-3, 1e-6, 1e-9]), (7, 7, 7))
    assert (got == cover).all() and got.sum() == 12
    assert ilv_line((4, 3, 2), (3, 4, 2)) == [(4, 3, 2), (4, 4, 2), (3, 4, 2)]  # the shift rule's side


def test_float_scanlines_cover_a_flat_triangle_with_the_optimal_count():
    """A triangle parallel to z (one slice) is scanned along x with d^ = 1: one
    scanline per unit of width (Theorem 4.1, 0.1 % inside the bound)."""
    tri = np.array([[[0.25, 0.5, 2.5], [10.25, 0.5, 2.5], [0.25, 7.5, 2.5]]])
    counts = OpCounts()
    got = scanline_surface(tri, (12, 9, 5), "rlv", counts=counts)
    assert (got == conservative_surface(tri, (12, 9, 5))).all()
    assert counts.scanlines == math.ceil(10.0 / 0.999) + 1


SINGULAR_TRIANGLES = {
    # vertices on voxel corners, the face on the plane z = 2: both layers touch it
    "on a voxel plane": [[1, 1, 2], [7, 2, 2], [3, 6, 2]],
    # vertices on corners, a 45 degree plane through voxel edges
    "through voxel edges": [[1, 1, 1], [6, 6, 1], [1, 1, 6]],
    # one vertex exactly on a face, one on an edge, one inside
    "vertex on a face": [[3, Fraction(5, 2), Fraction(7, 4)], [6, 5, Fraction(13, 4)], [Fraction(3, 2), 6, 5]],
    # a sliver along a voxel edge line
    "sliver on an edge line": [[1, 3, 3], [7, 3, 3], [4, Fraction(13, 4), 3]],
    # half-voxel lattice, generic orientation
    "half-lattice": [[Fraction(1, 2), 1, Fraction(3, 2)], [7, Fraction(5, 2), 4], [2, Fraction(13, 2), Fraction(11, 2)]],
}


@pytest.mark.parametrize("name", SINGULAR_TRIANGLES)
def test_slv_is_conservative_and_rlv_differs_only_at_singular_points(name):
    """Exact rational arithmetic.  The conservative reference is exact on these
    dyadic inputs (small numbers in float64).  A voxel the triangle touches
    without entering it (T meets the closed box but no box shrunk by 1e-9)
    contains only singular points of T: RLV may leave exactly those out."""
    tri = np.array([[[Fraction(x) for x in v] for v in SINGULAR_TRIANGLES[name]]], dtype=object)
    tri_f = tri.astype(float)
    dims = (9, 9, 9)
    cons = conservative_surface(tri_f, dims)
    entered = conservative_surface(tri_f, dims, 0.5 - 1e-9)
    slv = scanline_surface(tri_f, dims, "slv", exact=True)
    rlv = scanline_surface(tri_f, dims, "rlv", exact=True)
    assert (slv == cons).all()
    assert (entered <= rlv).all() and (rlv <= cons).all()
    if name == "on a voxel plane":
        # the layer below the face is touched only: SLV has all of it, RLV none
        assert cons[:, :, 1].any() and not rlv[:, :, 1].any()


def test_scanline_results_equal_conservative_without_singular_points():
    mesh = generic_sphere()
    spec = glvox.grid_for(mesh, 40)
    tris = mesh.triangles_voxel(spec)
    cons = conservative_surface(tris, spec.dims)
    assert not surface_ties(tris, spec.dims).any()  # no singular point anywhere
    for mode in ("rlv", "slv"):
        assert (scanline_surface(tris, spec.dims, mode) == cons).all(), mode


# ----------------------------------------------------------------------------
# GPU against the CPU implementation

def _ties_for(mesh, spec, mode, tunnel, tris32):
    ties = surface_ties(tris32, spec.dims) | surface_ties(mesh.triangles_voxel(spec), spec.dims)
    if tunnel != 26:
        ties |= float_variant_ties(tris32, spec.dims, mode, tunnel)
    return ties


GPU_CASES = [("gen:torus", 40), ("gen:bunny-like", 48), ("cad_wingnut.obj", 64),
             ("messy_teapot_newell.obj", 64), ("stanford_dragon_vrip_res3.ply", 48)]


def _mesh(name, shared_mesh):
    return load_mesh(name if name.startswith("gen:") else shared_mesh(name))


@pytest.mark.parametrize("tunnel", TUNNELS)
@pytest.mark.parametrize("name,res", GPU_CASES)
def test_gpu_ilv_equals_cpu_voxel_for_voxel(name, res, tunnel, gl_context, shared_mesh):
    mesh = _mesh(name, shared_mesh)
    spec = glvox.grid_for(mesh, res)
    gpu = run_method("scanline-ilv", mesh, spec, tunnel=tunnel)
    cpu = scanline_surface(gpu_voxel_coords(mesh, spec), spec.dims, "ilv", tunnel)
    assert (gpu.dense() == cpu).all(), f"{int((gpu.dense() != cpu).sum())} voxels differ"


@pytest.mark.parametrize("tunnel", TUNNELS)
@pytest.mark.parametrize("mode", ("rlv", "slv"))
@pytest.mark.parametrize("name,res", [("cad_wingnut.obj", 64), ("messy_teapot_newell.obj", 64)])
def test_gpu_float_paths_equal_cpu_up_to_ties(name, res, mode, tunnel, gl_context, shared_mesh):
    mesh = _mesh(name, shared_mesh)
    spec = glvox.grid_for(mesh, res)
    tris32 = gpu_voxel_coords(mesh, spec)
    gpu = run_method(f"scanline-{mode}", mesh, spec, tunnel=tunnel).dense()
    cpu = scanline_surface(tris32, spec.dims, mode, tunnel)
    bad = (gpu != cpu) & ~_ties_for(mesh, spec, mode, tunnel, tris32)
    assert not bad.any(), np.argwhere(bad)[:5].tolist()


def check_float_path(mode, mesh, spec, ref=None):
    """SLV is the conservative set up to ties; RLV is it less voxels touched only at
    singular points (its definition, not rounding: a face on a voxel plane keeps one of
    the two layers it touches), beyond which it differs only on ties."""
    check = check_against_reference(run_method(f"scanline-{mode}", mesh, spec), mesh, reference_grid=ref)
    assert check.reference == "reference-conservative"
    if mode == "slv":
        assert check.ok, (mode, check.describe())
        return
    ref = run_method("reference-conservative", mesh, spec) if ref is None else ref
    singular = ref.dense() & ~conservative_surface(mesh.triangles_voxel(spec), spec.dims, 0.5 - TIE_EPS)
    bad = [tuple(v) for v in check.unexplained if not singular[tuple(v)]]
    assert not bad, (mode, check.describe(), bad[:5])


@pytest.mark.parametrize("mode", ("rlv", "slv"))
@pytest.mark.parametrize("name", ["cad_fandisk.off", "cad_featuretype.stl"])
def test_gpu_rlv_and_slv_against_reference_conservative(mode, name, gl_context, shared_mesh):
    mesh = load_mesh(shared_mesh(name))
    check_float_path(mode, mesh, glvox.grid_for(mesh, 96))


@pytest.mark.parametrize("name", SHARED_MESHES)
def test_gpu_rlv_and_slv_on_every_shared_mesh_at_48(name, gl_context, shared_mesh):
    """The float paths against the exact reference on every shared mesh in the default run
    (issue 20: one real mesh was not enough), at 48^3; 256^3 with GLVOX_SLOW=1 (below).  SLV:
    the conservative set up to ties.  RLV: less voxels touched only at singular points, and
    beyond them it may differ only on the ties of its own float decisions (float_variant_ties:
    on the happy Buddha a voxel overlapped by ~5e-3 voxel, set by the float64 mirror of RLV,
    is dropped by the GPU's float32 one)."""
    mesh = load_mesh(shared_mesh(name))
    spec = glvox.grid_for(mesh, 48)
    ref = run_method("reference-conservative", mesh, spec)
    ties = tie_set("reference-conservative", mesh, spec)
    slv = check_against_reference(run_method("scanline-slv", mesh, spec), mesh, reference_grid=ref, ties=ties)
    assert slv.ok, slv.describe()
    tris = mesh.triangles_voxel(spec)
    got = run_method("scanline-rlv", mesh, spec).dense()
    singular = ref.dense() & ~conservative_surface(tris, spec.dims, 0.5 - TIE_EPS)
    bad = (got ^ ref.dense()) & ~singular & ~ties
    if bad.any():  # its own float ties, only where needed (they cost a pass over the triangles)
        bad &= ~float_variant_ties(tris, spec.dims, "rlv", 26)
    assert not bad.any(), np.argwhere(bad)[:5].tolist()


def test_large_triangles_go_through_the_overflow_passes(gl_context):
    """At 200^3 the box's triangles need more loop iterations than an
    invocation may run on llvmpipe: they are listed, measured and redrawn in
    parts, and the result is still the CPU's.  Each method's kept objects are
    released first, so that ILV builds its small-triangle table within the call
    (with passes and bindings of its own) and the listing still arrives."""
    mesh = rotated_box()
    spec = glvox.grid_for(mesh, 200)
    tris32 = gpu_voxel_coords(mesh, spec)
    for mode in MODES:
        get_method(f"scanline-{mode}").release(gl_context)
        g = run_method(f"scanline-{mode}", mesh, spec)
        if gl_context.is_software:
            assert g.run.stats["overflow_triangles"] > 0 and g.run.stats["overflow_parts"] > 0
        cpu = scanline_surface(tris32, spec.dims, mode)
        diff = g.dense() != cpu
        if mode == "ilv":
            assert not diff.any()
        else:
            assert not (diff & ~_ties_for(mesh, spec, mode, 26, tris32)).any()


def test_slv_singular_events_on_a_box_on_voxel_planes(gl_context):
    """An axis-aligned box with its faces and edges on voxel planes, 128 voxels
    wide: nearly every event of SLV's lines is singular (a line lying in a face
    plane, an edge in two), so each marks the rest of its box in the corner
    loop (lines.glsl, mark_box_but), and on llvmpipe its large triangles go
    through the overflow passes, which charge those loops.  Dyadic geometry
    (pitch 2^-7): the GPU equals the exact CPU result, the conservative set."""
    b = trimesh.creation.box(bounds=[[0.25, 0.25, 0.25], [1.25, 1.25, 1.25]])
    mesh = load_mesh((b.vertices, b.faces), name="box on voxel planes")
    spec = GridSpec(dims=(192, 192, 192), origin=np.zeros(3), voxel_size=2.0 ** -7)
    tris = spec.vertices_to_voxel(mesh.vertices[mesh.faces])
    assert np.array_equal(tris, np.round(tris)) and tris.min() == 32 and tris.max() == 160
    g = run_method("scanline-slv", mesh, spec)
    if gl_context.is_software:
        assert g.run.stats["overflow_triangles"] > 0
    cpu = scanline_surface(tris, spec.dims, "slv", exact=True)
    assert np.array_equal(g.dense(), cpu)
    assert np.array_equal(cpu, conservative_surface(tris, spec.dims))


@pytest.mark.parametrize("ends,corner", [(((0.5, 0.5), (2.5, 2.5)), (0.5, 2.5)),
                                         (((0.5, 0.5), (2.5, 2.5)), (2.5, 0.5)),
                                         (((0.5, 2.5), (2.5, 0.5)), (0.5, 0.5)),
                                         (((0.5, 2.5), (2.5, 0.5)), (2.5, 2.5))])
def test_slv_marks_the_whole_box_where_an_edge_passes_a_voxel_edge(ends, corner, gl_context):
    """A triangle with an edge along a diagonal of a 2 x 2 square of voxel
    columns, passing two voxel edges exactly (dyadic, so no rounding), and its
    third corner on one side: a voxel beyond the edge touched only at such a
    point is the super cover's (and the conservative set's), and only the
    event's box marks it.  Both diagonals (the edge crosses x and y planes at
    once going up, and going up and down), the triangle on either side."""
    v = np.array([[*ends[0], 1.25], [*ends[1], 1.5], [*corner, 1.625]])
    spec = GridSpec(dims=(4, 4, 3), origin=np.zeros(3), voxel_size=1.0)
    mesh = load_mesh((v, np.array([[0, 1, 2]])), name="diagonal triangle")
    tris = spec.vertices_to_voxel(mesh.vertices[mesh.faces])
    assert np.array_equal(tris, v[None])
    cpu = scanline_surface(tris, spec.dims, "slv", exact=True)
    assert np.array_equal(cpu, conservative_surface(tris, spec.dims))
    assert np.array_equal(run_method("scanline-slv", mesh, spec).dense(), cpu)


def test_stage_timings_and_statistics(gl_context):
    mesh = load_mesh("gen:torus")
    g = run_method("scanline-ilv", mesh, glvox.grid_for(mesh, 32))
    names = [s.name for s in g.run.timings.stages]
    assert names[:2] == ["setup", "voxelize"] and names[-1] == "readback"
    assert g.run.timings.stage("voxelize").gpu_s is not None
    assert g.run.stats["overflow_triangles"] == 0 and g.run.stats["voxels"] == g.count


# ----------------------------------------------------------------------------
# separation on closed meshes (Sec. 5)

CLOSED = [("gen:sphere", 64), ("gen:torus", 96), ("gen:bunny-like", 64), ("cad_fandisk.off", 96),
          ("cad_wingnut.obj", 96), ("cad_rocker_arm.obj", 64), ("cad_featuretype.stl", 64),
          ("depth_reduced_diamond_lattice.stl", 64), ("stanford_armadillo_libigl_86k.obj", 48)]


@pytest.mark.parametrize("name,res", CLOSED)
def test_variants_are_tunnel_free_and_nested(name, res, gl_context, shared_mesh):
    """26 blocks 26-paths, 18 blocks 18-paths, 6 blocks 6-paths; each variant is
    a subset of the one before.  RLV and SLV against the mesh's solid, ILV
    against the solid of its lattice mesh (the vertices snapped to voxel
    centres, which is what ILV voxelizes, Sec. 4.1).

    The variants are separate compilations (TUNNEL is a define), so nesting needs
    every variant to round the float path alike: the scanline and clipping
    arithmetic keeps its product-sums in ``precise`` variables (GLSL 4.50 Sec. 4.9
    forbids fusing them into fma there; Sec. 4.7.1 allows it otherwise, and a
    compiler may then decide differently per variant).  No rasterizer is used."""
    mesh = _mesh(name, shared_mesh)
    spec = glvox.grid_for(mesh, res)
    inside = run_method("reference-solid", mesh, spec).dense()
    lattice = solid(lattice_points(gpu_voxel_coords(mesh, spec), spec.dims) + 0.5, spec.dims)
    for mode in MODES:
        ins = lattice if mode == "ilv" else inside
        r = {t: run_method(f"scanline-{mode}", mesh, spec, tunnel=t).dense() for t in TUNNELS}
        assert (r[18] <= r[26]).all() and (r[6] <= r[18]).all(), mode
        for t in TUNNELS:
            assert leaks(r[t], ins, t) == 0, (mode, t)


def test_thin_variants_are_thinner_on_curved_meshes(gl_context):
    mesh = load_mesh("gen:sphere")
    spec = glvox.grid_for(mesh, 64)
    for mode in MODES:
        n = [run_method(f"scanline-{mode}", mesh, spec, tunnel=t).count for t in TUNNELS]
        assert n[0] > n[1] > n[2], (mode, n)


WATERTIGHT = ("cad_fandisk.off", "cad_featuretype.stl", "cad_rocker_arm.obj", "cad_wingnut.obj",
              "depth_reduced_diamond_lattice.stl", "stanford_armadillo_libigl_86k.obj")
_SLOW_MARK = pytest.mark.slow


@pytest.mark.parametrize("name,res", [(n, 64) for n in WATERTIGHT]
                         + [pytest.param(n, r, marks=_SLOW_MARK) for r in (96, 128) for n in WATERTIGHT]
                         + [("gen:torus", 96), ("gen:sphere", 128), ("gen:bunny-like", 128)])
def test_ilv_is_26_tunnel_free_against_the_mesh_itself(name, res, gl_context, shared_mesh):
    """No 26-path of unset voxels from outside reaches a voxel whose centre is
    inside the mesh (the reference solid), although ILV voxelizes the lattice
    surface, not the mesh (a measured property, not a guarantee: see "ILV and
    the mesh itself" in glvox.reference.scanline; gen:torus at 96^3 leaked
    with an earlier tie rule for base edges)."""
    mesh = _mesh(name, shared_mesh)
    spec = glvox.grid_for(mesh, res)
    inside = run_method("reference-solid", mesh, spec).dense()
    assert leaks(run_method("scanline-ilv", mesh, spec).dense(), inside, 26) == 0


@pytest.mark.parametrize("name", ["gen:torus", "gen:bunny-like"])
def test_ilv_6_leaks_through_the_mesh_only_between_it_and_its_lattice_surface(name, gl_context):
    """The naive ``tunnel=6`` variant separates its lattice surface but not the
    mesh: at 96^3 a 6-path reaches a few voxel centres inside the mesh, all of
    them outside the lattice surface, i.e. between the two (vertex rounding
    moved the surface past them)."""
    mesh = load_mesh(name)
    spec = glvox.grid_for(mesh, 96)
    g = run_method("scanline-ilv", mesh, spec, tunnel=6).dense()
    inside = run_method("reference-solid", mesh, spec).dense()
    lattice = solid(lattice_points(gpu_voxel_coords(mesh, spec), spec.dims) + 0.5, spec.dims)
    reached = separation_leaks(g, inside, 6)
    assert 0 < len(reached) <= 5
    assert not lattice[tuple(reached.T)].any()
    assert len(separation_leaks(g, lattice, 6)) == 0


# ----------------------------------------------------------------------------
# ILV's voxel count (Table 3)

#: The paper's Table 3 bound on ILV's count error.
PAPER_ILV_BOUND = 0.025

#: Meshes on which this ILV exceeds it at 256^3 (measured error against RLV).
#: ILV voxelizes the lattice surface (vertices rounded to voxel centres, Alg. 1
#: GetVoxel); on these dense scans (triangles of about one voxel, fine detail)
#: the rounding roughens the surface, and its conservative count alone is
#: 2.9 % (buddha, tower) and 2.5 % (dragon res2) above the mesh's, which ILV
#: follows within 0.2 % (the tests below).
ILV_ABOVE_PAPER_BOUND = {
    "stanford_happy_buddha_113k.obj": 0.031, "messy_tower_holes.obj": 0.029,
    "stanford_dragon_vrip_res2.ply": 0.027,
}

#: Of those, the meshes whose lattice surface's conservative count alone
#: exceeds the bound: no ILV of any scanline strategy reaches it there.
LATTICE_ABOVE_PAPER_BOUND = ("stanford_happy_buddha_113k.obj", "messy_tower_holes.obj")

#: ILV's count against the conservative count of its own lattice surface:
#: +0.0 to +0.36 % measured at 256^3 on every shared mesh.
ILV_OVER_LATTICE_COVER = 0.005

#: Envelope of ILV's count error measured on every shared mesh: at most
#: +3.1 % at 256^3 (buddha) and +2.5 % at 512^3 (tower).
ILV_ENVELOPE = 0.035

#: A shift of the lattice surface small and generic enough that no vertex,
#: edge or face lies on a voxel face: its conservative count is then that of
#: a cover without voxels touched only at singular points, like RLV's.
LATTICE_SHIFT = np.array([1e-3, 1e-6, 1e-9])


def _ilv_error(mesh, res):
    """ILV count against RLV's: the conservative count less the voxels touched
    only at singular points (faces lying on voxel planes), equal to the
    conservative count on generic meshes (the paper's SS10 = SLV/RLV)."""
    spec = glvox.grid_for(mesh, res)
    rlv = run_method("scanline-rlv", mesh, spec).count
    return run_method("scanline-ilv", mesh, spec).count / rlv - 1.0


def _lattice_cover(mesh, spec):
    """Conservative count of ILV's lattice surface (every vertex at its voxel's
    centre), shifted by LATTICE_SHIFT."""
    lat = lattice_points(gpu_voxel_coords(mesh, spec), spec.dims) + 0.5
    return int(conservative_surface(lat + LATTICE_SHIFT, spec.dims).sum())


@pytest.mark.parametrize("name", ["messy_teapot_newell.obj", "cad_wingnut.obj", "cad_fandisk.off"])
def test_ilv_count_within_the_paper_bound(name, gl_context, shared_mesh):
    assert abs(_ilv_error(load_mesh(shared_mesh(name)), 256)) <= PAPER_ILV_BOUND


@pytest.mark.slow
@pytest.mark.parametrize("name", [
    pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=f"ILV error {ILV_ABOVE_PAPER_BOUND[n]:.1%} "
                                            "at 256^3: vertex rounding (see ILV_ABOVE_PAPER_BOUND)"))
    if n in ILV_ABOVE_PAPER_BOUND else n for n in SHARED_MESHES])
def test_ilv_count_within_the_paper_bound_on_every_shared_mesh(name, gl_context, shared_mesh):
    assert abs(_ilv_error(load_mesh(shared_mesh(name)), 256)) <= PAPER_ILV_BOUND


@pytest.mark.slow
@pytest.mark.parametrize("name", SHARED_MESHES)
def test_ilv_count_follows_its_lattice_surface(name, gl_context, shared_mesh):
    """ILV's count is that of a cover of its lattice surface, within 0.5 %:
    what it loses against the mesh's cover is the vertex rounding."""
    mesh = load_mesh(shared_mesh(name))
    spec = glvox.grid_for(mesh, 256)
    ilv = run_method("scanline-ilv", mesh, spec).count
    assert abs(ilv / _lattice_cover(mesh, spec) - 1.0) <= ILV_OVER_LATTICE_COVER


@pytest.mark.slow
@pytest.mark.parametrize("name", LATTICE_ABOVE_PAPER_BOUND)
def test_vertex_rounding_alone_exceeds_the_paper_bound(name, gl_context, shared_mesh):
    """Why those xfails stay: the lattice surface ILV voxelizes has a
    conservative count more than 2.5 % above the mesh's (RLV's) at 256^3."""
    mesh = load_mesh(shared_mesh(name))
    spec = glvox.grid_for(mesh, 256)
    rlv = run_method("scanline-rlv", mesh, spec).count
    assert _lattice_cover(mesh, spec) / rlv - 1.0 > PAPER_ILV_BOUND


@pytest.mark.slow
@pytest.mark.parametrize("name", SHARED_MESHES)
def test_ilv_count_error_is_bounded_on_every_shared_mesh(name, gl_context, shared_mesh):
    """The envelope measured here (ILV_ENVELOPE), at 256^3 and 512^3."""
    mesh = load_mesh(shared_mesh(name))
    for res in (256, 512):
        assert abs(_ilv_error(mesh, res)) <= ILV_ENVELOPE, res


@pytest.mark.slow
@pytest.mark.parametrize("name", SHARED_MESHES)
def test_gpu_against_reference_conservative_on_every_shared_mesh(name, gl_context, shared_mesh):
    mesh = load_mesh(shared_mesh(name))
    spec = glvox.grid_for(mesh, 256)
    ref = run_method("reference-conservative", mesh, spec)
    for mode in ("rlv", "slv"):
        check_float_path(mode, mesh, spec, ref)


@pytest.mark.slow
@pytest.mark.parametrize("name,res", [("messy_teapot_newell.obj", 512), ("cad_fandisk.off", 512),
                                      ("stanford_bunny_bun_zipper.ply", 256)])
def test_gpu_ilv_equals_cpu_at_high_resolution(name, res, gl_context, shared_mesh):
    mesh = load_mesh(shared_mesh(name))
    spec = glvox.grid_for(mesh, res)
    for tunnel in TUNNELS:
        gpu = run_method("scanline-ilv", mesh, spec, tunnel=tunnel).dense()
        assert (gpu == scanline_surface(gpu_voxel_coords(mesh, spec), spec.dims, "ilv", tunnel)).all()


# ----------------------------------------------------------------------------
# bad input, options

def test_triangles_outside_or_across_the_grid(gl_context, shared_mesh):
    """A grid over part of the mesh: triangles outside are skipped, those across
    the boundary clipped; the GPU still equals the CPU (ILV) or differs by ties."""
    mesh = load_mesh(shared_mesh("messy_teapot_newell.obj"))
    lo, hi = mesh.bounds
    spec = glvox.grid_for(mesh, bounds=np.stack([lo, lo + 0.45 * (hi - lo)]), dims=(40, 30, 30))
    tris32 = gpu_voxel_coords(mesh, spec)
    for mode in MODES:
        gpu = run_method(f"scanline-{mode}", mesh, spec).dense()
        cpu = scanline_surface(tris32, spec.dims, mode)
        assert gpu.any()
        if mode == "ilv":
            assert (gpu == cpu).all()
        else:
            assert not ((gpu != cpu) & ~_ties_for(mesh, spec, mode, 26, tris32)).any()
    # a grid the mesh does not reach at all
    far = GridSpec((8, 8, 8), mesh.bounds[1] + 10.0, 0.1)
    assert all(run_method(f"scanline-{m}", mesh, far).count == 0 for m in MODES)


def test_slivers_and_collinear_lattice_triangles(gl_context):
    """Needles thinner than float32 resolves, lattice triangles whose vertices
    share a voxel or a line: voxelized as their edges, the same on both sides."""
    rng = np.random.default_rng(7)
    v, f = [], []
    for i in range(60):
        a = rng.uniform(2, 20, 3)
        d = rng.normal(size=3)
        b = a + rng.uniform(0.5, 6) * d / np.linalg.norm(d)
        c = a + rng.uniform(0, 1) * (b - a) + rng.normal(size=3) * 10.0 ** rng.uniform(-7, -2)
        v += [a, b, c]
        f.append([3 * i, 3 * i + 1, 3 * i + 2])
    mesh = load_mesh((np.array(v), np.array(f)))
    spec = GridSpec((24, 24, 24), (0, 0, 0), 1.0)
    tris32 = gpu_voxel_coords(mesh, spec)
    for mode in MODES:
        gpu = run_method(f"scanline-{mode}", mesh, spec).dense()
        cpu = scanline_surface(tris32, spec.dims, mode)
        if mode == "ilv":
            assert (gpu == cpu).all()
        else:
            assert not ((gpu != cpu) & ~_ties_for(mesh, spec, mode, 26, tris32)).any()
            assert (gpu <= conservative_surface(tris32, spec.dims, 0.5 + TIE_EPS)).all()


def _small_triangles(lattice_lo, corners, rng):
    """Triangles whose lattice points are lattice_lo + corner (corner x + 4 y + 16 z of a
    4 x 4 x 4 block), each vertex jittered inside its voxel, away from its faces."""
    offs = np.array([(c % 4, c // 4 % 4, c // 16) for c in range(64)], dtype=np.float64)
    pts = np.asarray(lattice_lo, dtype=np.float64)[:, None, :] + offs[np.asarray(corners)]
    v = (pts + rng.uniform(0.2, 0.8, pts.shape)).reshape(-1, 3)
    return load_mesh((v, np.arange(len(v)).reshape(-1, 3)))


@pytest.mark.parametrize("tunnel", TUNNELS)
def test_ilv_small_triangles_in_a_block(tunnel, gl_context):
    """ILV draws a triangle whose lattice points fit in a 4 x 4 x 4 block from a table
    the GPU's own scan builds.  Every set of three corners of the block (45,760; a
    sample of 8,000 for the thin variants), its vertices in a random order, each in
    its own block of a grid (one block across x's word boundary 31 | 32), equals the
    CPU scan voxel for voxel: the table, its index and its row writes."""
    rng = np.random.default_rng(3)
    sets = np.array([t for t in itertools.combinations_with_replacement(range(64), 3)])
    if tunnel != 26:
        sets = sets[rng.choice(len(sets), 8000, replace=False)]
    sets = rng.permuted(sets, axis=1)
    k = np.arange(len(sets))
    blocks = np.stack([k % 36, k // 36 % 36, k // 1296], axis=1)
    mesh = _small_triangles(blocks * 5, sets, rng)
    spec = GridSpec((180, 180, 180), (0, 0, 0), 1.0)
    g = run_method("scanline-ilv", mesh, spec, tunnel=tunnel)
    assert g.run.stats["scanned_triangles"] == 0  # all drawn from the table
    cpu = scanline_surface(gpu_voxel_coords(mesh, spec), spec.dims, "ilv", tunnel)
    assert (g.dense() == cpu).all(), f"{int((g.dense() != cpu).sum())} voxels differ"


@pytest.mark.parametrize("res", [64, 128])
def test_ilv_scans_only_the_triangles_the_table_does_not_hold(res, gl_context, shared_mesh):
    """The table pass lists the triangles it cannot draw and a second dispatch scans
    those alone: on the teapot (large and small triangles) the scanned ones are the
    lattice triangles wider than 3 that meet the grid, counted here from the lattice
    points, and the voxels are the CPU scan's."""
    mesh = load_mesh(shared_mesh("messy_teapot_newell.obj"))
    spec = glvox.grid_for(mesh, res)
    tris32 = gpu_voxel_coords(mesh, spec)
    P = lattice_points(tris32, spec.dims)
    lo, hi = P.min(axis=1), P.max(axis=1)
    meets = np.all((hi >= 0) & (lo < np.asarray(spec.dims)), axis=1)
    wide = meets & ((hi - lo).max(axis=1) > 3)
    assert 0 < wide.sum() < meets.sum()
    g = run_method("scanline-ilv", mesh, spec)
    assert g.run.stats["scanned_triangles"] == wide.sum()
    assert (g.dense() == scanline_surface(tris32, spec.dims, "ilv")).all()


def test_ilv_small_triangles_clipped_at_every_face_of_the_grid(gl_context):
    """Small triangles whose block sticks out of the grid by 0 to 3 voxels on either
    side of every axis (and straddles x's word boundary 31 | 32): the table's rows are
    clipped to the grid exactly as the scan's voxels are.  nx = 64 fills its rows'
    words, so a bit past either end would land in a voxel of the row before or after."""
    rng = np.random.default_rng(11)
    dims = np.array([64, 7, 6])
    n = 200
    choices = [np.array([-3, -2, -1, 0, 28, 29, 30, 31, d - 4, d - 3, d - 2, d - 1]) if i == 0 else
               np.array([-3, -2, -1, 0, d - 4, d - 3, d - 2, d - 1]) for i, d in enumerate(dims)]
    lo = np.stack([rng.choice(c, n) for c in choices], axis=1)
    mesh = _small_triangles(lo, rng.integers(0, 64, (n, 3)), rng)
    spec = GridSpec(tuple(int(d) for d in dims), (0, 0, 0), 1.0)
    for tunnel in TUNNELS:
        gpu = run_method("scanline-ilv", mesh, spec, tunnel=tunnel)
        assert gpu.run.stats["scanned_triangles"] == 0
        cpu = scanline_surface(gpu_voxel_coords(mesh, spec), spec.dims, "ilv", tunnel)
        assert cpu[0].any() and cpu[-1].any() and cpu[:, 0].any() and cpu[:, :, -1].any()
        assert (gpu.dense() == cpu).all(), f"tunnel {tunnel}: {int((gpu.dense() != cpu).sum())} voxels differ"
        assert gpu.count == cpu.sum()


def test_ilv_refuses_coordinates_beyond_its_int32_range(gl_context):
    v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [30000.0, 0.5, 0.5]])
    mesh = load_mesh((v, np.array([[0, 1, 2], [0, 1, 3]])))
    spec = GridSpec((4, 4, 4), (0, 0, 0), 0.25)  # the second triangle reaches 120000 voxels out
    with pytest.raises(LimitError, match=r"scanline-ilv needs every vertex .* within 16000 voxel indices"):
        run_method("scanline-ilv", mesh, spec)
    with pytest.raises(LimitError, match=r"within 16000 voxel indices .* got 1 triangles beyond it"):
        scanline_surface(mesh.triangles_voxel(spec), spec.dims, "ilv")
    # the float paths clip instead and finish
    g = run_method("scanline-rlv", mesh, spec)
    assert g.count == scanline_surface(gpu_voxel_coords(mesh, spec), spec.dims, "rlv").sum()


def test_registry_entries_and_the_tunnel_option():
    for mode in MODES:
        info = get_method(f"scanline-{mode}").info
        assert (info.kind, info.pipeline, info.reference, info.exact) == (
            "surface", "compute", "reference-conservative", False)
        assert validate_options(info, {"tunnel": "18"}) == {"tunnel": 18}
        assert validate_options(info, {}) == {"tunnel": 26}
    with pytest.raises(MethodError, match=r"option tunnel must be one of \[26, 18, 6\], got 12"):
        validate_options(get_method("scanline-ilv").info, {"tunnel": "12"})
    with pytest.raises(ValueError, match=r"mode must be one of \('rlv', 'slv', 'ilv'\), got 'xlv'"):
        scanline_surface(np.zeros((1, 3, 3)), (2, 2, 2), "xlv")


def test_table1_scanline_needs_fewer_operations_than_schwarz_seidel():
    """Zhang et al.'s Table 1 claim (compare/zhang_table1.py prints the table): at every angle the
    instrumented ILV run needs fewer comparisons and additions than the S&S
    test counted in the paper's units."""
    for axis in ("y", "z"):
        for deg in zhang.ANGLES:
            tri = zhang.triangle(axis, deg)
            ss = zhang.ss_counts(tri)
            ours = OpCounts()
            scanline_surface(tri[None], (zhang.N,) * 3, "ilv", counts=ours)
            assert 0 < ours.comparisons < ss[0] and 0 < ours.additions < ss[1], (axis, deg)
