"""Per-voxel attributes (issue 21): the source-triangle rule, its GPU pass, storage.

Hand-worked cases fix the rule itself (expected values written from the
geometry, not from glvox); the real textured and vertex-coloured meshes check
the GPU against the float64 reference, every triangle mismatch a proven tie.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import glvox
from glvox.errors import FormatError, FormatWarning, GridError, MethodError
from glvox.gpu.transform import gpu_vertices_voxel
from glvox.grid import GridSpec
from glvox.methods import run_method
from glvox.reference.attributes import (closest_points, nearest_seeds, proven_ties, reference_attributes,
                                        sample_texture)
from glvox.results import VoxelGrid
from glvox.tolerances import ATTR_COLOR_TOL, ATTR_NORMAL_TOL, JFA_SLACK
from glvox.visuals import COLOR_TEXTURE, Texture, Visuals, load_visual_mesh

ALL = ("triangle", "color", "normal", "material")

# -- storage ------------------------------------------------------------------


def _grid_with_attributes():
    occ = np.zeros((3, 4, 5), bool)
    occ[0, 1, 2] = occ[2, 0, 0] = occ[1, 3, 4] = occ[2, 3, 1] = True
    spec = GridSpec(occ.shape, np.zeros(3), 0.5)
    m = int(occ.sum())
    attrs = {"triangle": np.arange(m, dtype=np.int32), "color": np.arange(4 * m, dtype=np.uint8).reshape(m, 4),
             "normal": np.eye(3, dtype=np.float32)[np.arange(m) % 3], "material": np.full(m, 7, np.int32)}
    return occ, VoxelGrid(occ, spec, attributes=attrs), attrs


def test_indices_are_c_order_and_attribute_grid_is_dense():
    occ, g, attrs = _grid_with_attributes()
    idx = g.indices()
    assert np.array_equal(idx, np.argwhere(occ))
    dense = g.attribute_grid("color")
    assert dense.shape == (3, 4, 5, 4) and dense.dtype == np.uint8
    for row, (i, j, k) in enumerate(idx):
        assert np.array_equal(dense[i, j, k], attrs["color"][row])
    assert not dense[~occ].any()  # unset voxels: alpha 0, no colour
    assert (g.attribute_grid("triangle")[~occ] == -1).all()
    with pytest.raises(GridError, match="no attribute 'nope'"):
        g.attribute_grid("nope")


def test_npz_round_trip_keeps_attributes_and_old_files_load(tmp_path):
    occ, g, attrs = _grid_with_attributes()
    back = glvox.load(g.save(tmp_path / "a.npz"))
    assert set(back.attributes) == set(attrs)
    for k, v in attrs.items():
        assert back.attributes[k].dtype == v.dtype and np.array_equal(back.attributes[k], v)
    # a file written before attributes existed: occupancy and placement only
    np.savez(tmp_path / "old.npz", occupancy=occ, origin=np.zeros(3), voxel_size=np.float64(0.5))
    old = glvox.load(tmp_path / "old.npz")
    assert old.attributes == {} and np.array_equal(old.dense(), occ)


def test_attributes_must_have_one_row_per_set_voxel(tmp_path):
    occ, g, attrs = _grid_with_attributes()
    with pytest.raises(GridError, match="one row per set voxel"):
        VoxelGrid(occ, g.spec, attributes={"triangle": attrs["triangle"][:-1]})
    with pytest.raises(GridError, match="unknown attribute"):
        VoxelGrid(occ, g.spec, attributes={"colour": attrs["color"]})
    np.savez(tmp_path / "bad.npz", occupancy=occ, origin=np.zeros(3), voxel_size=np.float64(0.5),
             attr_color=np.zeros((2, 4), np.uint8))
    with pytest.raises(FormatError, match="bad.npz"):
        glvox.load(tmp_path / "bad.npz")


# -- hand-worked cases ----------------------------------------------------------

#: The six faces of the cube [1.5, 4.5]^3 as (axis, side), each two triangles
#: (2f, 2f + 1), and a colour per face.
FACES = [(0, 0), (0, 1), (1, 0), (1, 1), (2, 0), (2, 1)]
FACE_COLORS = np.array([[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255],
                        [255, 255, 0, 255], [0, 255, 255, 255], [255, 0, 255, 255]], np.uint8)


def _cube():
    lo, hi = 1.5, 4.5
    verts, faces = [], []
    for axis, side in FACES:
        u, v = (axis + 1) % 3, (axis + 2) % 3
        quad = []
        for a, b in ((lo, lo), (hi, lo), (hi, hi), (lo, hi)):
            p = [0.0, 0.0, 0.0]
            p[axis], p[u], p[v] = (hi if side else lo), a, b
            quad.append(p)
        n = len(verts)
        verts += quad
        faces += [[n, n + 1, n + 2], [n, n + 2, n + 3]] if side else [[n, n + 2, n + 1], [n, n + 3, n + 2]]
    tm = trimesh.Trimesh(np.array(verts), np.array(faces), process=False,
                         face_colors=np.repeat(FACE_COLORS, 2, axis=0))
    return load_visual_mesh(tm), GridSpec((6, 6, 6), np.zeros(3), 1.0)


def _cube_expected(idx):
    """By hand: every surface voxel's center lies on the cube (coordinates 1.5 or
    4.5 on some axis); the faces it lies on are all at distance 0, and the tie
    goes to the lowest triangle index, i.e. the first face in FACES order."""
    c = idx + 0.5
    face = np.full(len(idx), -1)
    for f, (axis, side) in reversed(list(enumerate(FACES))):
        on = c[:, axis] == (4.5 if side else 1.5)
        face[on] = f
    return face


@pytest.mark.parametrize("method", ["ss-conservative", "ss-6sep", "reference-conservative"])
def test_cube_with_six_face_colours(gl_context, method):
    mesh, spec = _cube()
    g = run_method(method, mesh, spec, attributes=ALL)
    idx = g.indices()
    face = _cube_expected(idx)
    assert (face >= 0).all()
    assert np.array_equal(g.attributes["color"], FACE_COLORS[face])
    normal = np.zeros((len(idx), 3), np.float32)
    normal[np.arange(len(idx)), [FACES[f][0] for f in face]] = [1.0 if FACES[f][1] else -1.0 for f in face]
    assert np.array_equal(g.attributes["normal"], normal)
    assert np.array_equal(g.attributes["triangle"] // 2, face)  # one of the face's two triangles
    assert (g.attributes["material"] == 0).all()
    # 4^3 - 2^3 surface voxels, 24 on edges and 8 on corners: the tie rule decided those
    on_faces = ((idx + 0.5 == 1.5) | (idx + 0.5 == 4.5)).sum(axis=1)
    assert len(idx) == 56 and (on_faces == 2).sum() == 24 and (on_faces == 3).sum() == 8


def test_vertex_coloured_triangle():
    """Triangle (0,0), (8,0), (0,8) in the plane z = 0.5 with red, green, blue
    corners: a center (x, y) inside has barycentrics (1 - x/8 - y/8, x/8, y/8);
    outside the hypotenuse its closest point is the foot on x + y = 8."""
    tm = trimesh.Trimesh([[0, 0, 0.5], [8, 0, 0.5], [0, 8, 0.5]], [[0, 1, 2]], process=False,
                         vertex_colors=[[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255]])
    mesh, spec = load_visual_mesh(tm), GridSpec((8, 8, 1), np.zeros(3), 1.0)
    g = run_method("ss-conservative", mesh, spec, attributes=["color", "triangle"])
    idx = g.indices()
    x, y = idx[:, 0] + 0.5, idx[:, 1] + 0.5
    outside = x + y > 8
    fx = np.where(outside, (x - y + 8) / 2, x)
    fy = np.where(outside, (y - x + 8) / 2, y)
    expected = np.stack([1 - fx / 8 - fy / 8, fx / 8, fy / 8, np.ones_like(fx)], axis=1) * 255
    assert (g.attributes["triangle"] == 0).all()
    diff = np.abs(g.attributes["color"].astype(float) - expected)
    assert diff.max() <= 0.5 + ATTR_COLOR_TOL, diff.max()
    assert outside.any() and (~outside).any()


def _checker_quad(filter_="linear", n=8):
    """The quad [0, 8]^2 at z = 0.5, UV = (x, y) / 8, an n x n texture whose texel
    (i, j) (j counted from the bottom) has colour (256 i / n, 256 j / n, 255 * ((i + j) % 2))."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="xy")  # [row from bottom, column]
    img = np.stack([256 // n * i, 256 // n * j, 255 * ((i + j) % 2), np.full_like(i, 200)], axis=-1).astype(np.uint8)
    v = np.array([[0, 0, 0.5], [8, 0, 0.5], [8, 8, 0.5], [0, 8, 0.5]])
    mesh = glvox.load_mesh((v, np.array([[0, 1, 2], [0, 2, 3]])))
    # the Visuals a textured file would give, by hand
    uv = v[:, :2] / 8.0
    f = mesh.faces
    mesh.visuals = Visuals(np.full(2, COLOR_TEXTURE, np.uint8), np.zeros((2, 4), np.uint8),
                           np.zeros((2, 3, 4), np.uint8), uv[f], np.zeros(2, np.int32),
                           np.tile([0.0, 0.0, 1.0], (2, 3, 1)), np.zeros(2, np.int32),
                           [Texture(img[::-1].copy(), filter=filter_)])  # image rows top first
    return mesh, GridSpec((8, 8, 1), np.zeros(3), 1.0), img


@pytest.mark.parametrize("filter_", ["linear", "nearest"])
def test_textured_quad_checkerboard_aligned_with_voxels(gl_context, filter_):
    mesh, spec, img = _checker_quad(filter_)
    g = run_method("ss-conservative", mesh, spec, attributes=["color"])
    idx = g.indices()
    assert len(idx) == 64
    # voxel (i, j)'s center is texel (i, j)'s center: exactly that texel, alpha kept
    assert np.array_equal(g.attributes["color"], img[idx[:, 1], idx[:, 0]])


@pytest.mark.parametrize("filter_", ["linear", "nearest"])
def test_textured_quad_filters_between_texels(gl_context, filter_):
    """A 16 x 16 texture on the same quad: every voxel center falls on the corner
    of four texels (2i..2i+1, 2j..2j+1): bilinear averages them, nearest takes
    texel (2i + 1, 2j + 1) (GL's floor(u * 16))."""
    mesh, spec, img = _checker_quad(filter_, n=16)
    g = run_method("ss-conservative", mesh, spec, attributes=["color"])
    i, j = g.indices()[:, 0], g.indices()[:, 1]
    if filter_ == "nearest":
        expected = img[2 * j + 1, 2 * i + 1].astype(float)
    else:
        expected = sum(img[2 * j + b, 2 * i + a].astype(float) for a in (0, 1) for b in (0, 1)) / 4
    assert np.abs(g.attributes["color"] - expected).max() <= 0.5 + ATTR_COLOR_TOL


def test_reference_texture_sampling_bilinear_and_repeat():
    img = np.zeros((2, 2, 4), np.uint8)
    img[1, 0] = [255, 0, 0, 255]  # bottom-left texel (rows top first)
    tex = Texture(img)
    s = sample_texture(tex, np.array([[0.25, 0.25], [0.5, 0.25], [1.25, 0.25], [0.0, 0.25]]))
    assert np.allclose(s[0], [1, 0, 0, 1]) and np.allclose(s[1], [0.5, 0, 0, 0.5])
    assert np.allclose(s[2], s[0])  # repeat
    assert np.allclose(s[3], [0.5, 0, 0, 0.5])  # the left edge blends with the wrapped right column


def test_closest_points_match_a_brute_force_sampling():
    rng = np.random.default_rng(3)
    tris = rng.normal(size=(200, 3, 3))
    pts = rng.normal(size=(200, 3))
    d, bary = closest_points(tris, pts)
    w = rng.dirichlet(np.ones(3), size=4000)
    samples = np.einsum("sc,tcd->tsd", w, tris)
    brute = np.linalg.norm(samples - pts[:, None], axis=2).min(axis=1)
    assert (d <= brute + 1e-12).all() and (brute - d).max() < 0.05
    assert np.allclose(bary.sum(axis=1), 1.0) and (bary >= 0).all()
    assert np.allclose(np.linalg.norm(pts - np.einsum("tc,tcd->td", bary, tris), axis=1), d)


# -- real meshes: GPU against the reference ----------------------------------------

def _check_against_reference(g, mesh, normals="face"):
    spec = g.spec
    tris = gpu_vertices_voxel(mesh, spec).astype(np.float64)[mesh.faces]  # the mesh as the GPU sees it
    idx = g.indices()
    sources, ref = reference_attributes(mesh, tris, spec.dims, idx, ALL, normals)
    kept = g.attributes["triangle"]
    if mesh.source_faces is not None:
        kept = np.searchsorted(mesh.source_faces, kept)
    differ = g.attributes["triangle"] != ref["triangle"]
    ties = proven_ties(tris, spec.dims, idx, np.where(g.attributes["triangle"] >= 0, kept, -1), sources)
    assert not (differ & ~ties).any(), f"{(differ & ~ties).sum()} source triangles differ without a tie"
    same = ~differ
    dc = np.abs(g.attributes["color"].astype(int) - ref["color"].astype(int))[same]
    assert dc.max(initial=0) <= ATTR_COLOR_TOL
    dn = np.abs(g.attributes["normal"] - ref["normal"])[same]
    assert dn.max(initial=0) <= ATTR_NORMAL_TOL
    assert np.array_equal(g.attributes["material"][same], ref["material"][same])
    return differ.sum()


@pytest.mark.parametrize("n", [64, 128])
@pytest.mark.parametrize("method", ["ss-conservative", "ss-6sep"])
@pytest.mark.parametrize("name", ["textured_fuze.obj", "colored_reference.obj"])
def test_real_meshes_match_the_reference(gl_context, shared_mesh, name, method, n):
    mesh = load_visual_mesh(shared_mesh(name))
    g = run_method(method, mesh, glvox.grid_for(mesh, n), attributes=ALL, normals="vertex")
    assert (g.attributes["triangle"] >= 0).all()  # every surface voxel overlaps a triangle
    assert (g.attributes["color"][:, 3] == 255).all()
    _check_against_reference(g, mesh, "vertex")


@pytest.mark.parametrize("method", ["scanline-rlv", "scanline-slv"])
def test_scanline_surfaces_match_the_reference(gl_context, shared_mesh, method):
    mesh = load_visual_mesh(shared_mesh("textured_fuze.obj"))
    g = run_method(method, mesh, glvox.grid_for(mesh, 64), attributes=ALL)
    _check_against_reference(g, mesh)


@pytest.mark.parametrize("method", ["ss-solid", "gwn-solid", "carve-solid"])
def test_solids_carry_attributes_on_their_surface_only(gl_context, shared_mesh, method):
    mesh = load_visual_mesh(shared_mesh("textured_fuze.obj"))
    spec = glvox.grid_for(mesh, 48)
    g = run_method(method, mesh, spec, attributes=ALL)
    _check_against_reference(g, mesh)
    inner = g.attributes["triangle"] < 0
    assert inner.sum() > 1000  # a solid has an interior ...
    assert not g.attributes["color"][inner].any() and (g.attributes["material"][inner] == -1).all()
    surf = run_method("ss-conservative", mesh, spec).dense()
    assert not surf[tuple(g.indices()[inner].T)].any()  # ... and only it carries nothing


def test_fill_nearest_takes_a_nearest_surface_voxel(gl_context, shared_mesh):
    """Jump flooding is approximate: the voxel whose attributes an interior voxel
    takes is at most JFA_SLACK voxels farther than the exact nearest one (k-d tree)."""
    mesh = load_visual_mesh(shared_mesh("textured_fuze.obj"))
    spec = glvox.grid_for(mesh, 64)
    plain = run_method("gwn-solid", mesh, spec, attributes=ALL)
    g = run_method("gwn-solid", mesh, spec, attributes=ALL, fill_attributes="nearest")
    idx = g.indices()
    seeded = plain.attributes["triangle"] >= 0
    assert (g.attributes["triangle"] >= 0).all()
    assert np.array_equal(g.attributes["color"][seeded], plain.attributes["color"][seeded])
    exact = nearest_seeds(idx, seeded)
    d_exact = np.linalg.norm(idx - idx[exact], axis=1)
    # the distance to the nearest seed carrying the same triangle and colour
    key = lambda a: a["triangle"].astype(np.int64) * 2**32 + a["color"].view(np.uint32).ravel()  # noqa: E731
    kg, ks = key(g.attributes), key(plain.attributes)
    d_got = np.full(len(idx), np.inf)
    for v in np.unique(kg[~seeded]):
        rows = np.flatnonzero(~seeded & (kg == v))
        src = idx[seeded & (ks == v)]
        d_got[rows] = np.linalg.norm(idx[rows, None] - src[None], axis=2).min(axis=1)
    slack = (d_got - d_exact)[~seeded]
    print(f"jump flood: exact for {(slack <= 1e-9).mean():.4f} of the interior, worst {slack.max():.3f} voxel")
    assert slack.max() <= JFA_SLACK, slack.max()
    assert (slack <= 1e-9).mean() >= 0.999


# -- requests checked before any work ---------------------------------------------

def test_bad_requests_fail_before_work(gl_context):
    with pytest.raises(MethodError, match="unknown attribute 'colour'"):
        glvox.voxelize("gen:box", 8, attributes=["colour"])
    with pytest.raises(MethodError, match="kind 'sparse'"):
        glvox.voxelize("gen:box", 8, method="ss-octree", attributes="triangle")
    with pytest.raises(MethodError, match="carries no colours"):
        glvox.voxelize("gen:box", 8, attributes="color")
    with pytest.raises(MethodError, match="fills a solid's interior"):
        glvox.voxelize("gen:box", 8, attributes="triangle", fill_attributes="nearest")
    with pytest.raises(MethodError, match="normals must be one of"):
        glvox.voxelize("gen:box", 8, attributes="normal", normals="smooth")


def test_cli_voxelize_and_batch_write_attributes(tmp_path, shared_mesh, gl_context):
    from glvox.cli import main

    fuze = shared_mesh("textured_fuze.obj")
    out = tmp_path / "f.npz"
    assert main(["voxelize", str(fuze), "-r", "32", "--attributes", "color,triangle", "-o", str(out), "-q"]) == 0
    g = glvox.load(out)
    assert set(g.attributes) == {"color", "triangle"} and len(g.attributes["color"]) == g.count
    assert main(["voxelize", str(fuze), "-r", "32", "--attributes", "color", "-o", str(tmp_path / "f.binvox")]) == 1
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "c.obj").write_bytes(shared_mesh("colored_reference.obj").read_bytes())
    assert main(["batch", str(tmp_path / "in"), "-o", str(tmp_path / "out"), "-r", "24",
                 "--attributes", "color,material", "-q"]) == 0
    b = glvox.load(tmp_path / "out" / "c.npz")
    assert (b.attributes["color"][:, 3] == 255).all() and (b.attributes["material"] == 0).all()


# -- voxel files ------------------------------------------------------------------

def test_vti_keeps_attributes_and_vtk_reads_them(tmp_path):
    occ, g, attrs = _grid_with_attributes()
    glvox.save(g, tmp_path / "a.vti")
    back = glvox.load(tmp_path / "a.vti")
    assert np.array_equal(back.dense(), occ)
    for k, v in attrs.items():
        assert back.attributes[k].dtype == v.dtype and np.array_equal(back.attributes[k], v), k
    vtk = pytest.importorskip("vtk")
    from vtk.util.numpy_support import vtk_to_numpy

    reader = vtk.vtkXMLImageDataReader()
    reader.SetFileName(str(tmp_path / "a.vti"))
    reader.Update()
    color = vtk_to_numpy(reader.GetOutput().GetCellData().GetArray("attr_color"))
    i, j, k = np.argwhere(occ).T
    nx, ny = occ.shape[:2]
    assert np.array_equal(color[i + nx * (j + ny * k)], attrs["color"])  # VTK's cell id, x fastest


@pytest.mark.parametrize("suffix", [".nrrd", ".nii.gz"])
def test_one_array_formats_warn_that_attributes_are_dropped(tmp_path, suffix):
    pytest.importorskip("nrrd" if suffix == ".nrrd" else "nibabel")
    _, g, _ = _grid_with_attributes()
    with pytest.warns(FormatWarning, match="attributes"):
        glvox.save(g, tmp_path / f"a{suffix}")


def test_scene_parts_keep_their_own_visuals_and_input_face_ids(gl_context):
    """Two parts: a red face-coloured box (material 0) and a vertex-coloured blue
    one (material 1) placed by the scene graph; a zero-area face dropped from the
    input still counts in the triangle ids (they index the input's faces)."""
    a = trimesh.creation.box(extents=(1, 1, 1))
    a.visual.face_colors = [255, 0, 0, 255]
    b = trimesh.creation.box(extents=(1, 1, 1))
    b.visual.vertex_colors = [0, 0, 255, 255]
    scene = trimesh.Scene()
    scene.add_geometry(a, node_name="a", geom_name="a")
    scene.add_geometry(b, node_name="b", geom_name="b", transform=trimesh.transformations.translation_matrix([3, 0, 0]))
    mesh = load_visual_mesh(scene)
    g = run_method("ss-conservative", mesh, GridSpec((16, 4, 4), np.array([-0.5, -0.5, -0.5]), 0.25),
                   attributes=["color", "material", "triangle"])
    x = g.points()[:, 0]
    left, right = x < 1.0, x > 2.0
    assert left.any() and right.any() and (left | right).all()
    assert (g.attributes["material"][left] == 0).all() and (g.attributes["material"][right] == 1).all()
    assert (g.attributes["color"][left] == [255, 0, 0, 255]).all()
    assert (g.attributes["color"][right] == [0, 0, 255, 255]).all()
    assert (g.attributes["triangle"][left] < 12).all() and (g.attributes["triangle"][right] >= 12).all()

    tri = trimesh.Trimesh([[0, 0, 0.5], [8, 0, 0.5], [0, 8, 0.5]], [[0, 0, 1], [0, 1, 2]], process=False)
    flat = load_visual_mesh(tri)
    assert flat.n_degenerate == 1
    g = run_method("ss-conservative", flat, GridSpec((8, 8, 1), np.zeros(3), 1.0), attributes=["triangle"])
    assert (g.attributes["triangle"] == 1).all()


def _ridges(count=40, seed=5):
    """Roofs of two triangles meeting at a ridge below the center of voxel (2, 2, 2),
    non-dyadic coordinates: the center's closest point on both is the same ridge
    point, an exact tie however each triangle's arithmetic rounds."""
    rng = np.random.default_rng(seed)
    c = np.array([2.5, 2.5, 2.5])
    for _ in range(count):
        axis = rng.normal(size=3) * [1, 1, 0.1]
        axis /= np.linalg.norm(axis)
        up = np.cross(axis, np.cross([0, 0, 1.0], axis))
        up /= np.linalg.norm(up)
        side = np.cross(axis, up)
        m = c - rng.uniform(0.05, 0.3) * up  # the ridge passes this far below the center
        p, q = m - rng.uniform(0.2, 0.4) * axis, m + rng.uniform(0.2, 0.4) * axis
        r1 = m + rng.uniform(0.3, 0.4) * side - rng.uniform(0.3, 0.4) * up
        r2 = m - rng.uniform(0.3, 0.4) * side - rng.uniform(0.3, 0.4) * up
        yield np.array([[p, q, r1], [q, p, r2]])


def test_exact_ties_on_a_shared_edge_go_to_the_lower_index(gl_context):
    from glvox.reference.attributes import source_triangles

    spec = GridSpec((5, 5, 5), np.zeros(3), 1.0)
    for tris in _ridges():
        for order in ([0, 1], [1, 0]):
            t = tris[order]
            src = source_triangles(t, spec.dims, np.array([[2, 2, 2]]))
            assert src.triangle[0] == 0, "reference"
            g = run_method("ss-conservative", glvox.load_mesh((t.reshape(-1, 3), np.arange(6).reshape(2, 3))),
                           spec, attributes=["triangle"])
            row = np.flatnonzero((g.indices() == [2, 2, 2]).all(axis=1))
            assert g.attributes["triangle"][row[0]] == 0, "GPU"
