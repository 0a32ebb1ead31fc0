"""Exports in the voxels' own colours: MagicaVoxel .vox read back by midvoxio
(an independent reader from PyPI), coloured points and cubes read back by
trimesh.  Results carry colours as ``attributes['color']`` (M, 4) uint8, one
row per voxel of ``indices()`` (the contract of issue 21)."""

from __future__ import annotations

import numpy as np
import pytest

import glvox
from glvox.errors import FormatError
from glvox.formats import vox
from glvox.formats.colors import DEFAULT_COLOR, quantize
from glvox.grid import GridSpec
from glvox.results import VoxelGrid

midvoxio_parser = pytest.importorskip("midvoxio.parser", reason="midvoxio (the test extra) reads .vox files")


def colored(occ, spec, colors):
    """A VoxelGrid carrying ``colors`` (M, 4) uint8 as its 'color' attribute (the contract's layout)."""
    grid = VoxelGrid(np.asarray(occ, bool), spec)
    if colors is not None:
        assert colors.shape == (grid.count, 4)
        grid.set_attributes({"color": np.asarray(colors, np.uint8)})
    return grid


def random_colored(dims, seed=0, p=0.05, n_colors=None, bare=0.0):
    """A random grid on a non-round placement with random colours (``n_colors`` distinct if given)
    and a fraction ``bare`` of its voxels without colour (alpha 0)."""
    rng = np.random.default_rng(seed)
    spec = GridSpec(dims, (1.25, -3.5, 0.0625), 0.37)
    occ = rng.random(dims) < p
    m = int(occ.sum())
    if n_colors is None:
        colors = rng.integers(0, 256, (m, 4), dtype=np.uint8)
        colors[:, 3] = rng.integers(1, 256, m)
    else:
        table = rng.integers(0, 256, (n_colors, 4), dtype=np.uint8)
        table[:, 3] = 255
        colors = table[rng.integers(0, n_colors, m)]
    colors[rng.random(m) < bare, 3] = 0
    return colored(occ, spec, colors)


def read_vox(path):
    """(indices (M, 3), rgba (M, 4)) of every voxel in a .vox file, through midvoxio's parsed chunks.

    Placement as MagicaVoxel defines it (a model's voxel v lies at ``_t + v - floor(SIZE / 2)``),
    then shifted by ``floor(dims / 2)`` (the grid's dims, from the root's ``glvox_dims``) back to
    grid indices; colour c is the palette's (c - 1)-th RGBA entry (the format's specification).
    """
    v = midvoxio_parser.Parser(str(path)).parse()
    root = next(t for t in v.ntrns if t.node_id == 0)
    dims = np.array([int(s) for s in root.node_attributes["glvox_dims"].split()])
    if root.node_attributes["glvox_up"] == "y":
        dims = dims[[0, 2, 1]]
    shapes = {s.node_id: s.models[0].id for s in v.nshps}
    idx, rgba = [], []
    palette = np.array(v.palettes[0], dtype=np.uint8)
    for t in v.ntrns:
        if t.child_node_id not in shapes:
            continue
        m = shapes[t.child_node_id]
        vox_ = np.array(v.voxels[m], dtype=np.int64).reshape(-1, 4)
        shift = np.array([int(c) for c in t.frames[0]["_t"].split()]) - np.array(v.sizes[m]) // 2 + dims // 2
        idx.append(vox_[:, :3] + shift)
        rgba.append(palette[vox_[:, 3] - 1])
    idx, rgba = np.concatenate(idx), np.concatenate(rgba)
    order = np.lexsort(idx.T[::-1])
    return idx[order], rgba[order], v


# -- .vox ------------------------------------------------------------------------------------------

def test_vox_single_model_round_trip_exact_palette(tmp_path):
    """At most 255 distinct colours: one model, the same voxels, every colour exact, and the voxels
    without colour in DEFAULT_COLOR."""
    g = random_colored((37, 23, 11), n_colors=200, bare=0.1, p=0.3)
    glvox.save(g, tmp_path / "g.vox")
    idx, rgba, v = read_vox(tmp_path / "g.vox")
    assert len(v.sizes) == 1 + 1                           # one model (+ midvoxio's merged copy)
    assert tuple(v.sizes[0]) == g.dims
    np.testing.assert_array_equal(idx, g.indices())
    col = g.attributes["color"]
    has = col[:, 3] > 0
    np.testing.assert_array_equal(rgba[has], col[has])
    assert (rgba[~has] == DEFAULT_COLOR).all() and (~has).sum() > 0


def test_vox_split_into_models_placed_by_the_scene_graph(tmp_path):
    """Over 256 per axis: equal-sized models of at most 256, placed by their translations so that
    every voxel comes back at its index, once; midvoxio's own merge of the models (which reads the
    translations itself) gives back the dense grid."""
    g = random_colored((300, 9, 520), p=0.01, n_colors=50, seed=3)
    glvox.save(g, tmp_path / "big.vox")
    idx, rgba, v = read_vox(tmp_path / "big.vox")
    blocks, size = vox.model_layout(g.dims)
    assert blocks.tolist() == [2, 1, 3] and size.tolist() == [150, 9, 174]
    assert len(v.voxels) == 6 and all(tuple(s) == (150, 9, 174) for s in v.sizes[:6])
    np.testing.assert_array_equal(idx, g.indices())
    np.testing.assert_array_equal(rgba, g.attributes["color"])
    merged = v.full_vox[-1][: g.dims[0], : g.dims[1], : g.dims[2]]
    np.testing.assert_array_equal(merged != 0, g.dense())


def test_vox_up_y_turns_the_grid_upright(tmp_path):
    """up='y': glvox's +y becomes MagicaVoxel's +z, (x, y, z) = (i, nz - 1 - k, j): one voxel by hand."""
    spec = GridSpec((4, 5, 6), (0, 0, 0), 1.0)
    occ = np.zeros(spec.dims, bool)
    occ[1, 3, 0] = True
    glvox.save(colored(occ, spec, None), tmp_path / "y.vox", up="y")
    v = midvoxio_parser.Parser(str(tmp_path / "y.vox")).parse()
    assert tuple(v.sizes[0]) == (4, 6, 5)
    assert [tuple(int(c) for c in x) for x in v.voxels[0]] == [(1, 5, 3, 1)]
    assert v.palettes[0][0] == DEFAULT_COLOR                   # no colours: one entry


def test_vox_quantized_palette_nearest_and_bounded(tmp_path):
    """More than 255 colours (a smooth ramp plus noise, 4,000 distinct): at most 255 entries, each
    voxel in its nearest entry (checked by brute force), and the error pinned as measured."""
    rng = np.random.default_rng(7)
    spec = GridSpec((40, 40, 40), (0, 0, 0), 1.0)
    occ = rng.random(spec.dims) < 0.2
    ijk = np.argwhere(occ)
    ramp = np.concatenate([ijk * 6.0 + rng.normal(0, 8, ijk.shape), np.full((len(ijk), 1), 255.0)], axis=1)
    colors = np.ascontiguousarray(np.clip(np.rint(ramp), 0, 255).astype(np.uint8))
    g = colored(occ, spec, colors)
    assert len(np.unique(colors.view("<u4"))) > 4000
    glvox.save(g, tmp_path / "q.vox")
    idx, rgba, v = read_vox(tmp_path / "q.vox")
    np.testing.assert_array_equal(idx, g.indices())
    palette = np.array(v.palettes[0], np.float64)
    palette = palette[palette[:, 3] > 0]                 # the entries written (all opaque here)
    assert 200 < len(palette) <= 255
    d = np.linalg.norm(colors[:, None, :].astype(float) - palette[None], axis=2)
    got = np.linalg.norm(colors.astype(float) - rgba, axis=1)
    assert np.all(got <= d.min(axis=1) + 1e-9)
    # measured: RMS 21.2, max 53.6 (RGBA units) on this ramp, where Pillow's median cut alone (its own
    # assignment) gives RMS 32.1 and a uniform 6 x 6 x 7 palette 24.3; pinned with a little room
    assert np.sqrt(np.mean(got ** 2)) < 22.5 and got.max() < 56.0


def test_quantize_exact_up_to_the_limit_and_weighted():
    """255 distinct colours come back exact; a colour held by most voxels keeps its own entry."""
    rng = np.random.default_rng(1)
    table = rng.integers(0, 256, (255, 4), dtype=np.uint8)
    colors = table[rng.integers(0, 255, 5000)]
    palette, index = quantize(colors)
    np.testing.assert_array_equal(palette[index], colors)
    many = np.concatenate([np.tile([[10, 200, 30, 255]], (100_000, 1)),
                           rng.integers(0, 256, (3000, 4))]).astype(np.uint8)
    palette, index = quantize(many)
    assert len(palette) <= 255
    np.testing.assert_array_equal(palette[index[:100_000]], many[:100_000])


def test_vox_refusals(tmp_path):
    g = random_colored((5, 5, 5))
    with pytest.raises(FormatError, match=r"up must be one of \('z', 'y'\), got 'x'"):
        glvox.save(g, tmp_path / "a.vox", up="x")
    bad = VoxelGrid(g.dense(), g.spec)
    bad.attributes = {"color": np.zeros((g.count, 3), np.uint8)}
    with pytest.raises(FormatError, match=r"'color' attribute must be uint8 \(M, 4\) RGBA"):
        glvox.save(bad, tmp_path / "b.vox")
    with pytest.raises(FormatError, match="voxel file not found"):
        glvox.load(tmp_path / "b.vox")


# -- coloured points and cubes ---------------------------------------------------------------------

trimesh = pytest.importorskip("trimesh")

EXPORT_SPEC = GridSpec((9, 7, 5), (12.3456, -7.891, 0.123), 0.0371)


def read_geometry(path):
    """The one geometry of a PLY or GLB file, as trimesh reads it without merging vertices."""
    r = trimesh.load(str(path), process=False)
    if isinstance(r, trimesh.Scene):
        (r,) = r.geometry.values()
    return r


def f32(spec):
    return 4 * float(np.finfo(np.float32).eps) * float(np.abs(spec.bounds).max())


def hand_colored(spec=EXPORT_SPEC, seed=5):
    rng = np.random.default_rng(seed)
    occ = rng.random(spec.dims) < 0.45
    colors = rng.integers(0, 256, (int(occ.sum()), 4), dtype=np.uint8)
    colors[:, 3] = rng.integers(1, 256, len(colors))
    colors[::7, 3] = 0                                     # some voxels without a colour
    return colored(occ, spec, colors)


@pytest.mark.parametrize("suffix", [".points.ply", ".points.glb"])
def test_points_at_world_centers_in_their_colours(tmp_path, suffix):
    g = hand_colored()
    glvox.save(g, tmp_path / f"g{suffix}")
    pc = read_geometry(tmp_path / f"g{suffix}")
    ijk = np.argwhere(g.dense())
    centers = EXPORT_SPEC.origin + (ijk + 0.5) * EXPORT_SPEC.voxel_size   # by hand, not spec.centers
    np.testing.assert_allclose(pc.vertices, centers, rtol=0, atol=f32(EXPORT_SPEC))
    want = g.attributes["color"].copy()
    want[want[:, 3] == 0] = DEFAULT_COLOR
    np.testing.assert_array_equal(pc.colors, want)


def exposed_by_padding(occ):
    """(axis, sign) -> (F, 3) voxels whose neighbour that way is empty or outside: dense, by padding."""
    p = np.pad(occ, 1)
    out = {}
    for axis in range(3):
        for sign in (-1, 1):
            nb = np.roll(p, -sign, axis=axis)[1:-1, 1:-1, 1:-1]
            out[axis, sign] = np.argwhere(occ & ~nb)
    return out


@pytest.mark.parametrize("suffix", [".cubes.ply", ".cubes.glb"])
def test_cubes_are_the_exposed_faces_in_their_colours(tmp_path, suffix):
    """Every exposed face once (counted by padding the dense grid), on its voxel's face plane, wound
    outwards, all four vertices in the voxel's colour; the enclosed volume is the voxels' volume."""
    g = hand_colored()
    h, origin = EXPORT_SPEC.voxel_size, EXPORT_SPEC.origin
    glvox.save(g, tmp_path / f"g{suffix}")
    mesh = read_geometry(tmp_path / f"g{suffix}")
    expect = exposed_by_padding(g.dense())
    assert len(mesh.faces) == 2 * sum(len(v) for v in expect.values())
    tri = mesh.vertices[mesh.faces]                                        # (2F, 3, 3)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    axis = np.argmax(np.abs(normal), axis=1)
    sign = np.sign(normal[np.arange(len(normal)), axis]).astype(int)
    # the voxel behind each face: its centroid moved half a voxel against the normal
    inner = tri.mean(axis=1) - 0.5 * h * np.eye(3)[axis] * sign[:, None]
    voxel = np.floor((inner - origin) / h).astype(int)
    rows = {tuple(v): r for r, v in enumerate(np.argwhere(g.dense()))}
    want = g.attributes["color"].copy()
    want[want[:, 3] == 0] = DEFAULT_COLOR
    got_faces = {}
    for f in range(len(mesh.faces)):
        key = (int(axis[f]), int(sign[f]))
        got_faces.setdefault(key, set()).add(tuple(voxel[f]))
        np.testing.assert_array_equal(mesh.visual.vertex_colors[mesh.faces[f]],
                                      np.repeat(want[rows[tuple(voxel[f])]][None], 3, axis=0))
    for key, vox_ in expect.items():
        assert got_faces[key] == {tuple(v) for v in vox_}
    assert mesh.volume == pytest.approx(g.count * h ** 3, rel=1e-5)


def test_points_and_cubes_refusals(tmp_path):
    g = hand_colored()
    with pytest.raises(FormatError, match=r"unknown voxel file suffix '\.ply'"):
        glvox.save(g, tmp_path / "g.ply")                   # .ply alone stays a mesh suffix
    with pytest.raises(FormatError, match="does not read it"):
        glvox.load(tmp_path / "g.cubes.ply")


# -- reading .vox ----------------------------------------------------------------------------------

@pytest.mark.parametrize("dims, up", [((300, 9, 520), "z"), ((30, 40, 50), "y"), ((7, 300, 9), "y")])
def test_vox_reads_back_onto_its_grid(tmp_path, dims, up):
    g = random_colored(dims, p=0.02, n_colors=120, bare=0.05, seed=sum(dims))
    glvox.save(g, tmp_path / "g.vox", up=up)
    back = glvox.load(tmp_path / "g.vox")
    assert back.dims == g.dims and back.spec.same_placement(g.spec) and back.equal(g)
    want = g.attributes["color"].copy()
    want[want[:, 3] == 0] = DEFAULT_COLOR
    np.testing.assert_array_equal(back.attributes["color"], want)


def test_vox_reads_a_file_midvoxio_wrote(tmp_path):
    """midvoxio's ArrayWriter (an independent writer: one model, no scene graph, every cell listed with
    index 0 for empty): the voxels in the scene's units, the grid their bounding box, their colours."""
    from midvoxio.voxio import write_list_to_vox

    rng = np.random.default_rng(4)
    palette = rng.integers(0, 256, (256, 4)).astype(np.uint8)
    palette[:, 3] = 255
    palette = np.unique(palette, axis=0)[:200]
    arr = np.zeros((6, 5, 4, 4))
    cells = [(1, 1, 1), (4, 2, 3), (2, 4, 1), (3, 3, 2)]
    for n, c in enumerate(cells):
        arr[c] = (palette[10 * n] + 0.5) / 255.0          # midvoxio truncates value * 255 to uint8
    # its writer maps a cell to the last entry equal to its colour: no all-zero entry (empty cells are zero)
    filler = np.tile(np.array([[1, 2, 3, 255]], np.uint8), (256 - len(palette), 1))
    write_list_to_vox(arr, str(tmp_path / "m.vox"), palette_arr=np.concatenate([palette, filler]))
    back = glvox.load(tmp_path / "m.vox")
    lo = np.array(cells).min(axis=0)
    assert back.voxel_size == 1.0 and back.dims == tuple(np.array(cells).max(axis=0) - lo + 1)
    np.testing.assert_array_equal(back.origin, lo - np.array(arr.shape[:3]) // 2)  # MagicaVoxel's pivot
    np.testing.assert_array_equal(back.indices(), np.array(sorted(cells)) - lo)
    by_cell = {c: palette[10 * n] for n, c in enumerate(cells)}
    np.testing.assert_array_equal(back.attributes["color"], [by_cell[c] for c in sorted(cells)])


def test_vox_read_refusals(tmp_path, monkeypatch):
    g = random_colored((5, 6, 7), p=0.5)
    data = vox.vox_bytes(g)
    (tmp_path / "cut.vox").write_bytes(data[: len(data) // 2])
    with pytest.raises(FormatError, match=r"cut.vox: (a broken \.vox file|the \.vox chunk .* runs past)"):
        glvox.load(tmp_path / "cut.vox")
    (tmp_path / "png.vox").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(40))
    with pytest.raises(FormatError, match=r"png.vox: not a MagicaVoxel \.vox file"):
        glvox.load(tmp_path / "png.vox")
    plain = vox._dict
    monkeypatch.setattr(vox, "_dict", lambda d: plain({**d, "_r": "17"} if "_t" in d else d))
    (tmp_path / "rot.vox").write_bytes(vox.vox_bytes(g))   # every model turned (a rotation byte of 17)
    with pytest.raises(FormatError, match=r"translated, not rotated \(node 2 has rotation 17\)"):
        glvox.load(tmp_path / "rot.vox")


def test_render_command_draws_a_vox_file_in_its_colours(tmp_path):
    """End to end through the command line: a .vox file's colours on the picture (unlit)."""
    import subprocess
    import sys

    pytest.importorskip("matplotlib")
    import matplotlib.image

    spec = GridSpec((2, 1, 1), (0, 0, 0), 1.0)
    glvox.save(colored(np.ones(spec.dims), spec, np.array([[250, 20, 20, 255], [20, 20, 250, 255]], np.uint8)),
               tmp_path / "two.vox")
    p = subprocess.run([sys.executable, "-m", "glvox", "render", tmp_path / "two.vox", "-o", tmp_path / "two.png",
                        "--size", "120", "60", "--direction", "0", "0", "1", "--flat", "-q"],
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    img = (matplotlib.image.imread(tmp_path / "two.png")[..., :3] * 255).round().astype(int)
    ys, xs = np.nonzero((img != 255).any(axis=-1))
    y, x0, x1 = (ys.min() + ys.max()) // 2, xs.min(), xs.max() + 1
    assert img[y, x0 + (x1 - x0) // 4].tolist() == [250, 20, 20]      # voxel (0, 0, 0) on the left
    assert img[y, x0 + 3 * (x1 - x0) // 4].tolist() == [20, 20, 250]


def test_vox_empty_grid_and_octree(tmp_path):
    """An empty grid writes one empty model and reads back empty on its grid; an octree is decoded."""
    spec = GridSpec((300, 4, 5), (0.5, -1.0, 2.0), 0.25)
    glvox.save(VoxelGrid(np.zeros(spec.dims, bool), spec), tmp_path / "empty.vox")
    back = glvox.load(tmp_path / "empty.vox")
    assert back.count == 0 and back.dims == spec.dims and back.spec.same_placement(spec)
    o = glvox.voxelize("gen:box", 12, method="ss-octree")
    glvox.save(o, tmp_path / "o.vox")
    assert glvox.load(tmp_path / "o.vox").equal(o.to_grid())


# -- from a coloured mesh, as a user runs it ----------------------------------------------------------

def test_mesh_colours_reach_a_vox_through_the_cli(tmp_path, shared_mesh, gl_context, capsys):
    """glvox voxelize --attributes color -o x.vox: midvoxio reads the voxels glvox set, each in
    its palette colour within the quantization of the mesh's own colours; attributes .vox cannot
    hold are refused before any work, naming them."""
    from glvox.cli import main

    mesh = shared_mesh("colored_reference.obj")
    out = tmp_path / "c.vox"
    assert main(["voxelize", str(mesh), "-r", "40", "--attributes", "color", "-o", str(out), "-q"]) == 0
    g = glvox.voxelize(mesh, 40, attributes="color")
    idx, rgba, v = read_vox(out)
    assert np.array_equal(idx, g.indices())
    want = g.attributes["color"].astype(np.float64)
    # quantize's promise, checked on the file's own palette: each voxel's entry is the nearest to its colour
    palette = np.array(v.palettes[0], dtype=np.float64)[:255]
    nearest = np.sqrt(((palette[None] - want[:, None]) ** 2).sum(2)).min(1)
    assert np.allclose(np.sqrt(((rgba - want) ** 2).sum(1)), nearest)
    assert len(np.unique(g.attributes["color"].view("<u4"))) > 255  # the quantized case, not the exact one
    capsys.readouterr()
    assert main(["voxelize", str(mesh), "-r", "8", "--attributes", "color,normal", "-o", str(tmp_path / "n.vox")]) == 1
    err = capsys.readouterr().err.strip()
    assert err == ("glvox: error: n.vox would drop the attributes ['normal']: .npz and .vti keep every attribute, "
                   ".vox, .points.* and .cubes.* the colour only")
    assert not (tmp_path / "n.vox").exists()
