"""Mesh input: every accepted form, and one clear error per kind of bad input."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import glvox
from glvox.errors import (EmptyMeshError, FaceIndexError, LimitError, MeshError, MeshLoadError, NonFiniteVertexError,
                          NotWatertightError)
from glvox.mesh import DEGENERATE_AREA_RTOL, generated_mesh, load_mesh

TET_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
TET_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def test_arrays_trimesh_and_path_agree(tmp_path):
    a = load_mesh((TET_V, TET_F))
    b = load_mesh(trimesh.Trimesh(TET_V, TET_F, process=False))
    p = tmp_path / "tet.obj"
    trimesh.Trimesh(TET_V, TET_F, process=False).export(p)
    c = load_mesh(p)
    for m in (a, b, c):
        assert m.n_triangles == 4 and m.watertight
        np.testing.assert_allclose(m.triangles(), TET_V[TET_F])
    assert c.name == "tet.obj"


def test_shared_mesh_loads(shared_mesh):
    m = load_mesh(shared_mesh("stanford_armadillo_libigl_86k.obj"))
    assert m.n_triangles == 86482 and m.watertight
    bunny = load_mesh(shared_mesh("stanford_bunny_bun_zipper.ply"))
    assert not bunny.watertight  # open at the base (SOURCES.md)


def test_missing_file(tmp_path):
    with pytest.raises(MeshLoadError, match=r"mesh file not found: .*nothing\.stl"):
        load_mesh(tmp_path / "nothing.stl")


def test_the_face_takes_generated_meshes_and_refuses_unknown_names_as_the_command_line(tmp_path, monkeypatch,
                                                                                      capsys):
    from glvox.cli import main as cli_main
    from glvox.errors import DatasetError, MeshNotFoundError

    np.testing.assert_array_equal(glvox.load_mesh("gen:torus").triangles(), generated_mesh("torus").triangles())
    monkeypatch.chdir(tmp_path)
    with pytest.raises(MeshNotFoundError) as err:
        glvox.load_mesh("no_such_mesh.ply")
    assert isinstance(err.value, MeshLoadError) and isinstance(err.value, DatasetError)
    assert str(err.value) == ("mesh file not found: no_such_mesh.ply (nor is it a mesh name glvox knows: "
                              "`glvox data list`)")
    assert cli_main(["voxelize", "no_such_mesh.ply"]) == 1
    assert capsys.readouterr().err == f"glvox: error: {err.value}\n"
    with pytest.raises(MeshNotFoundError, match=r"^mesh file not found: no_such_mesh.ply \(nor is it"):
        glvox.voxelize("no_such_mesh.ply", 8, attributes="color")


def test_the_face_takes_the_mesh_names_glvox_knows(tmp_path, monkeypatch, shared_mesh):
    """glvox.load_mesh, voxelize and inspect_mesh: a name of `glvox data list`, found through
    GLVOX_MESHES (never downloaded here), is the mesh of that file."""
    bunny_file = shared_mesh("stanford_bunny_bun_zipper.ply")
    monkeypatch.setenv("GLVOX_MESHES", str(bunny_file.parent))
    monkeypatch.chdir(tmp_path)  # no file of that name here: the name is looked up
    by_name = glvox.load_mesh("stanford_bunny_bun_zipper.ply")
    by_file = load_mesh(bunny_file)
    assert by_name.name == by_file.name == "stanford_bunny_bun_zipper.ply"
    np.testing.assert_array_equal(by_name.triangles(), by_file.triangles())
    assert glvox.voxelize("stanford_bunny_bun_zipper.ply", 8, method="reference-conservative").count > 0
    assert glvox.inspect_mesh("stanford_bunny_bun_zipper.ply").triangles == by_file.n_triangles


def test_inspect_takes_a_mesh_name(tmp_path, monkeypatch, shared_mesh):
    """`glvox inspect NAME`: the name its checks accept is the name it loads."""
    import subprocess
    import sys

    bunny_file = shared_mesh("stanford_bunny_bun_zipper.ply")
    env = {**__import__("os").environ, "GLVOX_MESHES": str(bunny_file.parent)}
    p = subprocess.run([sys.executable, "-m", "glvox", "inspect", "stanford_bunny_bun_zipper.ply", "--json"],
                       capture_output=True, text=True, cwd=tmp_path, env=env, timeout=600)
    assert p.returncode == 0, p.stderr
    assert '"triangles": 69451' in p.stdout


def test_directory_is_not_a_mesh(tmp_path):
    with pytest.raises(MeshLoadError, match="mesh path is a directory"):
        load_mesh(tmp_path)


def test_empty_file(tmp_path):
    p = tmp_path / "empty.obj"
    p.write_bytes(b"")
    with pytest.raises(EmptyMeshError, match=r"mesh file is empty \(0 bytes\)"):
        load_mesh(p)


def test_garbage_and_wrong_suffix(tmp_path):
    p = tmp_path / "garbage.stl"
    p.write_bytes(bytes(range(256)) * 3)
    with pytest.raises(MeshError, match=r"garbage\.stl"):
        load_mesh(p)
    q = tmp_path / "mesh.xyz123"
    q.write_text("v 0 0 0\n")
    with pytest.raises(MeshLoadError, match=r"could not read mesh file .*mesh\.xyz123"):
        load_mesh(q)


def test_truncated_binary_stl(tmp_path, shared_mesh):
    data = shared_mesh("cad_featuretype.stl").read_bytes()
    p = tmp_path / "truncated.stl"
    p.write_bytes(data[: len(data) // 3])
    with pytest.raises(MeshLoadError, match=r"binary STL is truncated: .*truncated\.stl declares 3476 triangles"):
        load_mesh(p)


def test_obj_without_faces(tmp_path):
    p = tmp_path / "points.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(MeshError, match="points.obj"):
        load_mesh(p)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_vertices(bad):
    v = TET_V.copy()
    v[2, 1] = bad
    with pytest.raises(NonFiniteVertexError, match=r"1 vertices have NaN or infinite coordinates \(first: vertex 2"):
        load_mesh((v, TET_F))


def test_non_finite_unreferenced_vertex_is_ignored():
    v = np.vstack([TET_V, [[np.nan, 0, 0]], [[1e6, -1e6, 0]]])
    m = load_mesh((v, TET_F))
    assert m.n_triangles == 4
    # bounds (and the anchor, and the rows ss-solid fills) come from referenced vertices only
    np.testing.assert_array_equal(m.bounds, [TET_V.min(axis=0), TET_V.max(axis=0)])


def test_face_index_out_of_range():
    f = TET_F.copy()
    f[3, 2] = 9
    with pytest.raises(FaceIndexError, match=r"1 faces index vertices outside \[0, 3\] \(first: face 3 = \[1, 2, 9\]\)"):
        load_mesh((TET_V, f))
    f[3, 2] = -1
    with pytest.raises(FaceIndexError, match="outside"):
        load_mesh((TET_V, f))


def test_face_shape():
    with pytest.raises(FaceIndexError, match=r"faces must have shape \(F, 3\) \(triangles\), got \(2, 4\)"):
        load_mesh((TET_V, np.array([[0, 1, 2, 3], [0, 1, 2, 3]])))
    with pytest.raises(MeshError, match=r"vertices must have shape \(V, 3\), got \(4, 2\)"):
        load_mesh((TET_V[:, :2], TET_F))


def test_empty_mesh():
    with pytest.raises(EmptyMeshError, match="the mesh has no triangles"):
        load_mesh((TET_V, np.zeros((0, 3), int)))


def test_zero_area_triangles_are_dropped_and_counted():
    v = np.vstack([TET_V, [[0.5, 0.5, 0.0], [2, 2, 0]]])
    f = np.vstack([TET_F, [[0, 0, 1], [0, 4, 5]]])  # repeated vertex; collinear (0,0,0),(.5,.5,0),(2,2,0)
    m = load_mesh((v, f))
    assert m.n_degenerate == 2 and m.n_triangles == 4
    # a needle that is thin but not zero-area stays
    needle = np.vstack([TET_V, [[0.5, 0.5, 1e-6]]])
    m2 = load_mesh((needle, np.vstack([TET_F, [[0, 4, 1]]])))
    assert m2.n_degenerate == 0
    assert DEGENERATE_AREA_RTOL < 1e-6


def test_all_degenerate_is_empty():
    with pytest.raises(EmptyMeshError, match="all 1 triangles have zero area"):
        load_mesh((TET_V, np.array([[0, 1, 1]])))


def test_unknown_input_type():
    with pytest.raises(MeshError, match="mesh must be a file path, a trimesh.Trimesh or a \\(vertices, faces\\) pair, got int"):
        load_mesh(42)


def test_generated_meshes_are_closed():
    for name in ("torus", "sphere", "box", "bunny-like"):
        assert generated_mesh(name).watertight, name
    with pytest.raises(MeshLoadError, match="unknown generated mesh 'gen:cow'"):
        load_mesh("gen:cow")


def test_solid_methods_refuse_open_meshes_unless_allowed():
    open_mesh = (TET_V, TET_F[:3])
    m = load_mesh(open_mesh)
    assert not m.watertight
    with pytest.raises(NotWatertightError, match=r"is not watertight.*allow_open=True"):
        glvox.voxelize(open_mesh, 8, method="reference-solid")
    g = glvox.voxelize(open_mesh, 8, method="reference-solid", allow_open=True)
    assert g.run.stats["watertight"] is False
    # surface methods do not care
    assert glvox.voxelize(open_mesh, 8, method="reference-conservative").count > 0


def test_far_from_origin_vertices_are_kept_precise():
    m = load_mesh((TET_V + 1e6, TET_F))
    v32, _ = m.gpu_arrays()
    assert v32.dtype == np.float32
    np.testing.assert_allclose(v32 + m.anchor, m.vertices, atol=1e-6)


def test_multi_part_file_is_placed_by_the_scene_graph(tmp_path):
    a = trimesh.creation.box(extents=(1, 1, 1))
    b = trimesh.creation.icosphere(1)
    scene = trimesh.Scene()
    scene.add_geometry(a, node_name="a")
    shift = np.eye(4)
    shift[:3, 3] = [10.0, 0.0, 0.0]
    scene.add_geometry(b, node_name="b", transform=shift)
    p = tmp_path / "parts.glb"
    scene.export(p)
    m = load_mesh(p)
    assert m.n_triangles == len(a.faces) + len(b.faces)
    np.testing.assert_allclose(m.bounds, [[-0.5, -1.0, -1.0], [11.0, 1.0, 1.0]], atol=1e-6)


def test_textured_obj_loads_without_pillow(shared_mesh):
    m = load_mesh(shared_mesh("messy_wallhole.obj"))  # mtllib and texture coordinates
    assert m.n_triangles + m.n_degenerate == 66 and m.n_degenerate == 11  # SOURCES.md: 11 zero-area faces


def test_text_mesh_that_is_not_utf8_reads_the_same_without_chardet(tmp_path, monkeypatch):
    """trimesh guesses a non-UTF-8 text file's encoding with chardet when it is
    installed and raises ImportError when not (a fresh install): glvox decodes
    itself then, so the error is the same either way."""
    import trimesh

    p = tmp_path / "garbage.obj"
    p.write_bytes(bytes(np.random.default_rng(3).integers(128, 256, 4000, dtype=np.uint8)))
    real = trimesh.load

    def no_chardet(obj, *args, **kwargs):
        if isinstance(obj, str):
            raise ModuleNotFoundError("No module named 'chardet'")
        return real(obj, *args, **kwargs)

    monkeypatch.setattr(trimesh, "load", no_chardet)
    with pytest.raises(EmptyMeshError, match=r"garbage\.obj holds no triangles"):
        load_mesh(p)
    q = tmp_path / "ok.obj"
    q.write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n# \xff\xfe not utf-8\n")
    assert load_mesh(q).n_triangles == 1


def test_face_index_past_the_vertices_of_an_obj_file(tmp_path):
    """trimesh's OBJ reader fails with numpy's words; glvox says which file and what is wrong."""
    path = tmp_path / "bad_index.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\n")
    with pytest.raises(FaceIndexError) as e:
        load_mesh(path)
    assert str(e.value) == (f"could not read mesh file {path}: a face refers to a vertex the file does not "
                            f"have (it has 3 vertices)")


def test_coordinates_near_the_float64_limit():
    """A span past 1.8e308 is refused by name; a span of 1e307 is a valid mesh (its areas do not
    overflow), which GPU methods refuse because float32 vertices would be infinite, and the float64
    references voxelize."""
    faces = np.array([[0, 1, 2], [0, 1, 3]])
    huge = np.array([[0, 0, 0], [1e308, 0, 0], [0, 1e308, 0], [-1e308, -1e308, 1.0]])
    with pytest.raises(NonFiniteVertexError, match="the coordinates span more than a float64 holds"):
        load_mesh((huge, faces))
    big = np.array([[0, 0, 0], [1e307, 0, 0], [0, 1e307, 0], [2e307, 0, 0]])
    m = load_mesh((big, np.array([[0, 1, 2], [0, 1, 3]])))   # the second is a line: zero area
    assert m.n_triangles == 1 and m.n_degenerate == 1
    # areas are relative to the extent: a mesh 1e-9 across is as valid as one 1e307 across
    assert load_mesh((big * 1e-316, faces[:1])).n_degenerate == 0
    one = load_mesh((big[:3], faces[:1]))
    with pytest.raises(LimitError, match=r"coordinates reach 5e\+306 from the mesh's center, beyond the float32"):
        glvox.voxelize(one, 8)
    # the scaled copy's reference surface, placed on the same relative grid, is the same voxels
    ref = glvox.voxelize(one, 8, method="reference-conservative")
    small = glvox.voxelize(load_mesh((big[:3] / 1e306, faces[:1])), 8, method="reference-conservative")
    assert ref.count > 0 and np.array_equal(ref.dense(), small.dense())
