"""ss-octree (Schwarz & Seidel 2010, Sec. 5) against ss-solid and the exact solid reference.

The octree must decode to exactly ss-solid's grid (both decide every
crossing with shaders/ss/solid.glsl) and to reference-solid up to proven
ties; its structure must be the paper's (Morton order, contiguous children,
consistent pointers, all top-level nodes); its coverage factors must be the
exact block means of the solid.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh
from conftest import SHARED_MESHES

import glvox
from glvox.cli import main as cli_main
from glvox.errors import FormatError, LimitError, NotWatertightError, NotWatertightWarning
from glvox.grid import GridSpec
from glvox.mesh import Mesh, load_mesh
from glvox.methods import run_method
from glvox.metrics import check_against_reference, tie_set
from glvox.results.octree import NONE, SparseOctree, morton_encode, top_level

#: The shared meshes that are closed (tests/conftest.py lists them all).
WATERTIGHT = ("cad_fandisk.off", "cad_featuretype.stl", "cad_rocker_arm.obj", "cad_wingnut.obj",
              "depth_reduced_diamond_lattice.stl", "stanford_armadillo_libigl_86k.obj")


def octree(mesh, spec, **opts) -> SparseOctree:
    o = run_method("ss-octree", mesh, spec, **opts)
    assert isinstance(o, SparseOctree) and o.spec == spec
    assert o.run.stats["lost_crossings"] == 0, "a crossing found no level-0 node"
    return o


def check_structure(o: SparseOctree) -> None:
    """Sec. 5's layout: Morton order per level, eight contiguous children with
    the first at a multiple of 8, parent/child pointers that agree, x
    neighbours exactly where the adjacent node is stored, all 4^3 top nodes."""
    top = o.top
    assert top == top_level(o.dims)
    assert np.array_equal(o.levels[top].morton, np.arange(64))
    for level, lv in enumerate(o.levels):
        m = lv.morton.astype(np.int64)
        n = len(lv)
        assert np.all(np.diff(m) > 0), f"level {level} is not in strict Morton order"
        if level < top:
            assert n % 8 == 0
            assert np.array_equal(m & 7, np.tile(np.arange(8), n // 8))
            assert np.all((m >> 3).reshape(-1, 8) == (m >> 3)[::8, None])
            up = o.levels[level + 1]
            p = lv.parent.astype(np.int64)
            assert np.array_equal(up.morton[p].astype(np.int64), m >> 3)
            assert np.array_equal(up.child[p].astype(np.int64), np.arange(n) // 8 * 8)
        else:
            assert np.all(lv.parent == NONE)
        if level >= 1:
            has = lv.child != NONE
            first = lv.child[has].astype(np.int64)
            assert np.all(first % 8 == 0) and 8 * has.sum() == len(o.levels[level - 1])
            assert np.array_equal(np.sort(first), np.arange(0, len(o.levels[level - 1]), 8))
            assert not lv.inside[has].any()
        ijk = lv.coords()
        for step, ptr in ((1, lv.x_next), (-1, lv.x_prev)):
            nb = ijk + [step, 0, 0]
            code = morton_encode(nb[:, 0], nb[:, 1], nb[:, 2]).astype(np.int64)
            at = np.searchsorted(m, code)
            stored = (nb[:, 0] >= 0) & (at < n) & (m[np.minimum(at, n - 1)] == code)
            expect = np.where(stored, at, int(NONE))
            assert np.array_equal(ptr.astype(np.int64), expect), f"level {level} x pointers ({step:+d})"


def x_transitions_in_level0(o: SparseOctree, dense: np.ndarray) -> bool:
    """Sec. 5.1's aim: both voxels of every change of state along x (and a
    set voxel 0 of a column) lie in stored level-0 nodes."""
    stored = np.zeros([-(-d // 4) for d in o.dims], bool)
    i, j, k = o.levels[0].coords().T
    keep = (i < stored.shape[0]) & (j < stored.shape[1]) & (k < stored.shape[2])
    stored[i[keep], j[keep], k[keep]] = True
    mask = np.repeat(np.repeat(np.repeat(stored, 4, 0), 4, 1), 4, 2)[:o.dims[0], :o.dims[1], :o.dims[2]]
    change = np.zeros(o.dims, bool)
    change[1:] = dense[1:] != dense[:-1]
    change[0] = dense[0]
    both = change.copy()
    both[:-1] |= change[1:]
    return bool(np.all(mask[both]))


def check_exact(mesh, spec, **opts) -> SparseOctree:
    """Decodes to ss-solid exactly and to reference-solid up to proven ties."""
    o = octree(mesh, spec, **opts)
    g = o.to_grid()
    solid = run_method("ss-solid", mesh, spec, allow_open=True)
    assert g.equal(solid), f"{mesh.name} {spec.dims}: {g.compare(solid).to_dict()} against ss-solid"
    c = check_against_reference(g, mesh, "reference-solid")
    assert c.ok, f"{mesh.name} {spec.dims}: {c.describe()}"
    assert o.count == g.count == o.run.stats["voxels"]
    check_structure(o)
    assert x_transitions_in_level0(o, solid.dense())
    return o


def _shells():
    outer = trimesh.creation.icosphere(3, radius=1.0)
    mid = trimesh.creation.icosphere(3, radius=0.6)
    mid.invert()
    inner = trimesh.creation.box(extents=(0.5, 0.4, 0.3))
    return trimesh.util.concatenate([outer, mid, inner])


GENERATED = {
    "sphere": lambda: trimesh.creation.icosphere(4, radius=1.0),
    "torus": lambda: trimesh.creation.torus(1.0, 0.3),
    "nested-shells": _shells,
    "bunny-like": lambda: glvox.load_mesh("gen:bunny-like"),
}


def generated(name) -> Mesh:
    m = GENERATED[name]()
    return m if isinstance(m, Mesh) else load_mesh((m.vertices, m.faces), name=name)


@pytest.mark.parametrize("fit", [{"resolution": 64}, {"resolution": 47}, {"dims": (70, 45, 29)},
                                 {"resolution": 40, "tight": True}])
@pytest.mark.parametrize("shape", sorted(GENERATED))
def test_generated_solids_decode_exactly(gl_context, shape, fit):
    mesh = generated(shape)
    check_exact(mesh, glvox.grid_for(mesh, **fit))


# 128^3 on every mesh is the same check as 64^3 at 8x the voxels (the CPU references' cost):
# by default one mesh runs at 128, the rest with GLVOX_SLOW=1
@pytest.mark.parametrize("name, n", [(m, 64) for m in WATERTIGHT] + [
    pytest.param(m, 128, marks=() if m == "cad_fandisk.off" else pytest.mark.slow) for m in WATERTIGHT])
def test_shared_watertight_meshes_decode_exactly(gl_context, shared_mesh, name, n):
    mesh = load_mesh(shared_mesh(name))
    check_exact(mesh, glvox.grid_for(mesh, n))


@pytest.mark.slow
@pytest.mark.parametrize("name", WATERTIGHT)
def test_shared_watertight_meshes_at_256(gl_context, shared_mesh, name):
    mesh = load_mesh(shared_mesh(name))
    check_exact(mesh, glvox.grid_for(mesh, 256))


@pytest.mark.slow
@pytest.mark.parametrize("shape", sorted(GENERATED))
def test_generated_solids_at_256(gl_context, shape):
    mesh = generated(shape)
    check_exact(mesh, glvox.grid_for(mesh, 256))


def test_box_with_faces_on_voxel_centers(gl_context):
    """Faces exactly on voxel centers, crossings exactly on node faces
    (x = 7.5 and 15.5 flip from voxels 8 and 16, the first of level-1 nodes 1
    and 2), columns exactly on the side faces: the fill rule and the half-open
    crossing rule decide, identically to the reference (small integers and
    halves are exact in float32)."""
    spec = GridSpec((32, 24, 40), (0.0, 0.0, 0.0), 1.0)
    for lo, hi in (([7.5, 3.5, 8.5], [15.5, 16.5, 24.5]), ([0.5, 0.5, 0.5], [31.5, 23.5, 39.5]),
                   ([3.5, 7.5, 15.5], [23.5, 8.5, 16.5])):
        box = trimesh.creation.box(bounds=[lo, hi])
        mesh = load_mesh((box.vertices, box.faces))
        o = check_exact(mesh, spec)
        ref = run_method("reference-solid", mesh, spec)
        assert o.to_grid().equal(ref)
        i = np.arange(32) + 0.5
        expect = (i > lo[0]) & (i <= hi[0])
        assert np.array_equal(ref.dense()[:, 10 if hi[1] > 10 else 7, 16 if hi[2] > 16 else 15], expect)


def test_hand_worked_small_box(gl_context):
    """A box inside level-1 node (0, 0, 0) of a 16^3 grid: top level 1 (a 32^3
    cube of 4^3 level-1 nodes), one active level-1 node, eight level-0 nodes;
    voxels 1..4 along each axis are inside (centers 1.5 .. 4.5)."""
    spec = GridSpec((16, 16, 16), (0.0, 0.0, 0.0), 1.0)
    box = trimesh.creation.box(bounds=[[1.2, 1.2, 1.2], [4.7, 4.7, 4.7]])
    o = check_exact(load_mesh((box.vertices, box.faces)), spec)
    assert o.top == 1 and o.nodes_per_level == [8, 64]
    assert o.levels[1].child[0] == 0 and np.all(o.levels[1].child[1:] == NONE)
    assert not o.levels[1].inside.any() and o.count == 64
    # child c = x | y << 1 | z << 2 of node (0,0,0); SG voxel (x, y, z) is bit x + 4y + 16z
    sg = np.array([[[(x + 4 * y + 16 * z) for z in range(4)] for y in range(4)] for x in range(4)])
    for c in range(8):
        off = np.array([c & 1, (c >> 1) & 1, c >> 2]) * 4
        inside = [(np.arange(4) + o_ >= 1) & (np.arange(4) + o_ <= 4) for o_ in off]
        bits = sg[np.ix_(*[np.flatnonzero(s) for s in inside])].reshape(-1)
        expect = int(np.bitwise_or.reduce(np.left_shift(1, bits.astype(np.uint64)))) if len(bits) else 0
        assert int(o.data[c]) == expect, f"child {c}"
    assert np.array_equal(o.coverage(0)[:2, :2, :2].reshape(-1) * 64,
                          [27, 9, 9, 3, 9, 3, 3, 1])


def test_uniform_interior_nodes_have_no_children(gl_context):
    """A box filling most of a 32^3 grid: the level-1 nodes (1..2)^3 of its
    interior meet no face, stay without children and are inside."""
    spec = GridSpec((32, 32, 32), (0.0, 0.0, 0.0), 1.0)
    box = trimesh.creation.box(bounds=[[1.2, 1.2, 1.2], [30.7, 30.7, 30.7]])
    o = check_exact(load_mesh((box.vertices, box.faces)), spec)
    lv = o.levels[1]
    ijk = lv.coords()
    interior = np.all((ijk >= 1) & (ijk <= 2), axis=1)
    assert interior.sum() == 8
    assert np.all(lv.child[interior] == NONE) and lv.inside[interior].all()
    assert o.count == 30 ** 3


def test_geometry_left_of_and_around_a_clipped_grid(gl_context):
    """Explicit bounds that cut the mesh on every side: crossings left of the
    grid (q_bar < 0) flip whole columns from voxel 0, and must find their
    level-0 node at x = 0."""
    mesh = generated("bunny-like")
    b = mesh.bounds
    for bounds in (b * 0.6, np.array([b[0] * 0.3, b[1]]), np.array([b[0], b[1] * 0.4])):
        check_exact(mesh, glvox.grid_for(mesh, 48, bounds=bounds))


@pytest.mark.parametrize("dims", [(1, 1, 1), (3, 5, 2), (1, 40, 1), (9, 8, 17)])
def test_tiny_and_thin_grids(gl_context, dims):
    mesh = generated("sphere")
    check_exact(mesh, glvox.grid_for(mesh, dims=dims))


def test_mesh_outside_the_grid_gives_an_empty_octree(gl_context):
    mesh = generated("sphere")
    o = octree(mesh, GridSpec((16, 16, 16), (5.0, 5.0, 5.0), 0.1))
    assert o.count == 0 and o.nodes_per_level == [0, 64] and not o.levels[1].inside.any()
    assert o.to_grid().count == 0
    check_structure(o)


@pytest.mark.parametrize("dims", [(64, 64, 64), (70, 45, 29), (33, 17, 90)])
def test_coverage_is_the_exact_block_mean(gl_context, dims):
    """Sec. 5.5: the coverage of a level-L node is the fraction of inside
    voxels of its (4 * 2^L)^3 block (voxels beyond the grid count as
    outside), exactly the mean of the decoded solid over the block."""
    mesh = generated("bunny-like")
    o = octree(mesh, glvox.grid_for(mesh, dims=dims))
    dense = o.to_grid().dense()
    for level in range(o.top + 1):
        s = 4 << level
        cd = [-(-d // s) for d in dims]
        pad = np.zeros([c * s for c in cd], bool)
        pad[:dims[0], :dims[1], :dims[2]] = dense
        mean = pad.reshape(cd[0], s, cd[1], s, cd[2], s).sum(axis=(1, 3, 5)) / float(s) ** 3
        cov = o.coverage(level)
        assert cov.dtype == np.float32 and cov.shape == tuple(cd)
        assert np.array_equal(cov, mean.astype(np.float32)), f"level {level}"
    assert 0.0 < o.coverage(0).max() <= 1.0


def test_coarse_coverage_equals_the_reference_at_4x_resolution(gl_context):
    """Level-0 coverage of an octree at 4N is the paper's 64x supersampled
    scalar voxelization at N: each coarse voxel's factor is the mean of the
    exact reference solid at 4x the resolution over it, up to its tie voxels."""
    mesh = generated("torus")
    coarse = glvox.grid_for(mesh, 32)
    fine = GridSpec(tuple(4 * d for d in coarse.dims), coarse.origin, coarse.voxel_size / 4)
    o = octree(mesh, fine)
    cov = o.coverage(0)
    assert cov.shape == coarse.dims
    ref = run_method("reference-solid", mesh, fine).dense()
    ties = tie_set("reference-solid", mesh, fine)

    def blocks(a):
        return a.reshape(32, 4, 32, 4, 32, 4).sum(axis=(1, 3, 5))

    diff = np.abs(np.rint(cov * 64).astype(np.int64) - blocks(ref))
    assert np.all(diff <= blocks(ties))
    assert 0.0 < cov.mean() < 1.0 and np.count_nonzero((cov > 0) & (cov < 1)) > 100


def test_open_mesh_warns_and_decodes_to_the_parity_result(gl_context, shared_mesh):
    """Open meshes need allow_open and warn; the walls (the +x extrusions of
    the boundary edges) keep the octree equal to ss-solid's parity result.
    Without them (the paper's algorithm) nodes in the shadow of a hole are
    taken as uniform and the result differs there."""
    mesh = load_mesh(shared_mesh("stanford_bunny_bun_zipper.ply"))
    spec = glvox.grid_for(mesh, 64)
    with pytest.raises(NotWatertightError, match="allow_open"):
        run_method("ss-octree", mesh, spec)
    with pytest.warns(NotWatertightWarning, match="not watertight"):
        o = octree(mesh, spec, allow_open=True)
    assert o.run.stats["walls"] > 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotWatertightWarning)
        solid = run_method("ss-solid", mesh, spec, allow_open=True)
        paper = octree(mesh, spec, allow_open=True, walls=False)
    assert o.to_grid().equal(solid)
    check_structure(o)
    assert paper.run.stats["walls"] == 0
    assert not paper.to_grid().equal(solid)
    assert len(paper.levels[0]) < len(o.levels[0])


OPEN = sorted(set(SHARED_MESHES) - set(WATERTIGHT))


@pytest.mark.filterwarnings("ignore::glvox.errors.NotWatertightWarning")
@pytest.mark.parametrize("n", [64, pytest.param(256, marks=pytest.mark.slow)])
@pytest.mark.parametrize("name", OPEN)
def test_every_open_shared_mesh_decodes_to_ss_solid(gl_context, shared_mesh, name, n):
    """The documented result on open meshes: ss-solid's parity of crossings,
    exactly (holes, fragments, duplicate faces, non-manifold edges)."""
    mesh = load_mesh(shared_mesh(name))
    spec = glvox.grid_for(mesh, n)
    o = octree(mesh, spec, allow_open=True)
    assert o.to_grid().equal(run_method("ss-solid", mesh, spec, allow_open=True))
    check_structure(o)


def test_walls_change_nothing_on_a_closed_mesh(gl_context):
    mesh = generated("nested-shells")
    spec = glvox.grid_for(mesh, 48)
    a, b = octree(mesh, spec), octree(mesh, spec, walls=False)
    assert a.run.stats["walls"] == 0 and a.nodes_per_level == b.nodes_per_level
    assert np.array_equal(a.data, b.data)


def test_sparseness_follows_the_surface(gl_context):
    """Table 3: the share of stored level-0 nodes about halves per doubling of
    the resolution (the surface grows 4x, the level-0 positions 8x), and so
    does the octree's size against the dense bit grid."""
    mesh = generated("sphere")
    shares, dense_share = [], []
    for n in (64, 128, 256):
        o = octree(mesh, glvox.grid_for(mesh, n))
        mem = o.memory()
        assert mem["total"] == mem["structure"] + mem["data"]
        assert mem["dense"] == -(-n ** 3 // 8)
        assert mem["level0_nodes"] == len(o.levels[0])
        assert mem["level0_percent"] == pytest.approx(100 * len(o.levels[0]) / (n // 4) ** 3)
        shares.append(mem["level0_percent"])
        dense_share.append(mem["percent_of_dense"])
    assert 0.4 < shares[1] / shares[0] < 0.65 and 0.4 < shares[2] / shares[1] < 0.65
    assert 0.4 < dense_share[1] / dense_share[0] < 0.65 and 0.4 < dense_share[2] / dense_share[1] < 0.65
    assert mem["total"] < mem["dense"]
    stages = [s.name for s in o.run.timings.stages]
    assert stages[1:6] == ["active nodes", "construct", "voxelize", "propagate", "coverage"]


def test_grids_beyond_what_the_octree_supports_are_refused(gl_context):
    mesh = generated("sphere")
    with pytest.raises(LimitError, match=r"up to 4096 voxels per axis"):
        run_method("ss-octree", mesh, GridSpec((4097, 8, 8), (0.0, 0.0, 0.0), 1.0))


def test_buffers_over_the_ssbo_limit_are_refused_by_name(gl_context):
    mesh = generated("sphere")
    spec = glvox.grid_for(mesh, 128)
    limits = gl_context.limits()
    old = limits["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"]
    limits["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"] = 64 * 1024
    try:
        with pytest.raises(LimitError, match=r"ss-octree needs .* for .*nodes, over this "
                                             r"context's GL_MAX_SHADER_STORAGE_BLOCK_SIZE.*smaller grid"):
            run_method("ss-octree", mesh, spec)
    finally:
        limits["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"] = old
    octree(mesh, spec)  # and it runs again once the limit is back


def test_npz_round_trip_and_cli(gl_context, tmp_path):
    mesh = load_mesh("gen:torus")
    spec = glvox.grid_for(mesh, 48)
    o = octree(mesh, spec)
    path = glvox.save(o, tmp_path / "t.npz")
    back = glvox.load(path)
    assert isinstance(back, SparseOctree) and back.spec.same_placement(spec)
    assert np.array_equal(back.data, o.data) and back.nodes_per_level == o.nodes_per_level
    for a, b in zip(back.levels, o.levels):
        for f in ("morton", "parent", "x_next", "x_prev", "child", "inside", "count"):
            assert np.array_equal(getattr(a, f), getattr(b, f)) if getattr(b, f) is not None \
                else getattr(a, f) is None
    with np.load(path) as z:
        assert "occupancy" not in z.files and str(z["kind"]) == "sparse"
    assert cli_main(["voxelize", "gen:torus", "-m", "ss-octree", "-r", "48", "-o",
                     str(tmp_path / "c.npz"), "-q"]) == 0
    assert glvox.load(tmp_path / "c.npz").to_grid().equal(o.to_grid())
    glvox.save(o, tmp_path / "t.binvox")
    assert glvox.load(tmp_path / "t.binvox").equal(o.to_grid())
    with pytest.raises(FormatError, match="unknown voxel file suffix"):
        glvox.save(o, tmp_path / "t.ply")
    arrays = dict(np.load(path))
    del arrays["octree_L1_child"]
    np.savez(tmp_path / "cut.npz", **arrays)
    with pytest.raises(FormatError, match=r"cut.npz: not a complete sparse octree"):
        glvox.load(tmp_path / "cut.npz")


def test_to_grid_refuses_grids_too_big_to_hold_densely(gl_context):
    mesh = generated("sphere")
    o = octree(mesh, glvox.grid_for(mesh, 2048))
    with pytest.raises(LimitError, match="coverage"):
        o.to_grid()
    assert o.count > 0.5 * 4 / 3 * np.pi * 1024 ** 3
    assert o.coverage(o.top).shape == (4, 4, 4)
