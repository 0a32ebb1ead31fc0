"""glvox inspect: mesh defects on hand-made meshes with known counts, and against trimesh."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh
from conftest import SHARED_MESHES

import glvox
from glvox import inspect as gi
from glvox.cli import main
from glvox.inspect import inspect_mesh

TETRA_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
TETRA_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])  # outward


def test_closed_tetrahedron_and_its_flips():
    r = inspect_mesh((TETRA_V, TETRA_F))
    assert (r.triangles, r.vertices, r.components, r.boundary_edges, r.nonmanifold_edges) == (4, 4, 1, 0, 0)
    assert r.watertight and r.winding_consistent and r.inconsistent_edges == 0
    assert r.signed_volume == pytest.approx(1 / 6, abs=1e-15) and r.orientation == "outward"
    assert r.duplicate_faces == r.degenerate_faces == r.self_intersections == 0
    inside_out = inspect_mesh((TETRA_V, TETRA_F[:, ::-1]))
    assert inside_out.signed_volume == pytest.approx(-1 / 6, abs=1e-15) and inside_out.orientation == "inward"
    assert inside_out.winding_consistent
    one = TETRA_F.copy()
    one[3] = one[3, ::-1]  # one face flipped: its three edges run the same way as their neighbours'
    r = inspect_mesh((TETRA_V, one))
    assert r.inconsistent_edges == 3 and not r.winding_consistent and r.watertight


def test_holes_parts_duplicates_degenerates():
    open_tet = inspect_mesh((TETRA_V, TETRA_F[:3]))
    assert open_tet.boundary_edges == 3 and not open_tet.watertight and open_tet.components == 1
    two = np.concatenate([TETRA_V, TETRA_V + 5])
    r = inspect_mesh((two, np.concatenate([TETRA_F, TETRA_F + 4])))
    assert r.components == 2 and r.watertight
    # a face repeated (any vertex order): three edges of three faces each
    dup = inspect_mesh((TETRA_V, np.concatenate([TETRA_F, [TETRA_F[1][[1, 2, 0]]]])))
    assert dup.duplicate_faces == 1 and dup.nonmanifold_edges == 3
    # a zero-area face (repeated vertex) is dropped on load and counted
    deg = inspect_mesh((TETRA_V, np.concatenate([TETRA_F, [[0, 1, 1]]])))
    assert deg.degenerate_faces == 1 and deg.triangles == 4
    # two tetrahedra sharing one edge: that edge has four faces; the bodies are separate parts
    v = np.concatenate([TETRA_V, [[1, 1, 0], [1, 1, 1]]])
    other = np.array([[1, 4, 2], [1, 5, 4], [4, 5, 2], [2, 5, 1]])
    r = inspect_mesh((v, np.concatenate([TETRA_F, other])))
    assert r.nonmanifold_edges == 1 and r.components == 2


def test_vertices_are_merged_by_position():
    """A soup of separate triangles (12 vertices) that closes up by position."""
    soup_v = TETRA_V[TETRA_F].reshape(-1, 3)
    r = inspect_mesh((soup_v, np.arange(12).reshape(4, 3)))
    assert r.vertices == 4 and r.watertight and r.components == 1 and r.boundary_edges == 0


def crossing_pair(offset=(0.0, 0.0, 0.0)):
    """A horizontal triangle and a vertical one through its interior: two edges of the
    vertical one cross the horizontal one, no edge of the horizontal one crosses."""
    v = np.array([[-1, -1, 0], [2, -1, 0], [-1, 2, 0], [0, 0, -1], [0.3, 0, 1], [0, 0.3, 1]], float)
    return v + offset, np.array([[0, 1, 2], [3, 4, 5]])


def test_self_intersections_are_counted_by_edge():
    r = inspect_mesh(crossing_pair())
    assert r.self_intersections == 2 and r.self_intersection_edges_tested == 6
    # touching at a shared vertex is no intersection; nor is a closed convex solid
    assert inspect_mesh((TETRA_V, TETRA_F)).self_intersections == 0
    fan = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0]], float)
    assert inspect_mesh((fan, np.array([[0, 1, 2], [0, 3, 4]]))).self_intersections == 0
    # a vertex resting on another triangle's interior touches it, crosses nothing
    tee = np.array([[-1, -1, 0], [2, -1, 0], [-1, 2, 0], [0.2, 0.2, 0], [0.5, 0.2, 1], [0.2, 0.5, 1]], float)
    assert inspect_mesh((tee, np.array([[0, 1, 2], [3, 4, 5]]))).self_intersections == 0


def many_pairs(n):
    parts = [crossing_pair((5.0 * i, 0.0, 0.0)) for i in range(n)]
    v = np.concatenate([p[0] for p in parts])
    f = np.concatenate([p[1] + 6 * i for i, p in enumerate(parts)])
    return v, f


def test_self_intersections_estimated_from_a_sample(monkeypatch):
    """400 pairs: 800 of 2400 edges cross.  A sample of 600 edges gives an estimate
    within 4 binomial standard deviations; a tight pair budget samples fewer edges."""
    mesh = many_pairs(400)
    assert inspect_mesh(mesh).self_intersections == 800
    monkeypatch.setattr(gi, "SELF_INTERSECTION_SAMPLE", 600)
    r = inspect_mesh(mesh)
    sd = 2400 * np.sqrt(600 * (1 / 3) * (2 / 3)) / 600
    assert r.self_intersection_edges_tested == 600 and abs(r.self_intersections - 800) <= 4 * sd
    monkeypatch.setattr(gi, "PAIR_BUDGET", 300)
    r = inspect_mesh(mesh)
    assert r.self_intersection_edges_tested < 600 and abs(r.self_intersections - 800) <= 0.5 * 800


@pytest.mark.parametrize("name", SHARED_MESHES)
def test_agrees_with_trimesh_on_the_shared_meshes(shared_mesh, name):
    """Components (split at non-manifold edges), boundary edges, winding consistency,
    watertightness and (closed meshes) volume, against trimesh on the same triangles."""
    mesh = glvox.load_mesh(shared_mesh(name))
    r = inspect_mesh(mesh)
    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=True, validate=False)
    parts = trimesh.graph.connected_components(tm.face_adjacency, nodes=np.arange(len(tm.faces)))
    assert r.components == len(parts)
    assert r.boundary_edges == len(trimesh.grouping.group_rows(tm.edges_sorted, require_count=1))
    assert r.winding_consistent == tm.is_winding_consistent and r.watertight == tm.is_watertight
    if r.watertight:
        assert r.signed_volume == pytest.approx(tm.volume, rel=1e-9)


def test_cli(capsys, tmp_path):
    path = tmp_path / "tet.stl"
    trimesh.Trimesh(TETRA_V, TETRA_F).export(path)
    assert main(["inspect", str(path), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["triangles"] == 4 and d["watertight"] is True and d["uncertain_share"] is None
    assert main(["inspect", str(path)]) == 0
    assert "boundary_edges:" in capsys.readouterr().out
    assert main(["inspect", str(tmp_path / "missing.obj")]) == 1
    assert capsys.readouterr().err.strip() == (f"glvox: error: mesh file not found: {tmp_path / 'missing.obj'} "
                                              "(nor is it a mesh name glvox knows: `glvox data list`)")
    assert main(["inspect", str(path), "-r", "0"]) == 1
    assert "-r/--resolution must be a positive" in capsys.readouterr().err


def test_uncertain_share_definition():
    w = np.zeros((4, 4, 4), np.float32)
    w[0] = 1.0          # 16 sure inside
    w[1, :2] = 0.45     # 8 uncertain, below the threshold
    w[2, 0] = 0.59      # 4 uncertain, inside
    w[3, 0] = 0.39      # 4 outside the band and the region
    assert gi.uncertain_share(w) == (12, 12 / 28)
    assert gi.uncertain_share(w, threshold=0.95) == (16, 16 / 16)
    assert gi.uncertain_share(np.zeros((2, 2, 2))) == (0, 1.0)  # nothing near inside: an empty solid, not a sure one


def test_uncertain_share_on_a_grid(gl_context, shared_mesh):
    """Closed meshes are sure (w is 0 or 1 off the surface); an open teapot is not, and
    the share from gwn-solid's field matches the one from reference-gwn's exact field."""
    assert inspect_mesh("gen:torus", 32).uncertain_share == 0.0
    teapot = glvox.load_mesh(shared_mesh("messy_teapot_newell.obj"))
    bunny = glvox.load_mesh(shared_mesh("stanford_bunny_bun_zipper.ply"))
    for mesh in (teapot, bunny):
        r = inspect_mesh(mesh, 48)
        exact = glvox.voxelize(mesh, 48, method="reference-gwn").fields["winding"]
        n, share = gi.uncertain_share(exact)
        assert r.resolution == 48 and abs(r.uncertain_voxels - n) <= 2 and r.uncertain_share > 0
        assert r.uncertain_share == pytest.approx(share, abs=2 / 1000)


def test_double_sided_and_misoriented_meshes_are_told(capsys, tmp_path):
    """The defects of ShapeNet-style meshes, in words and in --json: a double-sided cube is
    not 'inward' with a sure solid, it is double-sided, every parity and winding method
    finds it empty, and its winding solid is all uncertain."""
    from glvox.testing import defects

    path = defects.write_obj(tmp_path / "two_faced.obj", defects.double_sided_cube())
    assert main(["inspect", str(path), "--json", "-r", "8"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert (d["orientation"], d["opposite_face_pairs"], d["opposite_share"], d["signed_volume_ratio"]) == \
        ("double-sided", 12, 1.0, 0.0)
    assert d["signed_volume"] == 0.0 and d["uncertain_share"] == 1.0
    assert d["solid_methods"]["ss-solid"] == d["solid_methods"]["gwn-solid"] == "empty (double-sided faces cancel)"
    assert d["solid_methods"]["carve-solid"] == d["solid_methods"]["binvox-solid"] == "ok"
    assert main(["inspect", str(path)]) == 0
    out = capsys.readouterr()
    assert "orientation:" in out.out and "double-sided\n" in out.out and out.err == ""
    lines = out.out.splitlines()
    methods = lines[lines.index("solid_methods:") + 1:]
    assert methods[0].split() == ["eisemann-solid:", "empty", "(double-sided", "faces", "cancel)"]  # problems first
    assert [ln.split()[0] for ln in methods if ln.endswith(" ok")] == \
        ["binvox-solid:", "carve-solid:", "karabassi:", "reference-binvox:", "reference-carve:"]

    flipped = inspect_mesh(defects.flipped_face_cube())
    assert (flipped.inconsistent_parts, flipped.orientation) == (1, "outward")
    assert flipped.solid_methods["gwn-solid"] == "unreliable (inconsistent orientation)"
    assert flipped.solid_methods["ss-solid"] == "ok"
    mixed = inspect_mesh(defects.two_cubes_one_inside_out())
    assert (mixed.orientation, mixed.inverted_parts, mixed.signed_volume_ratio) == ("mixed", 1, 0.0)
    assert mixed.solid_methods["reference-gwn"] == "partly empty (1 of 2 parts inside out)"
    box = inspect_mesh(defects.open_box())
    assert box.solid_methods["carve-solid"] == "may leak (open boundary)" and box.orientation == "outward"
