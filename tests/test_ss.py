"""Schwarz & Seidel in compute shaders (the ``ss`` family) against the exact references.

Surfaces (ss-conservative in each variant, ss-6sep): every mismatch must be a
proven tie (the voxel's verdict flips when the box half-size moves by
TIE_EPS); none is tolerated by count.

Solids (ss-solid, ss-solid-tiled) against reference-solid: every mismatch must
be a proven tie (the voxel's center lies within TIE_EPS of the surface, so
moving the mesh by at most TIE_EPS can flip it); none is tolerated by count.
The two share ss/solid.glsl, so they must agree with each other exactly.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh
from conftest import SHARED_MESHES

import glvox
from glvox.errors import LimitError, NotWatertightError, NotWatertightWarning
from glvox.gpu.buffers import buffer_pool, gpu_bytes
from glvox.gpu.dispatch import LOOP_BUDGET
from glvox.grid import MAX_VOXELS, GridSpec
from glvox.mesh import Mesh, load_mesh
from glvox.methods import run_method
from glvox.methods.ss import solid as ss_solid
from glvox.methods.ss import solid_tuning as ss_solid_tuning
from glvox.methods.ss.surface import AUTO_SIMPLE_DENSITY, default_variant
from glvox.metrics import check_against_reference, separation_leaks, tie_set
from glvox.reference._candidates import column_candidates, normals
from glvox.reference.solid import axis_signs, column_crossings


# ---------------------------------------------------------------------------
# surfaces: ss-conservative, ss-6sep
# ---------------------------------------------------------------------------

CONSERVATIVE_VARIANTS = ("simple", "specialized", "sorted")


def check_all(mesh, spec):
    """Every variant and ss-6sep against its reference, ties proven; returns the GPU grids."""
    out = {}
    for ref_name, runs in (
        ("reference-conservative", [("ss-conservative", {"variant": v}) for v in CONSERVATIVE_VARIANTS]),
        ("reference-6sep", [("ss-6sep", {})]),
    ):
        ref = run_method(ref_name, mesh, spec, allow_open=True)
        ties = tie_set(ref_name, mesh, spec)
        for name, opts in runs:
            g = run_method(name, mesh, spec, **opts)
            c = check_against_reference(g, mesh, ref_name, reference_grid=ref, ties=ties)
            assert c.ok, f"{mesh.name} {spec.dims} {name} {opts}: {c.describe()}"
            out[(name, opts.get("variant"))] = g
        out[ref_name] = ref
    return out


# 128^3 on every mesh is the same check as 64^3 at 8x the voxels (the CPU references' cost):
# by default one mesh runs at 128, the rest with GLVOX_SLOW=1
@pytest.mark.parametrize("name, n", [(m, 64) for m in SHARED_MESHES] + [
    pytest.param(m, 128, marks=() if m == "cad_fandisk.off" else pytest.mark.slow) for m in SHARED_MESHES])
def test_every_shared_mesh_matches_the_references(gl_context, shared_mesh, name, n):
    mesh = load_mesh(shared_mesh(name))
    check_all(mesh, glvox.grid_for(mesh, n))


def _quad(p0, p1, p2, p3, diagonal):
    v = np.array([p0, p1, p2, p3], dtype=float)
    f = [[0, 1, 2], [0, 2, 3]] if diagonal == 0 else [[0, 1, 3], [1, 2, 3]]
    return v, np.array(f)


SURFACE_GENERATED = {
    "sphere": lambda: trimesh.creation.icosphere(3, radius=1.0),
    "box": lambda: trimesh.creation.box(extents=(2.0, 1.3, 0.7)),
    "torus": lambda: trimesh.creation.torus(1.0, 0.3),
    "thin-sheet": lambda: trimesh.Trimesh(*_quad([0, 0, 0], [3, 0.2, 0.1], [3, 2, 1.3], [0.1, 2, 1.1], 0)),
    "needles": lambda: trimesh.Trimesh(
        np.array([[0, 0, 0], [5, 0.001, 0.002], [5, 0.0015, 0.0], [0, 3, 0], [0.002, 3.001, 4], [0.001, 3, 4]]),
        np.array([[0, 1, 2], [3, 4, 5]])),
}


@pytest.mark.parametrize("n", [17, 64])
@pytest.mark.parametrize("shape", sorted(SURFACE_GENERATED))
def test_generated_meshes_match_the_references(gl_context, shape, n):
    m = SURFACE_GENERATED[shape]()
    mesh = load_mesh((m.vertices, m.faces), name=shape)
    check_all(mesh, glvox.grid_for(mesh, n))


def test_triangles_exactly_on_voxel_planes(gl_context):
    """A box whose faces lie on voxel planes and a fan of triangles in the plane
    z = 3: every touched voxel on both sides, up to proven ties."""
    spec = GridSpec((8, 8, 8), (0.0, 0.0, 0.0), 1.0)
    box = trimesh.creation.box(bounds=[[2.0, 1.0, 3.0], [6.0, 5.0, 7.0]])
    out = check_all(load_mesh((box.vertices, box.faces)), spec)
    # exact here: the coordinates are small integers, float32 represents them exactly
    assert out[("ss-conservative", "specialized")].equal(out["reference-conservative"])
    fan = np.array([[1.0, 1.0, 3.0], [6.0, 1.0, 3.0], [6.0, 6.0, 3.0], [1.0, 6.0, 3.0], [3.5, 3.5, 3.0]])
    faces = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    out = check_all(load_mesh((fan, faces)), spec)
    g = out[("ss-conservative", "specialized")].dense()
    assert g[:, :, 2].any() and g[:, :, 3].any() and not g[:, :, 4].any()


@pytest.mark.parametrize("diag_seed", range(6))
def test_planar_quad_two_tessellations_give_the_same_voxels(gl_context, diag_seed):
    """S&S Fig. 5: conservative voxels do not depend on how a planar quad is split.
    6-sep is checked on rectangles with an axis-aligned edge only: for general
    quads the Sec. 3.4 criterion itself depends on the split (see
    tests/test_reference.py::test_six_separating_depends_on_diagonal_at_acute_corner)."""
    rng = np.random.default_rng(diag_seed)
    # a random planar quad: corners of a parallelogram-ish shape in a random plane
    o, a, b = rng.uniform(2, 4, 3), rng.normal(size=3), rng.normal(size=3)
    a, b = 4 * a / np.linalg.norm(a), 3 * b / np.linalg.norm(b)
    s, t = rng.uniform(0.7, 1.3, 2)
    quad = [o, o + a, o + s * a + t * b, o + b]
    spec = GridSpec((12, 12, 12), (-2.0, -2.0, -2.0), 1.0)
    grids = []
    for d in (0, 1):
        v, f = _quad(*quad, diagonal=d)
        grids.append(run_method("ss-conservative", load_mesh((v, f)), spec))
    assert grids[0].equal(grids[1])
    rect = [o, o + a, o + a + [0, 0, 3.0], o + [0, 0, 3.0]]
    six = [run_method("ss-6sep", load_mesh(_quad(*rect, diagonal=d)), spec) for d in (0, 1)]
    assert six[0].equal(six[1])


@pytest.mark.parametrize("name", ["stanford_armadillo_libigl_86k.obj", "cad_rocker_arm.obj"])
def test_separability_and_thinness_on_closed_meshes(gl_context, shared_mesh, name):
    mesh = load_mesh(shared_mesh(name))
    spec = glvox.grid_for(mesh, 64)
    inside = run_method("reference-solid", mesh, spec).dense()
    cons = run_method("ss-conservative", mesh, spec).dense()
    six = run_method("ss-6sep", mesh, spec).dense()
    assert len(separation_leaks(cons, inside, 26)) == 0
    assert len(separation_leaks(six, inside, 6)) == 0
    assert not (six & ~cons).any()  # 6-sep is a subset of conservative
    assert six.sum() < 0.8 * cons.sum()
    # the check has teeth: the thin surface lets 26-paths through
    assert len(separation_leaks(six, inside, 26)) > 0


def test_degenerate_and_outside_triangles(gl_context):
    """Zero-area triangles (repeated vertices, collinear) reach the shader when a
    Mesh is built directly; they and triangles outside the grid give no GL
    error and lose no voxel the reference sets."""
    v = np.array([[1.2, 1.3, 1.4], [4.6, 1.3, 1.4], [2.0, 4.1, 3.3],   # a real triangle
                  [5.5, 5.5, 5.5],                                     # a point triangle
                  [0.5, 6.2, 0.5], [6.5, 6.2, 6.5], [3.5, 6.2, 3.5],   # collinear
                  [50.0, 50.0, 50.0], [60.0, 50.0, 50.0], [50.0, 60.0, 51.0],  # far outside
                  [-3.0, 2.0, 2.0], [9.0, 2.5, 2.5], [3.0, 9.0, 3.0]])  # larger than the grid
    f = np.array([[0, 1, 2], [3, 3, 3], [4, 5, 6], [4, 4, 5], [7, 8, 9], [10, 11, 12]])
    mesh = Mesh(vertices=v, faces=f, name="degenerate")
    spec = GridSpec((7, 7, 7), (0.0, 0.0, 0.0), 1.0)
    for ref_name, name, opts in (("reference-conservative", "ss-conservative", {"variant": "simple"}),
                                 ("reference-conservative", "ss-conservative", {"variant": "specialized"}),
                                 ("reference-conservative", "ss-conservative", {"variant": "sorted"}),
                                 ("reference-6sep", "ss-6sep", {})):
        g = run_method(name, mesh, spec, debug=True, **opts)
        ref = run_method(ref_name, mesh, spec)
        c = check_against_reference(g, mesh, ref_name, reference_grid=ref)
        assert c.ok, (name, opts, c.describe())
        assert gl_context.mgl.error == "GL_NO_ERROR"
    assert ref.dense()[5, 5, 5]  # the point triangle sets its voxel (and the GPU too, above)


def test_statistics_are_table_1s_columns(gl_context, shared_mesh):
    mesh = load_mesh(shared_mesh("stanford_bunny_bun_zipper.ply"))
    g = run_method("ss-conservative", mesh, glvox.grid_for(mesh, 128), variant="specialized")
    st = g.run.stats
    assert sum(st["cases_1d_2d_3d"]) == mesh.n_triangles
    assert abs(sum(st["case_percent_1d_2d_3d"]) - 100.0) < 0.2
    # Table 1 lists 10%/49%/41% for the bunny at 128^3 (69,666 triangles, here 69,451)
    assert st["case_percent_1d_2d_3d"][1] == pytest.approx(49, abs=3)
    stages = [s.name for s in g.run.timings.stages]
    assert stages == ["transform", "voxelize", "readback"]  # no classify pass: the first chunk's pass counts
    assert all(s.gpu_s is not None and s.gpu_s >= 0 for s in g.run.timings.stages if s.name != "readback")
    sorted_run = run_method("ss-conservative", mesh, glvox.grid_for(mesh, 128), variant="sorted")
    assert [s.name for s in sorted_run.run.timings.stages] == [
        "transform", "classify", "sort", "ranges", "voxelize", "readback"]
    assert sorted_run.run.stats["cases_1d_2d_3d"] == st["cases_1d_2d_3d"]
    assert sorted_run.equal(g)


def test_huge_triangles_are_split_into_bounded_chunks(gl_context):
    """One triangle spanning a 200^3 grid is millions of bounding-box voxels for
    one invocation; without chunking, llvmpipe's loop limit silently cuts it."""
    v = np.array([[0.3, 0.2, 0.1], [199.7, 13.0, 150.2], [20.5, 199.6, 199.9]])
    mesh = load_mesh((v, np.array([[0, 1, 2]])))
    spec = GridSpec((200, 200, 200), (0.0, 0.0, 0.0), 1.0)
    ref = run_method("reference-conservative", mesh, spec)
    ties = tie_set("reference-conservative", mesh, spec)
    for variant in CONSERVATIVE_VARIANTS:
        g = run_method("ss-conservative", mesh, spec, variant=variant)
        c = check_against_reference(g, mesh, reference_grid=ref, ties=ties)
        assert c.ok, (variant, c.describe())
        assert g.count > 0.9 * ref.count  # most of the triangle is far from any tie
        if variant != "sorted":  # the first pass listed it, the second ran its other chunks
            assert g.run.stats["triangles_with_several_chunks"] == 1 and g.run.stats["max_chunks"] > 2
    six = run_method("ss-6sep", mesh, spec)
    assert check_against_reference(six, mesh).ok


def test_runs_are_deterministic_and_reuse_buffers(gl_context, shared_mesh):
    mesh = load_mesh(shared_mesh("stanford_dragon_vrip_res3.ply"))
    spec = glvox.grid_for(mesh, 96)
    first = run_method("ss-conservative", mesh, spec)
    pool = buffer_pool(gl_context, "ss-conservative")
    ids = {k: b.glo for k, b in pool._bufs.items()}
    again = run_method("ss-conservative", mesh, spec)
    assert again.equal(first)
    assert {k: b.glo for k, b in pool._bufs.items()} == ids  # no reallocation when warm


def _corner_grids(big_dims, small_dims, k: int = 3):
    """The sphere 20 voxels across, from voxel 3 in x and y and from ``k`` in z, on a big
    grid and on a small one with the same origin and voxel size: every vertex gets the
    same voxel coordinates on both (the transform does not depend on the dims), so the
    big grid's corner must equal the small grid."""
    mesh = load_mesh("gen:sphere")
    lo, hi = mesh.bounds
    h = float((hi - lo).max()) / 20.0
    origin = (float(lo[0] - 3.3 * h), float(lo[1] - 3.3 * h), float(lo[2] - (k + 0.3) * h))
    return mesh, GridSpec(big_dims, origin, h), GridSpec(small_dims, origin, h)


def test_a_grid_over_the_ssbo_limit_is_voxelized_in_slabs(ssbo_limit):
    """A grid whose bits are over GL_MAX_SHADER_STORAGE_BLOCK_SIZE: two z slabs, the
    first ending halfway through the sphere; the voxels equal those of a small grid."""
    nx = ny = 1024
    per_slice = ny * nx // 8
    first = ssbo_limit // per_slice  # slices the first slab holds
    mesh, big, small = _corner_grids((nx, ny, first + 16), (32, 32, first + 16), k=first - 10)
    assert big.n_words * 4 > ssbo_limit
    got = run_method("ss-conservative", mesh, big)
    want = run_method("ss-conservative", mesh, small)
    assert got.run.stats["slabs"] == 2 and want.count > 0
    np.testing.assert_array_equal(got.words()[:, :32, :1], want.words())
    assert got.count == want.count  # nothing anywhere else


@pytest.mark.parametrize("method, variant", [("ss-conservative", "simple"), ("ss-conservative", "specialized"),
                                             ("ss-conservative", "sorted"), ("ss-6sep", None), ("ss-solid", None)])
def test_slabs_give_the_whole_grid_voxel_for_voxel(gl_context, monkeypatch, method, variant):
    """With the storage-block limit forced to 4, 5 and 7 z slices of the grid, every
    variant voxelizes slab by slab (classify sees the whole grid, each slab's dispatch its
    slices): the same words, count and case counts as in one buffer."""
    mesh = load_mesh("gen:bunny-like")
    spec = glvox.grid_for(mesh, dims=(512, 256, 24))  # 16 KiB a slice; the mesh's buffers fit 4
    opts = {} if variant is None else {"variant": variant}
    whole = run_method(method, mesh, spec, **opts)
    real = gl_context.limits()
    per_slice = spec.dims[1] * spec.words_per_row * 4
    for nk, slabs in ((4, 6), (5, 5), (7, 4)):
        monkeypatch.setattr(gl_context, "limits", lambda nk=nk: {**real, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE":
                                                                  nk * per_slice + 3})
        g = run_method(method, mesh, spec, **opts)
        assert g.run.stats["slabs"] == slabs
        np.testing.assert_array_equal(g.words(), whole.words())
        assert g.count == whole.count and g.run.stats.get("cases_1d_2d_3d") == whole.run.stats.get("cases_1d_2d_3d")
    # one slice over the limit: refused in one line before any work
    monkeypatch.setattr(gl_context, "limits", lambda: {**real, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": per_slice - 4})
    with pytest.raises(LimitError, match=r"one z slice of the \(512, 256, 24\) bit grid needs 16384 bytes, over "
                                         r"GL_MAX_SHADER_STORAGE_BLOCK_SIZE 16380"):
        run_method(method, mesh, spec, **opts)


def test_solid_slabs_write_inside_their_slab(gl_context, monkeypatch):
    """Each slab's crossings stay in the slices its buffer holds: a triangle's columns are
    clipped to the slab (ss/solid_input.glsl's pass_columns), since a write past the
    buffer is undefined on a GPU (llvmpipe drops it).  The grid buffer is made the whole
    grid's size and zeroed, so that a write into a later slab's rows would stay behind
    the slab: nothing may."""
    mesh = load_mesh("gen:bunny-like")
    spec = glvox.grid_for(mesh, dims=(512, 256, 24))
    per_slice = spec.dims[1] * spec.words_per_row * 4
    grid = buffer_pool(gl_context, "ss-solid").get("grid", spec.n_words * 4)
    real = gl_context.limits()
    monkeypatch.setattr(gl_context, "limits", lambda: {**real, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": 5 * per_slice})
    g = run_method("ss-solid", mesh, spec)
    assert g.run.stats["slabs"] == 5 and g.count > 0
    # the grid's own bytes: a pooled buffer from an earlier, larger run may be longer
    assert not np.frombuffer(grid.read(size=spec.n_words * 4), dtype="<u4")[5 * per_slice // 4:].any()


def test_surfaces_take_grids_over_the_dense_limit(gl_context):
    """ss-conservative on 2048 x 2048 x 513 voxels (more than MAX_VOXELS, 269 MB of bits:
    z slabs on llvmpipe), and ss-solid and gwn-solid too: their corners equal a small grid's;
    ss-solid-tiled still refuses it, naming those two and the sparse ss-octree."""
    mesh, big, small = _corner_grids((2048, 2048, 513), (32, 32, 32))
    assert big.n_voxels > MAX_VOXELS
    for name in ("ss-conservative", "ss-solid", "gwn-solid"):
        calls = []
        got = run_method(name, mesh, big, progress=lambda done, total: calls.append((done, total)))
        n = got.run.stats["slabs"]
        assert n > 1 and calls == [(i, n) for i in range(1, n + 1)], name  # progress after every slab
        want = run_method(name, mesh, small)
        np.testing.assert_array_equal(got.words()[:32, :32, :1], want.words())
        assert got.count == want.count > 0, name
    with pytest.raises(LimitError, match=r"more than the 2147483647 it keeps dense; use a smaller grid, gwn-solid or "
                                         r"ss-solid, or the sparse ss-octree"):
        run_method("ss-solid-tiled", load_mesh("gen:box"), big)


#: NVIDIA's GL_MAX_SHADER_STORAGE_BLOCK_SIZE (2 GiB - 1 on the H100, driver 580): a
#: 2048^3 grid's 1 GiB of bits fits one buffer there, so no slabs and flat indices
#: past 2^31 and 2^32 voxels inside one dispatch.
NVIDIA_SSBO_LIMIT = 2**31 - 1


def _one_block_limit(gl_context, monkeypatch, nbytes: int) -> None:
    """The context's storage-block limit where it holds ``nbytes``; on llvmpipe (128 MiB)
    NVIDIA's is forced, since llvmpipe binds and bounds-checks a storage buffer by its
    real size whatever limit it reports.  Elsewhere a limit under ``nbytes`` skips."""
    limits = gl_context.limits()
    if int(limits["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"]) >= nbytes:
        return
    if "llvmpipe" not in gl_context.renderer:
        pytest.skip(f"this context's storage blocks hold less than {nbytes} bytes")
    monkeypatch.setattr(gl_context, "limits",
                        lambda: {**limits, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": NVIDIA_SSBO_LIMIT})


def _far_corner(big_dims):
    """The sphere 20 voxels across ending 3.7 voxels before the far corner of a grid of
    ``big_dims``, and a 27^3 grid holding it with the same voxel size and the same
    fractions of a voxel (its origin 27 voxels before the far corner): the big grid's
    last 27 voxels along each axis must equal the small grid."""
    mesh = load_mesh("gen:sphere")
    lo, hi = mesh.bounds
    h = float((hi - lo).max()) / 20.0
    far = [float(lo[a] - (big_dims[a] - 23.7) * h) for a in range(3)]
    near = [float(lo[a] - 3.3 * h) for a in range(3)]
    return mesh, GridSpec(big_dims, far, h), GridSpec((27, 27, 27), near, h)


def _last_voxels(grid, n: int) -> np.ndarray:
    """The last ``n`` voxels along each axis of a packed grid, as bools (z, y, x)."""
    nx = grid.spec.dims[0]
    words = grid.words()[-n:, -n:, :]
    bits = np.unpackbits(np.ascontiguousarray(words).view(np.uint8), bitorder="little")
    return bits.reshape(n, n, -1)[:, :, nx - n:nx].astype(bool)


@pytest.mark.parametrize("dims", [
    (2048, 2048, 520),  # past 2^31 voxels: int32 flat indices overflow
    pytest.param((2048, 2048, 1040), marks=pytest.mark.slow),  # past 2^32: uint32 ones wrap
])
def test_a_grid_in_one_buffer_past_two_billion_voxels(gl_context, monkeypatch, dims):
    """On NVIDIA a grid past MAX_VOXELS fits one storage buffer (2048^3: 1 GiB of bits),
    so the methods that take such grids index it in one dispatch, without the slabs that
    keep every index small on llvmpipe: the sphere at the far corner (voxel indices past
    2^31, or 2^32) must equal a small grid's voxels."""
    mesh, big, small = _far_corner(dims)
    assert big.n_voxels > (2**32 if dims[2] > 1024 else 2**31)
    _one_block_limit(gl_context, monkeypatch, big.n_words * 4)
    runs = [("ss-conservative", {"variant": v}) for v in CONSERVATIVE_VARIANTS]
    runs += [("ss-6sep", {}), ("ss-solid", {}), ("gwn-solid", {})]
    for name, opts in runs:
        got = run_method(name, mesh, big, **opts)
        if name != "gwn-solid":  # its field is computed in slabs whatever the grid's buffer
            assert "slabs" not in got.run.stats, name
        want = run_method(name, mesh, small, **opts)
        dense = want.dense().transpose(2, 1, 0)
        assert dense.any() and not dense[0].any() and not dense[:, 0].any() and not dense[:, :, 0].any()
        np.testing.assert_array_equal(_last_voxels(got, 27), dense, err_msg=f"{name} {opts}")
        assert got.count == want.count, f"{name} {opts}"


@pytest.mark.slow
@pytest.mark.parametrize("n", [256, 512, 1024])
@pytest.mark.parametrize("name", ["stanford_bunny_bun_zipper.ply", "stanford_dragon_vrip_res2.ply"])
def test_large_grids(gl_context, shared_mesh, name, n):
    mesh = load_mesh(shared_mesh(name))
    spec = glvox.grid_for(mesh, n)
    g = run_method("ss-conservative", mesh, spec)
    six = run_method("ss-6sep", mesh, spec)
    assert g.count > six.count > 0
    if n <= 512:
        check_all(mesh, spec)


def test_triangle_below_float32_spacing_is_a_tie_not_an_error(gl_context):
    """Found by the fuzz tests: a 1e-6 triangle at voxel y = 32 rounds onto the
    face y = 32 in float32, where the 6-separating test sets the voxels on both
    sides; in float64 it is tilted and sets one.  Its whole shape is rounding,
    so every voxel its box touches is a tie."""
    tris = np.array([[[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                     [[1.0, 0.0, 0.0], [0.999999, 0.0, 0.0], [0.999999, 1e-6, 1e-6]]])
    mesh = load_mesh((tris.reshape(-1, 3), np.arange(6).reshape(2, 3)), name="tiny")
    spec = glvox.grid_for(mesh, dims=(2, 65, 1))
    check_all(mesh, spec)


def test_auto_variant_follows_the_measured_density_rule(gl_context):

    assert AUTO_SIMPLE_DENSITY == 0.5
    assert default_variant(50, (10, 10, 10)) == "simple"        # 50 triangles on a 10 x 10 face: 0.5
    assert default_variant(49, (10, 10, 10)) == "sorted"
    assert default_variant(128, (8, 8, 64)) == "simple"          # face: (8 * 8 * 64) ** (2/3) = 256
    assert default_variant(127, (8, 8, 64)) == "sorted"
    mesh = glvox.load_mesh("gen:torus")                          # 9216 triangles
    for n, expect in ((64, "simple"), (256, "sorted")):          # 9216 / 64^2 = 2.25; / 256^2 = 0.14
        spec = glvox.grid_for(mesh, n)
        auto = run_method("ss-conservative", mesh, spec, ctx=gl_context)
        assert auto.run.stats["variant"] == expect and auto.run.options["variant"] == "auto"
        assert auto.equal(run_method("ss-conservative", mesh, spec, ctx=gl_context, variant=expect))


# ---------------------------------------------------------------------------
# solids: ss-solid, ss-solid-tiled
# ---------------------------------------------------------------------------

SOLID = ("ss-solid", "ss-solid-tiled")


def watertight_shared():
    return [n for n in SHARED_MESHES if n.startswith(("cad_", "stanford_armadillo", "depth_reduced"))]


def check_solid(mesh, spec, allow_open=False):
    """Both methods against the reference with ties proven, and against each other exactly."""
    ref = run_method("reference-solid", mesh, spec, allow_open=True)
    ties = tie_set("reference-solid", mesh, spec)
    out = {}
    for name in SOLID:
        g = run_method(name, mesh, spec, allow_open=allow_open)
        c = check_against_reference(g, mesh, "reference-solid", reference_grid=ref, ties=ties)
        assert c.ok, f"{mesh.name} {spec.dims} {name}: {c.describe()}"
        # ss-solid counts its voxels on the GPU: the count must be the words' popcount
        assert g.count == g.run.stats["voxels"] == int(np.bitwise_count(g.words()).sum())
        out[name] = g
    assert out["ss-solid"].equal(out["ss-solid-tiled"]), f"{mesh.name}: the two solid methods differ"
    out["reference-solid"] = ref
    return out


@pytest.mark.parametrize("n", [64, 128])
@pytest.mark.parametrize("name", watertight_shared())
def test_watertight_shared_meshes(gl_context, shared_mesh, name, n):
    mesh = load_mesh(shared_mesh(name))
    assert mesh.watertight
    check_solid(mesh, glvox.grid_for(mesh, n))


@pytest.mark.slow
@pytest.mark.parametrize("n", [256])
@pytest.mark.parametrize("name", watertight_shared())
def test_watertight_shared_meshes_large(gl_context, shared_mesh, name, n):
    mesh = load_mesh(shared_mesh(name))
    check_solid(mesh, glvox.grid_for(mesh, n))


def nested_shells():
    """A hollow ball: an outer sphere and an inner one facing inwards, so a ray
    crosses four times; plus a small solid ball floating in the cavity."""
    outer = trimesh.creation.icosphere(3, radius=1.0)
    inner = trimesh.creation.icosphere(3, radius=0.7)
    inner.invert()
    core = trimesh.creation.icosphere(2, radius=0.3)
    return trimesh.util.concatenate([outer, inner, core])


SOLID_GENERATED = {
    "sphere": lambda: trimesh.creation.icosphere(4, radius=1.0),
    "torus": lambda: trimesh.creation.torus(1.0, 0.35),
    "nested-shells": nested_shells,
    "rotated-box": lambda: trimesh.creation.box(
        extents=(2.0, 1.3, 0.7), transform=trimesh.transformations.euler_matrix(0.3, 0.5, 0.7)),
}


@pytest.mark.parametrize("n", [33, 64])
@pytest.mark.parametrize("shape", sorted(SOLID_GENERATED))
def test_generated_solids(gl_context, shape, n):
    m = SOLID_GENERATED[shape]()
    assert m.is_watertight
    mesh = load_mesh((m.vertices, m.faces), name=shape)
    check_solid(mesh, glvox.grid_for(mesh, n))


def test_nested_shells_are_hollow(gl_context):
    m = nested_shells()
    mesh = load_mesh((m.vertices, m.faces), name="nested")
    spec = glvox.grid_for(mesh, 48)
    g = run_method("ss-solid-tiled", mesh, spec).dense()
    # the voxels around radius r along +x: the core, the cavity, the shell, outside
    for r, inside in ((0.05, True), (0.5, False), (0.85, True), (0.99, True)):
        idx = np.floor(spec.world_to_voxel(np.array([[r, 0.01, 0.01]]))).astype(int)[0]
        assert g[tuple(idx)] == inside, (r, idx)


def test_box_faces_exactly_on_voxel_centers(gl_context):
    """Faces on the center planes x, y, z = c + 1/2 put every center of the box's
    boundary exactly on the surface and every boundary column exactly on a
    projected edge.  Coordinates are exact in float32, so the GPU must equal
    the reference with no tie at all: the half-open rule along x (center > q)
    and the top-left rule on the (y, z) edges decide every one.  The grid of
    128 makes the faces span more than one chunk of columns."""
    spec = GridSpec((128, 128, 128), (0.0, 0.0, 0.0), 1.0)
    box = trimesh.creation.box(bounds=[[2.5, 3.5, 4.5], [101.5, 90.5, 120.5]])
    mesh = load_mesh((box.vertices, box.faces))
    ref = run_method("reference-solid", mesh, spec)
    d = ref.dense()
    assert d.any()
    for name in SOLID:
        g = run_method(name, mesh, spec)
        assert g.equal(ref), f"{name}: {g.compare(ref).to_dict()}"
    # hand-worked: along x, voxel i is in iff 2.5 < i + 1/2 <= 101.5 (i = 3..101);
    # along y the face y = 3.5 is a left edge of the projection (owned) and
    # y = 90.5 is not (j = 3..89); along z the face z = 4.5 has an inward
    # normal +z, not a top edge, and z = 120.5 is one (k = 5..120)
    expect = np.zeros(spec.dims, bool)
    expect[3:102, 3:90, 5:121] = True
    np.testing.assert_array_equal(d, expect)


def test_big_triangles_span_several_chunks_and_tiles(gl_context):
    """A grid of 300^3 with a box across it: each face triangle covers about
    45k columns (several chunks of ss-solid) and 5.6k tiles (two chunks of the
    tile test)."""
    spec = GridSpec((300, 300, 300), (0.0, 0.0, 0.0), 1.0)
    box = trimesh.creation.box(bounds=[[1.2, 0.7, 0.9], [298.3, 299.1, 297.6]])
    mesh = load_mesh((box.vertices, box.faces))
    assert ss_solid.COLUMN_CHUNK < 45000 / 2
    out = check_solid(mesh, spec)
    # the four triangles of the two x faces (the others are edge-on to x)
    assert out["ss-solid"].run.stats["triangles_with_several_chunks"] == 4
    assert out["ss-solid"].run.stats["max_chunks"] > 2


def test_many_triangles_per_tile_take_several_passes(gl_context):
    """1100 nested cubes on a 16^3 grid: every cube puts at least two
    triangles in every tile its x faces cover, more than one pass of
    ss/tile_process.comp handles; the parity of the nesting decides."""
    sizes = np.linspace(2.0, 15.0, 1100)
    cubes = [trimesh.creation.box(extents=(s, s * 0.9, s * 0.8)) for s in sizes]
    m = trimesh.util.concatenate(cubes)
    mesh = load_mesh((m.vertices, m.faces), name="nested-cubes")
    assert mesh.watertight
    spec = GridSpec((16, 16, 16), (-8.0, -8.0, -8.0), 1.0)
    out = check_solid(mesh, spec)
    st = out["ss-solid-tiled"].run.stats
    assert st["max_triangles_per_tile"] > ss_solid.TILE_TRIANGLES
    assert st["tile_passes"] >= 2


def test_anisotropic_dims_and_clipping(gl_context):
    """Rows that are not a multiple of 32 voxels, tiles cut by the grid's
    edge, and a grid covering only part of the mesh (crossings before the
    grid flip whole columns, those past it nothing)."""
    m = trimesh.creation.torus(1.0, 0.4)
    mesh = load_mesh((m.vertices, m.faces), name="torus")
    for spec in (glvox.grid_for(mesh, dims=(45, 37, 29)),
                 GridSpec((50, 23, 41), (-0.3, -1.5, -0.45), 0.031)):
        out = check_solid(mesh, spec)
        words = out["ss-solid"].words()
        # the bits past nx in each row's last word stay zero
        tail = spec.dims[0] % 32
        if tail:
            assert not np.any(words[..., -1] >> np.uint32(tail))


def cover_pairs(tris, dims):
    """(tile, triangle) pairs where the triangle covers a column center of the
    tile (reference-solid's crossings along x), and where its (y, z) bounding
    box's centers reach the tile (CPU, float64)."""
    n = normals(tris)
    keep = np.flatnonzero(axis_signs(tris, n, 0) != 0)
    t = tris[keep]
    exact, boxes = set(), set()
    tiles_y = -(-dims[1] // 4)
    for tri, ju, jv in column_candidates(t, dims, 0):
        key = (jv // 4) * tiles_y + ju // 4
        boxes.update(zip(key.tolist(), keep[tri].tolist()))
    for tri, ju, jv, _ in column_crossings(t, n[keep], dims, 0):
        key = (jv // 4) * tiles_y + ju // 4
        exact.update(zip(key.tolist(), keep[tri].tolist()))
    return exact, boxes


@pytest.mark.parametrize("src,n", [("sphere", 64), ("armadillo", 64)])
def test_tile_queue_holds_every_covering_pair_and_few_others(gl_context, shared_mesh, src, n):
    """The critical-center tile test keeps every (tile, triangle) pair with a
    covered center, and discards most of the bounding-box pairs that have none."""
    if src == "sphere":
        m = trimesh.creation.icosphere(4, radius=1.0)
        mesh = load_mesh((m.vertices, m.faces), name="sphere")
    else:
        mesh = load_mesh(shared_mesh("stanford_armadillo_libigl_86k.obj"))
    spec = glvox.grid_for(mesh, n)
    g = run_method("ss-solid-tiled", mesh, spec)
    st = g.run.stats
    exact, boxes = cover_pairs(mesh.triangles_voxel(spec), spec.dims)
    assert len(exact) <= st["pairs"] <= len(boxes)
    # the test is conservative, not loose: most bounding-box-only pairs are dropped
    assert st["pairs"] - len(exact) <= 0.5 * (len(boxes) - len(exact))
    assert len({k for k, _ in exact}) <= st["active_tiles"] <= len({k for k, _ in boxes})
    assert st["triangles_per_active_tile"] == pytest.approx(st["pairs"] / st["active_tiles"], abs=0.01)


def test_deterministic(gl_context, shared_mesh):
    mesh = load_mesh(shared_mesh("cad_rocker_arm.obj"))
    spec = glvox.grid_for(mesh, 96)
    for name in SOLID:
        a = run_method(name, mesh, spec)
        b = run_method(name, mesh, spec)
        assert a.equal(b)


def test_open_mesh_is_refused_then_warned_and_parity(gl_context):
    """A box with one face missing: refused by default; with allow_open a
    warning, and the result is the parity of crossings along x, as the
    reference computes it."""
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    top = np.flatnonzero(box.face_normals[:, 2] > 0.5)
    faces = np.delete(box.faces, top, axis=0)
    mesh = load_mesh((box.vertices, faces), name="open-box")
    assert not mesh.watertight
    spec = glvox.grid_for(mesh, 16)
    with pytest.raises(NotWatertightError, match="not watertight.*allow_open"):
        run_method("ss-solid", mesh, spec)
    with pytest.warns(NotWatertightWarning, match="parity of ray crossings"):
        out = check_solid(mesh, spec, allow_open=True)
    # rays along x never meet the missing +z face: the parity is the whole box
    closed = load_mesh((box.vertices, box.faces), name="box")
    assert out["ss-solid"].equal(run_method("ss-solid", closed, spec))


def test_limits_are_refused_clearly(gl_context, ssbo_limit):
    mesh = load_mesh("gen:sphere")
    with pytest.raises(LimitError, match="rows of 4096 voxels; this grid has nx = 4100: use ss-solid"):
        run_method("ss-solid-tiled", mesh, glvox.grid_for(mesh, dims=(4100, 4, 4)))
    # a dense grid glvox holds whose bits exceed one storage block (128 MiB on llvmpipe)
    limit = ssbo_limit
    nz = 8 * limit // (2048 * 1024) + 8
    if 2048 * 1024 * nz > 2**31 - 1:
        pytest.skip(f"GL_MAX_SHADER_STORAGE_BLOCK_SIZE is {limit}: no dense grid exceeds it")
    with pytest.raises(LimitError, match="GL_MAX_SHADER_STORAGE_BLOCK_SIZE.*ss-octree"):  # ss-solid: z slabs
        run_method("ss-solid-tiled", mesh, glvox.grid_for(mesh, dims=(2048, 1024, nz)))


def test_stats_and_stages(gl_context):
    mesh = load_mesh("gen:torus")
    spec = glvox.grid_for(mesh, 64)
    g = run_method("ss-solid-tiled", mesh, spec)
    names = [s.name for s in g.run.timings.stages]
    assert names == ["transform", "classify", "pairs", "sort", "compact", "tiles", "readback"]
    st = g.run.stats
    assert st["pairs"] > 0 and st["active_tiles"] > 0 and st["voxels"] == g.count
    g = run_method("ss-solid", mesh, spec)
    assert [s.name for s in g.run.timings.stages] == ["transform", "voxelize", "fill", "readback"]


@pytest.mark.parametrize("int64", [True, False], ids=["int64", "int32"])
@pytest.mark.parametrize("nx", [20, 33, 64, 96, 100, 127, 128, 160, 190, 200, 250])
def test_row_fill_every_word_width(gl_context, monkeypatch, nx, int64):
    """The fill pass moves 1, 2 or 4 words per load, 64-bit words where the
    context has GL_ARB_gpu_shader_int64 and the row holds whole pairs, 32-bit
    ones otherwise (forced here by hiding the extension): nx 20, 33, 96, 100,
    160, 190, 200 and 250 cover 1, 2, 3, 4, 5, 6, 7 and 8 words per row (127:
    a last 64-bit word one bit short of full).  A single open triangle leaves
    the parity odd to the row's end, so the bits past nx must be masked; a box
    checks the carry between words."""
    if not int64:
        monkeypatch.setattr(ss_solid_tuning, "INT64", "GL_glvox_hidden_extension")
    elif ss_solid_tuning.INT64 not in gl_context.mgl.extensions:
        pytest.skip(f"no {ss_solid_tuning.INT64} on {gl_context.renderer}")
    wpr = -(-nx // 32)
    defines = ss_solid_tuning.fill_defines(gl_context, wpr)
    assert defines["WORD64"] == int(int64 and wpr % 2 == 0)
    spec = GridSpec((nx, 6, 7), (0.0, 0.0, 0.0), 1.0)
    tri = load_mesh((np.array([[nx * 0.37, 0.2, 0.1], [nx * 0.61, 5.9, 0.3], [nx * 0.5, 0.4, 6.8]]),
                     np.array([[0, 1, 2]])), name="one-triangle")
    box = trimesh.creation.box(bounds=[[0.6, 1.2, 0.8], [nx - 1.3, 4.7, 6.1]])
    for mesh, allow_open in ((tri, True), (load_mesh((box.vertices, box.faces)), False)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NotWatertightWarning)
            ref = run_method("reference-solid", mesh, spec, allow_open=True)
            g = run_method("ss-solid", mesh, spec, allow_open=allow_open)
            # the grid is cleared again for the next run
            again = run_method("ss-solid", mesh, spec, allow_open=allow_open)
        assert ref.count > 0 and g.equal(ref) and again.equal(ref), f"{mesh.name} nx={nx}"
        assert g.count == int(np.bitwise_count(g.words()).sum())


@pytest.mark.parametrize("words", [1, 2, 32, 4096, 1 << 16])
@pytest.mark.parametrize("n_rows", [1, 1000, 1 << 20])
def test_fill_rows_per_invocation_keep_the_loop_budget(gl_context, words, n_rows):
    """Rows of any length: an invocation's rows times their loads per row stay
    within LOOP_BUDGET, it does at least one row, and small grids keep
    FILL_MIN_GROUPS work groups where they have the rows for them."""
    d = ss_solid_tuning.fill_defines(gl_context, words)
    loads = words // (2 if d["WORD64"] else 1) // d["VEC"]
    per = ss_solid_tuning.fill_rows(d, words, n_rows, 64)
    assert 1 <= per <= ss_solid_tuning.FILL_ROWS and per * (loads + 1) < LOOP_BUDGET
    if per > 1:
        assert -(-n_rows // per) >= ss_solid_tuning.FILL_MIN_GROUPS * 64


@pytest.mark.parametrize("order_from", [0, None], ids=["row-order", "file-order"])
@pytest.mark.parametrize("src,n", [("nested-shells", 64), ("armadillo", 128)])
def test_row_order_gives_the_same_solid(gl_context, shared_mesh, monkeypatch, order_from, src, n):
    """On large grids ss-solid takes the triangles in row_order (slabs along z,
    then y): a permutation of them, so the same crossings and the same grid as
    the reference, forced here on small grids (ORDER_MIN_BYTES 0), and as the
    file's order.  The shells' triangles each cross many columns, so losing
    or doubling one shows."""
    if src == "armadillo":
        mesh = load_mesh(shared_mesh("stanford_armadillo_libigl_86k.obj"))
    else:
        m = SOLID_GENERATED[src]()
        mesh = load_mesh((m.vertices, m.faces), name=src)
    order = ss_solid_tuning.row_order(mesh)
    assert np.array_equal(np.sort(order), np.arange(mesh.n_triangles))
    z = mesh.vertices[mesh.faces[order, 0], 2]
    slabs = ss_solid_tuning.ORDER_SLABS
    slab = np.minimum((z - z.min()) * slabs / np.ptp(z), slabs - 1).astype(int)
    assert np.all(np.diff(slab) >= 0)
    if order_from is not None:
        monkeypatch.setattr(ss_solid_tuning, "ORDER_MIN_BYTES", order_from)
    spec = glvox.grid_for(mesh, n)
    g = run_method("ss-solid", mesh, spec)
    ref = run_method("reference-solid", mesh, spec)
    c = check_against_reference(g, mesh, "reference-solid", reference_grid=ref,
                                ties=tie_set("reference-solid", mesh, spec))
    assert c.ok, c.describe()
    assert g.count == int(np.bitwise_count(g.words()).sum())
    # the row-ordered faces were uploaded (and kept with the mesh) only where asked for
    derived = run_bufs(gl_context, mesh).derived.get("faces_in_row_order")
    assert (derived is not None) == (order_from is not None)
    if derived is not None:
        kept = np.frombuffer(derived.read(), dtype="<u4").reshape(-1, 3)
        np.testing.assert_array_equal(kept, mesh.faces[order])
        # and counted among the GPU bytes glvox keeps
        bufs = run_bufs(gl_context, mesh)
        with_it = gpu_bytes(gl_context)
        bufs.derived.pop("faces_in_row_order")
        try:
            assert with_it - gpu_bytes(gl_context) == derived.size
        finally:
            bufs.derived["faces_in_row_order"] = derived


def run_bufs(ctx, mesh):
    """The uploaded mesh, with the bounds ss_solid.mesh_rows reads."""
    from glvox.gpu.buffers import mesh_buffers
    return mesh_buffers(ctx, mesh)


def test_fill_visits_only_the_mesh_rows(gl_context):
    """The fill pass visits the rows of the mesh's projected bounding box
    (plus a row each side) and leaves the others to the clear: a small sphere
    in a corner of the grid, run after a mesh that filled other rows of the
    same buffer, must come out exactly as the reference, with every set voxel
    inside the visited rectangle."""
    spec = GridSpec((64, 64, 64), (0.0, 0.0, 0.0), 1.0)
    big = trimesh.creation.box(bounds=[[3.3, 2.6, 4.1], [60.2, 61.7, 59.4]])
    small = trimesh.creation.icosphere(subdivisions=3, radius=6.3)
    small.apply_translation([30.2, 50.7, 9.4])
    for m in (big, small):
        mesh = load_mesh((m.vertices, m.faces))
        out = check_solid(mesh, spec)
        g = out["ss-solid"]
        j0, k0, nj, nk = ss_solid.mesh_rows(spec, run_bufs(gl_context, mesh))
        assert g.run.stats["fill_rows"] == nj * nk
        rows = np.argwhere(out["reference-solid"].dense().any(axis=0))  # (j, k) of rows with voxels
        assert rows.size and np.all(rows.min(0) >= (j0, k0)) and np.all(rows.max(0) < (j0 + nj, k0 + nk))
    # the sphere spans 12.6 rows (y 44.4..57.0, z 3.1..15.7): the rectangle adds at most two each side
    assert nj <= 17 and nk <= 17 and j0 >= 42 and k0 >= 1


def test_mesh_rows_outside_the_grid(gl_context):
    """A mesh whose projection misses the grid's rows leaves no row to fill and
    an empty grid; one cut by the grid keeps the rectangle inside it."""
    m = trimesh.creation.icosphere(subdivisions=2, radius=2.0)
    mesh = load_mesh((m.vertices, m.faces))
    away = GridSpec((16, 8, 8), (-4.0, 10.0, -4.0), 0.5)  # y from 10 to 14: above the sphere
    assert ss_solid.mesh_rows(away, run_bufs(gl_context, mesh))[2] == 0
    g = run_method("ss-solid", mesh, away)
    assert g.count == 0 and not g.words().any() and g.run.stats["fill_rows"] == 0
    # y from 0 to 4 cuts the sphere (radius 2) at its middle: rows 0 .. ceil(4 - 1/2) + 1;
    # z from -1 to 3 cuts it on both sides: every row
    cut = GridSpec((16, 8, 8), (-4.0, 0.0, -1.0), 0.5)
    assert ss_solid.mesh_rows(cut, run_bufs(gl_context, mesh)) == (0, 0, 6, 8)
    check_solid(mesh, cut)



def test_slab_stages_are_summed_by_name(gl_context, monkeypatch):
    """Slab by slab, each stage is reported once: its time summed over the slabs."""
    mesh = load_mesh("gen:bunny-like")
    spec = glvox.grid_for(mesh, dims=(512, 256, 24))
    real = gl_context.limits()
    monkeypatch.setattr(gl_context, "limits", lambda: {**real, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": 5 * 16384})
    g = run_method("ss-conservative", mesh, spec, variant="specialized")
    assert g.run.stats["slabs"] == 5
    assert [s.name for s in g.run.timings.stages] == ["transform", "classify", "voxelize", "readback"]
