"""``-m solid``: ss-solid on watertight, consistently oriented meshes, binvox-solid on
double-sided or inconsistently oriented ones, gwn-solid on the other open ones, recorded as such."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import ndimage

import glvox
from glvox.batch import BatchSettings, read_manifest, run_batch
from glvox.errors import MethodError
from glvox.mesh import load_mesh
from glvox.methods import get_method, run_method

OPEN = ["stanford_bunny_bun_zipper.ply", "stanford_dragon_vrip_res2.ply", "messy_teapot_newell.obj"]


def test_watertight_meshes_get_ss_solid(gl_context):
    mesh = load_mesh("gen:torus")
    spec = glvox.grid_for(mesh, 40)
    g = glvox.voxelize(mesh, grid=spec, method="solid")
    assert g.run.method == "ss-solid" and g.run.stats["requested"] == "solid"
    assert g.equal(run_method("ss-solid", mesh, spec))
    assert "solid" in [i.name for i in glvox.list_methods(kind="solid")]
    with pytest.raises(MethodError, match="method 'solid' has no option threshold; its options: none"):
        run_method("solid", mesh, spec, threshold=0.5)


@pytest.mark.parametrize("name", OPEN)
def test_open_oriented_meshes_get_gwn_solid_with_the_body_inside(gl_context, shared_mesh, name):
    """Open scans, oriented (the dragon with 1.5% of its faces doubled in places): no
    allow_open and no warning; the solid is gwn-solid's (the winding number is defined for
    them) and holds the body: the voxels vote-solid (an independent method) calls inside,
    two voxels or more away from the surface."""
    mesh = load_mesh(shared_mesh(name))
    assert not mesh.watertight and get_method("solid").resolve(mesh) == "gwn-solid"
    spec = glvox.grid_for(mesh, 64)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        g = glvox.voxelize(mesh, grid=spec, method="solid")
    assert g.run.method == "gwn-solid" and g.run.stats["requested"] == "solid"
    assert g.run.stats["picked_because"].startswith(("not watertight", "faces doubled in places"))
    assert g.equal(run_method("gwn-solid", mesh, spec))
    surface = run_method("reference-conservative", mesh, spec).dense()
    body = run_method("vote-solid", mesh, spec).dense() & ~ndimage.binary_dilation(surface, iterations=2)
    assert body.sum() > 1000, "a body to hold"
    assert not (body & ~g.dense()).any(), f"{name}: {int((body & ~g.dense()).sum())} body voxels left out"


def _torus_variants():
    t = load_mesh("gen:torus")
    v, f = t.vertices, t.faces
    flipped = f.copy()
    flipped[::3] = flipped[::3, ::-1]
    return {"double-sided": (v, np.concatenate([f, f[:, ::-1]])), "inconsistently oriented": (v, flipped)}


@pytest.mark.parametrize("trait", ["double-sided", "inconsistently oriented"])
def test_double_sided_and_flipped_meshes_get_binvox_solid(gl_context, trait):
    """Both are closed shapes parity would misread or the traits flag: binvox-solid runs,
    the reason is recorded, and the solid is the one-sided torus's binvox solid."""
    mesh = load_mesh(_torus_variants()[trait])
    torus = load_mesh("gen:torus")
    spec = glvox.grid_for(mesh, 40)
    g = glvox.voxelize(mesh, grid=spec, method="solid")
    assert g.run.method == "binvox-solid" and g.run.stats["requested"] == "solid"
    why = g.run.stats["picked_because"]
    assert why.startswith(trait), why
    assert g.equal(run_method("binvox-solid", torus, spec))
    # and close to the exact solid of the closed torus: it holds all of it, and binvox's
    # recipe (-aw -dc -down) adds a shell (measured IoU 0.845 at 40^3)
    exact = run_method("ss-solid", torus, spec).dense()
    d = g.dense()
    assert not (exact & ~d).any()
    assert (d & exact).sum() / (d | exact).sum() >= 0.84


def test_cli_says_which_method_solid_picked(gl_context, tmp_path, capsys):
    from glvox.cli import main
    assert main(["voxelize", "gen:torus", "-r", "16", "-m", "solid"]) == 0
    assert "voxelizing with ss-solid (ss family, compute, solid; picked by solid: watertight and consistently " \
           "oriented)" in capsys.readouterr().err
    import trimesh
    obj = tmp_path / "double.obj"
    trimesh.Trimesh(*_torus_variants()["double-sided"], process=False).export(obj)
    assert main(["voxelize", str(obj), "-r", "16", "-m", "solid"]) == 0
    assert "voxelizing with binvox-solid (binvox family, raster, solid; picked by solid: double-sided (100% of " \
           "faces coincide with another)" in capsys.readouterr().err


def test_batch_records_the_method_that_ran(gl_context, shared_mesh, tmp_path):
    """glvox batch -m solid never fails a mesh for being open; the manifest names the method."""
    paths = [shared_mesh(n) for n in OPEN] + [shared_mesh("cad_rocker_arm.obj")]
    lst = tmp_path / "list.txt"
    lst.write_text("\n".join(str(p) for p in paths) + "\n")
    s = run_batch(lst, tmp_path / "out", BatchSettings("solid", resolution=32), workers=0, quiet=True)
    assert (s.done, s.failed) == (4, 0)
    rows = {r["input"]: r for r in read_manifest(tmp_path / "out" / "manifest.csv")}
    assert {r["method"] for k, r in rows.items() if not k.startswith("cad_")} == {"gwn-solid"}
    assert rows["cad_rocker_arm.obj"]["method"] == "ss-solid"
    assert all(r["params"] == "-m solid -r 32 --format npz" and int(r["voxels"]) > 0 for r in rows.values())
    assert all(r["warnings"] == "" for r in rows.values())
    bunny = glvox.load(tmp_path / "out" / "stanford_bunny_bun_zipper.npz")
    mesh = load_mesh(shared_mesh(OPEN[0]))
    assert np.array_equal(bunny.dense(), run_method("gwn-solid", mesh, glvox.grid_for(mesh, 32)).dense())


def test_an_open_mesh_with_a_part_inside_out_gets_binvox_solid(gl_context):
    """An open box beside a closed cube wound inward: the cube's winding number is -1 (gwn-solid
    would leave it empty), parity needs a closed mesh; binvox-solid, which uses no orientation,
    keeps both bodies."""
    from glvox.testing.defects import cube, open_box

    v1, f1 = open_box()
    v2, f2 = cube((2.0, 0.0, 0.0))
    mesh = load_mesh((np.vstack([v1, v2]), np.vstack([f1, f2[:, ::-1] + len(v1)])))
    method, why = get_method("solid").resolve(mesh), get_method("solid").why(mesh)
    assert (method, why) == ("binvox-solid", "open, with 1 of 2 parts inside out"), (method, why)
