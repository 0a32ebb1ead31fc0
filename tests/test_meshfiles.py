"""The fast mesh readers (glvox.meshfiles) and the numpy watertight check give trimesh's answers.

The independent expectation is trimesh itself: ``trimesh.load(path,
process=False)`` for the arrays (what glvox loaded before the fast path) and
``Trimesh(..., process=True).is_watertight`` for closedness.
"""

from __future__ import annotations

import io

import numpy as np
import pytest
import trimesh

from conftest import SHARED_MESHES
from glvox.mesh import _row_labels, is_watertight, load_mesh
from glvox.meshfiles import read_fast
from glvox.testing.datasets import synthetic_dataset

#: Shared meshes outside the fast path (trimesh reads them): texture
#: coordinates, normals, polygons and line continuations.
SLOW_PATH = {"messy_wallhole.obj"}


def _trimesh_arrays(path_or_bytes, suffix=None):
    src = io.BytesIO(path_or_bytes) if isinstance(path_or_bytes, bytes) else str(path_or_bytes)
    m = trimesh.load(src, file_type=suffix, process=False, skip_materials=True)
    return np.asarray(m.vertices), np.asarray(m.faces)


def _assert_same(fast, expected):
    assert fast is not None, "the fast path declined a file it should read"
    v, f = fast
    assert v.dtype == np.float64 and f.dtype == np.int64
    np.testing.assert_array_equal(v, expected[0])
    np.testing.assert_array_equal(f, expected[1])


@pytest.mark.parametrize("name", SHARED_MESHES)
def test_shared_meshes_read_as_trimesh_reads_them(name, shared_mesh):
    path = shared_mesh(name)
    fast = read_fast(path.suffix[1:].lower(), path.read_bytes())
    if name in SLOW_PATH:
        assert fast is None
    else:
        _assert_same(fast, _trimesh_arrays(path))


def _tet(vertices=None):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float) if vertices is None else vertices
    return trimesh.Trimesh(v, [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], process=False)


#: Values whose float32 rounding differs from float64 (0.1) and exponent notation.
ODD = np.array([[0.1, -2.5e-7, 3.0], [1e5, 0.3333333333333333, -0.0], [7.0, 1.25e-12, 2.0], [0.2, 0.7, 9.9]])


@pytest.mark.parametrize("file_type", ["ply", "stl", "stl_ascii", "off", "obj"])
def test_exported_files_read_as_trimesh_reads_them(file_type):
    mesh = trimesh.creation.icosphere(2)
    mesh.vertices[:4] = ODD
    data = mesh.export(file_type=file_type)
    data = data.encode() if isinstance(data, str) else data
    suffix = file_type.split("_")[0]
    _assert_same(read_fast(suffix, data), _trimesh_arrays(data, suffix))


def _ply_text(fmt: str, vertex_props: str, vertex_rows: bytes, faces: bytes, nv: int, nf: int) -> bytes:
    return (f"ply\nformat {fmt} 1.0\ncomment made by hand\nelement vertex {nv}\n{vertex_props}"
            f"element face {nf}\nproperty list uchar int vertex_indices\nend_header\n").encode() \
        + vertex_rows + faces


def test_ascii_ply_rounds_float_properties_through_float32_like_trimesh():
    props = "property float x\nproperty float y\nproperty float z\nproperty float confidence\n"
    rows = b"".join(f"{x!r} {y!r} {z!r} 0.5\n".encode() for x, y, z in ODD.tolist())
    data = _ply_text("ascii", props, rows, b"3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n", 4, 4)
    fast = read_fast("ply", data)
    _assert_same(fast, _trimesh_arrays(data, "ply"))
    assert fast[0][0, 0] == np.float64(np.float32(0.1)) != 0.1


def test_big_endian_binary_ply():
    v = ODD.astype(">f4")
    faces = np.zeros(4, dtype=[("n", "u1"), ("i", ">i4", (3,))])
    faces["n"] = 3
    faces["i"] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
    data = _ply_text("binary_big_endian", "property float x\nproperty float y\nproperty float z\n",
                     v.tobytes(), faces.tobytes(), 4, 4)
    _assert_same(read_fast("ply", data), _trimesh_arrays(data, "ply"))


def test_obj_keeps_only_referenced_vertices_in_file_order_like_trimesh():
    data = b"# c\nv 0 0 0\nv 9 9 9\no part\nv 1 0 0\n\nv 0 1 0\nv 0 0 1\ns 1\nf 1 3 4\nf 1 4 5\nf 1 5 3\nf 3 5 4\n"
    fast = read_fast("obj", data)
    _assert_same(fast, _trimesh_arrays(data, "obj"))
    assert len(fast[0]) == 4  # the unreferenced (9, 9, 9) is gone, as in trimesh


@pytest.mark.parametrize("suffix, data", [
    ("obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3\n"),                    # a quad
    ("obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n"),                 # texture indices
    ("obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nv 0 0 1\nf 1 2 4\n"),             # interleaved blocks
    ("obj", b"v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n"),                       # CRLF
    ("obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -1\n"),                              # relative index
    ("obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n"),                               # one past the end
    ("obj", b"v 0 0 0 1 0 0\nv 1 0 0 1 0 0\nv 0 1 0 1 0 0\nf 1 2 3\n"),             # vertex colors
    ("obj", b"mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n"),       # materials
    ("off", b"OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 3 2\n"),                # a quad
    ("off", b"OFF\n3 1 0\n0 0 0 255 0 0\n1 0 0 255 0 0\n0 1 0 255 0 0\n3 0 1 2\n"), # colors
    ("off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"),                         # one past the end
    ("stl", b"solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
            b"endloop\nendfacet\nendsolid a\nsolid b\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
            b"vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid b\n"),         # two solids
    ("ply", b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
            b"element face 1\nproperty list uchar int vertex_indices\nend_header\n"
            b"0 0 0\n1 0 0\n0 1 0\n1 1 0\n4 0 1 3 2\n"),                              # a quad
    ("ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            b"element face 1\nproperty list uchar int vertex_indices\nend_header\n"
            b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n"),                              # more than declared

    ("ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            b"element face 1\nproperty list uchar int vertex_indices\nend_header\n"
            b"0 0 0\n\n1 0 0\n0 1 0\n3 0 1 2\n"),                                   # a blank vertex line
    ("ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            b"element face 1\nproperty list uchar int vertex_indices\nend_header\n"
            b"0 0 0\n1 0\n0 1 0 0\n3 0 1 2\n"),                                      # ragged vertex rows
    ("stl", b"solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0 1\nvertex 1 0 0 1\nvertex 0 1 0 1\n"
            b"endloop\nendfacet\nendsolid a\n"),                                       # 4 numbers a vertex
    ("stl", b"solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 x\n"
            b"endloop\nendfacet\nendsolid a\n"),                                       # not a number
    ("stl", b"solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex\nvertex 0 1 0\n"
            b"endloop\nendfacet\nendsolid a\n"),                                       # an empty vertex line
])
def test_layouts_outside_the_fast_path_are_left_to_trimesh(suffix, data):
    assert read_fast(suffix, data) is None


def test_watertight_is_decided_on_first_read_only(shared_mesh):
    """Loading for a surface does not pay for the closedness verdict; reading it decides it once."""
    m = load_mesh(shared_mesh("stanford_bunny_bun_zipper.ply"))
    assert "watertight" not in vars(m)
    assert m.watertight is False and vars(m)["watertight"] is False


def test_a_file_outside_the_fast_path_still_loads_through_trimesh(tmp_path):
    p = tmp_path / "quad.obj"
    p.write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3\n")
    m = load_mesh(p)
    assert m.n_triangles == 2 and len(m.vertices) == 4


# -- watertight -------------------------------------------------------------------
def _trimesh_watertight(v, f) -> bool:
    return bool(trimesh.Trimesh(vertices=v, faces=f, process=True, validate=False).is_watertight)


@pytest.mark.parametrize("name", SHARED_MESHES)
def test_watertight_agrees_with_trimesh_on_shared_meshes(name, shared_mesh):
    m = load_mesh(shared_mesh(name))
    assert m.watertight == _trimesh_watertight(m.vertices, m.faces)


def test_synthetic_batch_meshes_load_with_the_same_verdicts(tmp_path):
    """Closedness as generated (and as trimesh judges it); each broken file refused for its reason."""
    seen = set()
    for rel, info in synthetic_dataset(tmp_path, 28).items():
        if info["broken"]:
            with pytest.raises(Exception) as exc:
                load_mesh(tmp_path / rel)
            assert type(exc.value).__name__ == info["broken"], rel
            continue
        m = load_mesh(tmp_path / rel)
        assert m.watertight == info["watertight"] == _trimesh_watertight(m.vertices, m.faces), rel
        seen.add((rel.rsplit(".", 1)[1], m.watertight))
    assert {s for s, _ in seen} == {"stl", "obj", "ply", "off"} and {w for _, w in seen} == {True, False}


def test_watertight_hand_cases():
    tet = _tet()
    v, f = np.asarray(tet.vertices), np.asarray(tet.faces)
    assert is_watertight(v, f)
    assert not is_watertight(v, f[:3])                      # a boundary
    soup = v[f].reshape(-1, 3)                               # STL-like: every corner its own vertex
    assert is_watertight(soup, np.arange(12).reshape(4, 3))
    near = soup.copy()
    near[5] += 3e-9                                          # merged at trimesh's 1e-8 rounding
    assert is_watertight(near, np.arange(12).reshape(4, 3)) and _trimesh_watertight(near, np.arange(12).reshape(4, 3))
    apart = soup.copy()
    apart[5] += 1e-6                                         # not merged: an open seam
    assert not is_watertight(apart, np.arange(12).reshape(4, 3))
    # two tetrahedra sharing an edge: that edge has four faces
    v2 = np.vstack([v, [[1, 1, 1], [0.9, 0.2, 0.9]]])
    f2 = np.vstack([f, [[0, 1, 4], [0, 4, 5], [1, 5, 4], [0, 5, 1]]])
    assert not is_watertight(v2, f2) and not _trimesh_watertight(v2, f2)


def test_row_labels_survive_a_hash_collision():
    b = np.uint64(0xC2B2AE3D27D4EB4F).view(np.int64)
    keys = np.array([[0, 1, 0], [0, 0, b], [0, 1, 0], [5, 5, 5]], dtype=np.int64)  # rows 0 and 1 share a hash
    labels = _row_labels(keys)
    assert labels[0] == labels[2] and len({labels[0], labels[1], labels[3]}) == 3
    rng = np.random.default_rng(0)
    rows = rng.integers(-3, 3, size=(500, 3))
    _, expected = np.unique(rows, axis=0, return_inverse=True)
    got = _row_labels(rows)
    assert np.array_equal(got[:, None] == got[None, :], expected.ravel()[:, None] == expected.ravel()[None, :])
