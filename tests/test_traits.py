"""Mesh traits (glvox.traits) on hand-made meshes whose traits are known by construction."""

from __future__ import annotations

import doctest

import numpy as np
import pytest

import glvox.traits
from glvox.mesh import clean_twin, load_mesh
from glvox.methods import method_names
from glvox.testing import defects
from glvox.testing.defects import DEFECTS
from glvox.traits import SOLID_MECHANISMS, MeshTraits, mesh_traits, solid_outlook, solid_warning


@pytest.mark.parametrize("name", sorted(DEFECTS))
def test_known_traits(name):
    build, known = DEFECTS[name]
    t = mesh_traits(load_mesh(build(), name=name))
    got = {k: getattr(t, k) for k in known}
    assert got == pytest.approx(known, abs=1e-12)


def test_traits_are_computed_once_per_mesh():
    mesh = load_mesh(defects.cube())
    assert mesh_traits(mesh) is mesh_traits(mesh)
    other = load_mesh(defects.double_sided_cube())
    assert mesh_traits(other) is not mesh_traits(mesh)
    with pytest.raises(Exception):  # frozen
        mesh_traits(mesh).parts = 3


def test_coincident_faces_are_found_after_welding():
    """A triangle soup (three own vertices per face, as OBJ exports of ShapeNet hold
    them) with every face doubled reversed: welding by position finds the pairs,
    and a shift of 1e-12 of the box (below WELD_RTOL) does not hide them."""
    v, f = defects.double_sided_cube()
    soup_v = v[f].reshape(-1, 3).copy()
    soup_v[36:] += 1e-12  # the reversed copies, moved by far less than the weld tolerance
    t = mesh_traits(load_mesh((soup_v, np.arange(len(soup_v)).reshape(-1, 3))))
    assert (t.opposite_pairs, t.opposite_share, t.parts, t.open_edges) == (12, 1.0, 1, 0)
    assert t.signed_volume_ratio == pytest.approx(0.0, abs=1e-9)
    # moved by 1e-3 of the box: different faces, no longer coincident (each copy is its own closed cube)
    soup_v[36:] += 1e-3
    t = mesh_traits(load_mesh((soup_v, np.arange(len(soup_v)).reshape(-1, 3))))
    assert (t.opposite_pairs, t.parts, t.inverted_parts) == (0, 2, 1)


def test_same_winding_copies():
    """Every face twice with the same winding: duplicates, not opposite pairs; parity
    cancels (two crossings) but the winding number just doubles."""
    v, f = defects.cube()
    t = mesh_traits(load_mesh((v, np.vstack([f, f]))))
    assert (t.opposite_pairs, t.duplicate_share, t.inconsistent_parts, t.signed_volume_ratio) == (0, 1.0, 0, 2.0)
    out = solid_outlook(t)
    assert out["ss-solid"] == "empty (double-sided faces cancel)"
    assert out["gwn-solid"] == "ok"


def test_doubled_patches_act_as_holes_many_make_methods_unreliable():
    v, f = defects.cube()
    t = mesh_traits(load_mesh((v, np.vstack([f, f[:2, ::-1]]))))  # one side doubled: 4 of 14 faces
    assert (t.opposite_pairs, t.opposite_share) == (2, pytest.approx(4 / 14))
    assert t.inconsistent_parts == 0  # the pairs are set aside, the rest is consistent
    out = solid_outlook(t)
    assert out["reference-solid"] == "may streak (28.6% of faces double-sided)"
    assert out["gwn-solid"] == "may dent (28.6% of faces double-sided)"
    assert solid_warning(t, "gwn-solid", 400, 1000) is None  # a result that holds the body: no alarm
    assert solid_warning(t, "gwn-solid", 3, 1000).startswith("3 voxels (far fewer than the mesh's box holds)")
    t = mesh_traits(load_mesh((v, np.vstack([f, f[:8, ::-1]]))))  # four sides: 16 of 20 faces
    assert solid_outlook(t)["reference-solid"] == "unreliable (80% of faces double-sided: they cancel)"


def test_touching_closed_parts_are_not_inconsistent():
    """Two cubes sharing an edge: that edge has four faces, two in each direction; a
    consistent mesh, not judged there."""
    v1, f1 = defects.cube()
    v2, f2 = defects.cube(lo=(1.0, 1.0, 0.0))
    t = mesh_traits(load_mesh((np.vstack([v1, v2]), np.vstack([f1, f2 + 8]))))
    assert (t.parts, t.inconsistent_parts, t.inverted_parts) == (1, 0, 0)
    assert t.signed_volume_ratio == pytest.approx(0.5)  # two unit cubes in a 2 x 2 x 1 box


def test_whole_mesh_inside_out():
    v, f = defects.cube()
    t = mesh_traits(load_mesh((v, f[:, ::-1])))
    assert (t.signed_volume_ratio, t.inverted_parts, t.inconsistent_parts) == (-1.0, 1, 0)
    assert solid_outlook(t)["gwn-solid"] == "empty (inside out)"
    assert solid_outlook(t)["ss-solid"] == "ok"


def test_flat_mesh_has_zero_volume():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    t = mesh_traits(load_mesh((v, np.array([[0, 1, 2], [0, 2, 3]]))))
    assert (t.signed_volume_ratio, t.part_volume_ratio, t.open_edges) == (0.0, 0.0, 4)
    out = solid_outlook(t)
    assert out["ss-solid"] == "empty (zero volume)" and out["carve-solid"] == "surface only (zero volume)"


EXPECTED_OUTLOOK = {
    # name -> {method: verdict} for the methods that are not 'ok'
    "cube": {},
    "double_sided_cube": {m: "empty (double-sided faces cancel)" for m, k in SOLID_MECHANISMS.items()
                          if k in ("parity", "winding")},
    "flipped_face_cube": {"gwn-solid": "unreliable (inconsistent orientation)",
                          "reference-gwn": "unreliable (inconsistent orientation)"},
    "two_cubes_one_inside_out": {"gwn-solid": "partly empty (1 of 2 parts inside out)",
                                 "reference-gwn": "partly empty (1 of 2 parts inside out)"},
    "open_box": {**{m: "may streak (open boundary)" for m, k in SOLID_MECHANISMS.items() if k == "parity"},
                 **{m: "may leak (open boundary)" for m, k in SOLID_MECHANISMS.items()
                    if k in ("carve", "hull", "binvox")}},
}


@pytest.mark.parametrize("name", sorted(DEFECTS))
def test_outlook(name):
    out = solid_outlook(mesh_traits(load_mesh(DEFECTS[name][0]())))
    assert set(out) == set(SOLID_MECHANISMS)
    assert {m: v for m, v in out.items() if v != "ok"} == EXPECTED_OUTLOOK[name]


def test_every_solid_method_has_a_mechanism():
    """A solid method registered without a place in SOLID_MECHANISMS would get no verdict."""
    missing = set(method_names(kind="solid")) - set(SOLID_MECHANISMS) - {"solid"}  # the alias runs one of them
    assert not missing, f"add to glvox.traits.SOLID_MECHANISMS: {sorted(missing)}"


def test_warning_lines():
    t = mesh_traits(load_mesh(defects.double_sided_cube()))
    line = solid_warning(t, "ss-solid", 0, 1000)
    assert line.startswith("0 voxels (empty) from ss-solid: double-sided faces cancel (100% of faces doubled")
    assert line.endswith("use -m binvox-solid or -m carve-solid")
    assert solid_warning(t, "carve-solid", 1000, 1000) is None
    ok = mesh_traits(load_mesh(defects.cube()))
    assert solid_warning(ok, "ss-solid", 512, 1000) is None
    assert "no voxel center lies inside" in solid_warning(ok, "ss-solid", 0, 1000)
    leaky = mesh_traits(load_mesh(defects.open_box()))
    assert solid_warning(leaky, "carve-solid", 700, 1000) is None
    assert "open boundary (4 boundary edges)" in solid_warning(leaky, "karabassi", 0, 1000)


def test_doctests():
    assert doctest.testmod(glvox.traits).failed == 0
    assert doctest.testmod(defects).failed == 0
    assert isinstance(mesh_traits(load_mesh(defects.cube())), MeshTraits)


@pytest.mark.parametrize("name, double, inconsistent", [("gen:double-sided-torus", True, False),
                                                         ("gen:double-sided-bunny-like", True, False),
                                                         ("gen:flipped-half-sphere", False, True)])
def test_generated_defective_meshes_have_their_defect(name, double, inconsistent):
    """The open-mesh study's generated dataset-style meshes carry the defect they are named for,
    on the vertices of their clean twin (whose solid is their true one)."""
    mesh, twin = load_mesh(name), load_mesh(clean_twin(name))
    t = mesh_traits(mesh)
    assert np.array_equal(mesh.vertices, twin.vertices)
    assert (t.opposite_share == 1.0) is double and (t.inconsistent_parts == 1) is inconsistent
    assert mesh.n_triangles == twin.n_triangles * (2 if double else 1)
    assert clean_twin("gen:torus") is None and clean_twin("bunny.ply") is None
