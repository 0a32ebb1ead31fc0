"""carve-solid (exterior carving on the GPU) against reference-carve and reference-solid.

Every mismatch with reference-carve must lie in its tie set (voxels whose
carved verdict can change with a proven tie of the conservative surface,
glvox.reference.carve.carve_ties); on closed meshes the carved solid minus
the surface must be reference-solid minus the surface, up to solid ties.
The GPU passes (closing, flood fill) are also checked on hand-made and
random blockers against the scipy implementation, segment boundaries
included.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh
from conftest import SHARED_MESHES

import glvox
from glvox.gl.timing import StageTimer
from glvox.gpu.buffers import buffer_pool
from glvox.grid import GridSpec, pack_bits, unpack_bits
from glvox.mesh import load_mesh
from glvox.methods import run_method
from glvox.methods.carve import sweep as carve
from glvox.metrics import check_against_reference, tie_set
from glvox.reference.carve import MAX_CLOSE, close, close_window, exterior
from glvox.tolerances import TIE_EPS


def closed_shared():
    return [n for n in SHARED_MESHES if n.startswith(("cad_", "stanford_armadillo", "depth_reduced"))]


def check_carve(mesh, spec, k=0):
    """carve-solid against reference-carve (same close), mismatches proven ties."""
    g = run_method("carve-solid", mesh, spec, close=k)
    ref = run_method("reference-carve", mesh, spec, close=k)
    ties = tie_set("reference-carve", mesh, spec, close=k)
    c = check_against_reference(g, mesh, "reference-carve", reference_grid=ref, ties=ties)
    assert c.ok, f"{mesh.name} {spec.dims} close={k}: {c.describe()}"
    assert g.count == g.run.stats["voxels"] == int(np.bitwise_count(g.words()).sum())
    return g, ref


# -- the GPU passes on hand-made blockers ---------------------------------------------


def gpu_flood(ctx, blocker: np.ndarray, k: int = 0):
    """carve.close_on_gpu (k > 0) and carve.flood_on_gpu on a dense blocker: (exterior, rounds)."""
    spec = GridSpec(blocker.shape, (0, 0, 0), 1.0)
    pool = buffer_pool(ctx, "test-carve")
    surface = ctx.mgl.buffer(pack_bits(blocker).tobytes())
    ext = pool.get("ext", spec.n_words * 4)
    timer = StageTimer(ctx)
    if k:
        carve.close_on_gpu(ctx, spec, timer, pool, surface, k)
        closed = unpack_bits(np.frombuffer(surface.read(), dtype="<u4"), spec.dims)
        assert np.array_equal(closed, close(blocker, k)), f"closing k={k} differs on {blocker.shape}"
        blocker = closed
    rounds = carve.flood_on_gpu(ctx, spec, timer, pool, surface, ext)
    words = np.frombuffer(ext.read(size=spec.n_words * 4), dtype="<u4")
    surface.release()
    pool.release()
    return unpack_bits(words, spec.dims), rounds


def test_flood_follows_a_corridor_with_many_turns(gl_context):
    """A zigzag corridor from the boundary into a walled block: every turn costs a round,
    the whole corridor and room are reached, nothing behind the walls is."""
    n = 40
    wall = np.ones((n, n, n), bool)
    wall[0, 1:-1, 1:-1] = False  # an open face: the corridor starts at x = 0
    wall[:, 0, :] = wall[:, -1, :] = wall[:, :, 0] = wall[:, :, -1] = False  # free boundary
    path = []
    x, y = 1, 1
    for leg in range(12):  # alternate x and y legs, z fixed
        if leg % 2 == 0:
            path += [(xx, y) for xx in range(x, x + 3)]
            x += 2
        else:
            path += [(x, yy) for yy in range(y, y + 3)]
            y += 2
    for (px, py) in path:
        wall[px, py, 5] = False
    wall[x - 2:x + 3, y - 2:y + 3, 4:8] = False  # the room at the end
    ext, rounds = gpu_flood(gl_context, wall)
    expected = exterior(wall)
    assert np.array_equal(ext, expected)
    assert expected[x, y, 6], "the room is joined to the boundary through the corridor"
    assert not ext[20, 30, 20], "a voxel inside the solid walls is not reached"
    assert rounds >= 6, f"12 alternating legs need several rounds, got {rounds}"


@pytest.mark.parametrize("dims", [(37, 21, 9), (100, 33, 20), (5, 70, 3), (128, 9, 24)])
def test_flood_and_closing_on_random_blockers(gl_context, dims):
    rng = np.random.default_rng(sum(dims))
    for density in (0.25, 0.45):
        blocker = rng.random(dims) < density
        for k in (0, 1, 2, 5):
            ext, _ = gpu_flood(gl_context, blocker, k)
            assert np.array_equal(ext, exterior(close(blocker, k))), f"{dims} density {density} close {k}"


def test_flood_across_column_segments(gl_context, monkeypatch):
    """Columns longer than a segment are split; segments meet in later rounds."""
    monkeypatch.setattr(carve, "SEGMENT", 4)
    rng = np.random.default_rng(7)
    blocker = rng.random((8, 29, 31)) < 0.3
    blocker[:, :, 14] = True  # a wall at z = 14 ...
    blocker[3, 20, 14] = False  # ... with one hole: z paths must run across segments
    ext, _ = gpu_flood(gl_context, blocker)
    assert np.array_equal(ext, exterior(blocker))


def test_closing_window():
    assert [close_window(k) for k in (0, 1, 2, 3, 4)] == [(0, 0), (0, 1), (1, 1), (1, 2), (2, 2)]
    # a gap of k empty voxels closes, k + 1 does not
    for k in (1, 2, 3, 4):
        for gap, sealed in ((k, True), (k + 1, False)):
            s = np.zeros((20, 3, 3), bool)
            s[5, 1, 1] = s[6 + gap, 1, 1] = True
            assert close(s, k)[6:6 + gap, 1, 1].all() == sealed, (k, gap)
    with pytest.raises(ValueError, match=f"close must be in \\[0, {MAX_CLOSE}\\]"):
        close(np.zeros((2, 2, 2), bool), MAX_CLOSE + 1)


# -- whole method ---------------------------------------------------------------------


@pytest.mark.parametrize("shape", ["torus", "sphere", "bunny-like"])
@pytest.mark.parametrize("k", [0, 3])
def test_generated_meshes(gl_context, shape, k):
    mesh = load_mesh(f"gen:{shape}")
    check_carve(mesh, glvox.grid_for(mesh, dims=(45, 38, 33)), k)


@pytest.mark.parametrize("name", ["stanford_bunny_bun_zipper.ply", "messy_teapot_newell.obj",
                                  "messy_soup_synthetic.stl", "depth_gyroid_tpms_sheet.stl"])
def test_open_shared_meshes(gl_context, shared_mesh, name):
    """Any mesh: carving needs no inside, so open meshes run without allow_open or a warning."""
    mesh = load_mesh(shared_mesh(name))
    assert not mesh.watertight
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no NotWatertightWarning either
        g, _ = check_carve(mesh, glvox.grid_for(mesh, 64))
    assert g.run.stats["flood_rounds"] >= 1


def check_closed(mesh, spec):
    """On a closed mesh: carved minus surface = reference-solid minus surface up to solid ties,
    and the surface is in the carved solid."""
    g, _ = check_carve(mesh, spec)
    surface = run_method("reference-conservative", mesh, spec).dense()
    solid = run_method("reference-solid", mesh, spec).dense()
    ties = tie_set("reference-solid", mesh, spec)
    carved = g.dense()
    assert (carved | ~surface).all(), "the carved solid holds the surface"
    bad = (carved ^ solid) & ~surface & ~ties
    assert not bad.any(), f"{mesh.name}: {int(bad.sum())} voxels off the surface differ from reference-solid " \
                          f"(first {np.argwhere(bad)[:3].tolist()})"


@pytest.mark.parametrize("name", closed_shared())
def test_closed_shared_meshes_match_the_parity_solid(gl_context, shared_mesh, name):
    mesh = load_mesh(shared_mesh(name))
    assert mesh.watertight
    check_closed(mesh, glvox.grid_for(mesh, 64))


@pytest.mark.slow
@pytest.mark.parametrize("name", closed_shared())
def test_closed_shared_meshes_match_the_parity_solid_large(gl_context, shared_mesh, name):
    mesh = load_mesh(shared_mesh(name))
    check_closed(mesh, glvox.grid_for(mesh, 128))


def holed_box(hole: float):
    """A box [2.5, 21.5]^3 whose +z face has a square hole of integer side ``hole``
    voxels with its edges on half-integers, away from voxel faces (no ties): on the
    grid below, the rims touch the voxels their edges lie in, so the hole leaves
    ``hole - 1`` empty voxel columns in the conservative surface."""
    lo, hi = 2.5, 21.5
    box = trimesh.creation.box(bounds=[[lo] * 3, [hi] * 3])
    keep = ~np.isclose(box.triangles_center[:, 2], hi)
    v, f = list(box.vertices), [list(t) for t in box.faces[keep]]
    a = 12.0 + 0.5 * (hole % 2 == 0) - hole / 2  # a half-integer
    b = a + hole

    def quad(p0, p1, p2, p3):
        i = len(v)
        v.extend([p0, p1, p2, p3])
        f.extend([[i, i + 1, i + 2], [i, i + 2, i + 3]])

    # the top face as four quads around the hole (outward +z: counter-clockwise seen from above)
    quad((lo, lo, hi), (hi, lo, hi), (hi, a, hi), (lo, a, hi))
    quad((lo, b, hi), (hi, b, hi), (hi, hi, hi), (lo, hi, hi))
    quad((lo, a, hi), (a, a, hi), (a, b, hi), (lo, b, hi))
    quad((b, a, hi), (hi, a, hi), (hi, b, hi), (b, b, hi))
    mesh = load_mesh((np.array(v, float), np.array(f)))
    return mesh, GridSpec((24, 24, 24), (0, 0, 0), 1.0)


@pytest.mark.parametrize("k", [2, 4])
def test_box_with_a_hole_narrower_and_wider_than_close(gl_context, k):
    """A hole of side k + 1 voxels leaves a gap of k empty voxels: close=k seals it and the
    box is filled; a hole of side k + 2 stays open and the box is carved hollow."""
    for hole, sealed in ((k + 1, True), (k + 2, False)):
        mesh, spec = holed_box(hole)
        assert not mesh.watertight
        g, _ = check_carve(mesh, spec, k)
        inside = g.dense()[4:20, 4:20, 4:20]
        assert inside.all() == sealed and inside.any() == sealed, (k, hole)
        # without closing, every hole wider than the surface's thickness is open
        assert not run_method("carve-solid", mesh, spec).dense()[4:20, 4:20, 4:20].any()
    # closing never reaches past the box's surface into the empty grid around it
    mesh, spec = holed_box(k + 1)
    surface = run_method("reference-conservative", mesh, spec).dense()
    lo, hi = surface.nonzero()[0].min(), surface.nonzero()[0].max()
    assert not run_method("carve-solid", mesh, spec, close=k).dense()[:lo].any()
    assert not run_method("carve-solid", mesh, spec, close=k).dense()[hi + 1:].any()


def test_interior_faces(gl_context):
    """Faces with no shell around them enclose nothing: the carved solid is their surface.
    Inside a closed box, interior partitions change nothing: the box is filled."""
    planes = []
    for axis in range(3):
        quad = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float) * 0.8
        v = np.zeros((4, 3))
        v[:, (axis + 1) % 3], v[:, (axis + 2) % 3] = quad[:, 0], quad[:, 1]
        planes.append(v)
    verts = np.concatenate(planes)
    faces = np.concatenate([np.array([[0, 1, 2], [0, 2, 3]]) + 4 * i for i in range(3)])
    cross = load_mesh((verts, faces))
    spec = glvox.grid_for(cross, dims=(30, 30, 30), padding=2)
    g, _ = check_carve(cross, spec)
    surface = run_method("ss-conservative", cross, spec)
    assert g.equal(surface)
    box = trimesh.creation.box(extents=(2, 2, 2))
    both = load_mesh((np.concatenate([box.vertices, verts]), np.concatenate([box.faces, faces + 8])))
    assert not both.watertight  # the partitions make non-manifold edges
    spec = glvox.grid_for(both, dims=(30, 30, 30), padding=2)
    g, _ = check_carve(both, spec)
    filled = run_method("ss-solid", load_mesh(box), spec).dense() | run_method("ss-conservative", both, spec).dense()
    assert np.array_equal(g.dense(), filled)


def test_anisotropic_and_clipped_grids(gl_context):
    mesh = load_mesh("gen:bunny-like")
    b = mesh.bounds
    check_carve(mesh, glvox.grid_for(mesh, dims=(70, 20, 41)), 1)
    # a grid cutting the mesh: the cut opens the inside to the boundary
    cut = GridSpec((40, 40, 20), b[0], (b[1] - b[0]).max() / 40)
    g, _ = check_carve(mesh, cut)
    assert g.count < run_method("reference-solid", mesh, cut).count + run_method("reference-conservative", mesh, cut).count


def test_surface_variant_by_grid_size(gl_context, monkeypatch):
    """Small grids take ss-conservative's simple variant, large ones its default: the
    carve is the same (both variants equal reference-conservative up to ties)."""
    mesh = load_mesh("gen:bunny-like")
    spec = glvox.grid_for(mesh, dims=(40, 33, 37))
    assert run_method("carve-solid", mesh, spec).run.stats["surface_variant"] == "simple"
    monkeypatch.setattr(carve, "SIMPLE_MAX_DIM", 8)
    g, _ = check_carve(mesh, spec, 2)
    assert g.run.stats["surface_variant"] == "specialized"


def test_stats_stages_and_options(gl_context):
    mesh = load_mesh("gen:torus")
    spec = glvox.grid_for(mesh, 32)
    g = run_method("carve-solid", mesh, spec, close=2)
    stages = [s.name for s in g.run.timings.stages]
    assert stages[-4:] == ["close", "flood", "finish", "readback"] and "voxelize" in stages
    assert g.run.stats["close"] == 2 and g.run.stats["flood_rounds"] >= 1
    assert "close" not in [s.name for s in run_method("carve-solid", mesh, spec).run.timings.stages]
    for name in ("carve-solid", "reference-carve"):
        for bad in (33, -1):
            with pytest.raises(glvox.MethodError, match=f"option close must be a gap width from 0 to 32 voxels, "
                                                        f"got {bad}"):
                run_method(name, mesh, spec, close=bad)


@pytest.mark.parametrize("k", [0, 2])
def test_carve_ties_cover_every_surface_the_ties_allow(k):
    """The tie set is proven by monotonicity: every surface between S - T and S | T (T the
    surface ties) carves to the reference except on carve_ties.  A box with its faces on
    voxel planes and a hole whose edges are too, shifted by half TIE_EPS (geometry exactly on
    the planes is decided by the snap and has no ties): many ties, some changing the carve."""
    from glvox.reference.carve import carve as carve_surface, carve_ties
    from glvox.reference import conservative_surface, surface_ties

    mesh, spec = holed_box(4)
    tris = mesh.triangles_voxel(spec) - 0.5 + TIE_EPS / 2  # faces and hole edges beside voxel planes
    s = conservative_surface(tris, spec.dims)
    t = surface_ties(tris, spec.dims)
    ties = carve_ties(tris, spec.dims, k)
    assert t.any() and ties.any()
    base = carve_surface(s, k)
    rng = np.random.default_rng(k)
    for density in (0.0, 0.1, 0.5, 0.9, 1.0):
        between = (s & ~t) | (t & (rng.random(t.shape) < density))
        assert not ((carve_surface(between, k) ^ base) & ~ties).any(), density


@pytest.mark.parametrize("lo, hi", [(0.1, 0.7), (-3.3, 5.9), (1e5 + 0.1, 1e5 + 0.7)])
def test_faces_on_the_grid_boundary_keep_the_inside(gl_context, lo, hi):
    """The default fit puts a box's faces exactly on the grid's faces; the float32 copy
    of the mesh may land one just outside, where the surface pass would clip it.  The
    shared plane snap (glvox.grid.snap_to_planes) puts them on the grid's faces, so the
    box stays filled."""
    box = load_mesh(trimesh.creation.box(bounds=[[lo] * 3, [hi] * 3]))
    spec = glvox.grid_for(box, 16)
    g, ref = check_carve(box, spec)
    assert ref.count == 16 ** 3 and g.count == 16 ** 3
