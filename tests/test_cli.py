"""The command line: info, methods, voxelize, and one-line errors."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh

from glvox import io
from glvox.methods import method_names


def glvox(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "glvox", *map(str, args)], capture_output=True,
                          text=True, timeout=600, cwd=cwd)


def test_info_reports_renderer_and_limits():
    p = glvox("info")
    assert p.returncode == 0, p.stderr
    assert "renderer:" in p.stdout and "GL_MAX_SHADER_STORAGE_BLOCK_SIZE" in p.stdout
    d = json.loads(glvox("info", "--json").stdout)
    assert d["version"].startswith("4.")
    if d["software"]:
        assert "llvmpipe" in d["renderer"]


def test_methods_lists_the_registry():
    p = glvox("methods")
    assert p.returncode == 0
    for name in method_names():
        assert name in p.stdout
    d = json.loads(glvox("methods", "--json").stdout)
    assert {m["name"] for m in d} == set(method_names())


def test_voxelize_armadillo_npz_and_binvox_round_trip(tmp_path, shared_mesh):
    mesh = shared_mesh("stanford_armadillo_libigl_86k.obj")
    npz, bv = tmp_path / "x.npz", tmp_path / "x.binvox"
    p = glvox("voxelize", mesh, "-r", 64, "-m", "reference-solid", "-o", npz, "--json")
    assert p.returncode == 0, p.stderr
    d = json.loads(p.stdout)
    assert d["method"] == "reference-solid" and d["grid"]["dims"] == [64, 64, 64]
    assert d["stats"]["voxels"] > 0 and d["timings"]["wall_s"] > 0
    p2 = glvox("voxelize", mesh, "-r", 64, "-m", "reference-solid", "-o", bv, "-q")
    assert p2.returncode == 0, p2.stderr
    a, b = io.load(npz), io.load(bv)
    assert a.equal(b) and a.count == d["stats"]["voxels"]
    t = trimesh.load(bv)
    np.testing.assert_array_equal(t.matrix, a.dense())
    np.testing.assert_allclose(np.sort(t.points, axis=0), np.sort(a.points(), axis=0), atol=1e-9)
    # placement follows the documented fit: centered cubic grid, h = max extent / 64
    m = trimesh.load(mesh, force="mesh")
    h = m.extents.max() / 64
    assert a.voxel_size == pytest.approx(h)
    np.testing.assert_allclose(a.origin + 32 * h, m.bounds.mean(axis=0), atol=1e-9)


def test_voxelize_shows_progress_on_stderr(tmp_path):
    p = glvox("voxelize", "gen:sphere", "-r", 16, "-m", "reference-conservative", "-o", tmp_path / "s.npz")
    assert p.returncode == 0
    assert "loading gen:sphere" in p.stderr and "voxels set" in p.stderr and "wrote" in p.stderr


def test_voxelize_grid_options(tmp_path):
    out = tmp_path / "t.npz"
    p = glvox("voxelize", "gen:box", "-r", 10, "--tight", "--padding", "1", "-m", "reference-solid",
              "-o", out, "-q")
    assert p.returncode == 0, p.stderr
    g = io.load(out)
    # box 2 x 1.2 x 0.8; padding keeps N = 10 along x, so h = 2 / (10 - 2) = 0.25 and the
    # tight dims are ceil((8, 4.8, 3.2)) + 2 = (10, 7, 6)
    assert g.dims == (10, 7, 6) and g.voxel_size == pytest.approx(0.25)
    assert not g.dense()[0].any() and not g.dense()[-1].any()
    p = glvox("voxelize", "gen:box", "--dims", 5, 4, 3, "-m", "reference-solid", "-o", out, "-q")
    assert p.returncode == 0 and io.load(out).dims == (5, 4, 3)
    # method options as --KEY VALUE: the parity axis changes nothing on a closed mesh
    p = glvox("voxelize", "gen:box", "--dims", 5, 4, 3, "-m", "reference-solid", "--axis", 2,
              "--json", "-q")
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout)["options"] == {"axis": 2}


@pytest.mark.parametrize("args, msg", [
    (["voxelize", "/nonexistent/mesh.obj", "-r", "8"], "mesh file not found: /nonexistent/mesh.obj"),
    (["voxelize", "gen:torus", "-r", "8", "-m", "nope"], "unknown method 'nope'; known methods:"),
    (["voxelize", "gen:torus", "-r", "8", "-m", "reference-solid", "-O", "axis=7"],
     "option axis must be one of [0, 1, 2], got 7"),
    (["voxelize", "gen:torus", "-r", "8", "-m", "reference-solid", "-O", "speed=9"],
     "method 'reference-solid' has no option speed; its options: axis"),
    (["voxelize", "gen:torus", "-r", "8", "-o", "x.vox"], "unknown voxel file suffix '.vox'"),
    (["voxelize", "gen:torus", "-r", "8", "-m", "reference-solid", "--axis"], "method option --axis needs a value"),
    (["voxelize", "gen:torus", "-r", "8", "-m", "reference-solid", "--axis", "3"],
     "option axis must be one of [0, 1, 2], got 3"),
    (["voxelize", "gen:torus", "-r", "0"], "resolution must be a positive integer, got 0"),
    (["voxelize", "gen:torus"], "give -r/--resolution N, --dims NX NY NZ or --voxel-size H"),
])
def test_errors_are_one_line_and_non_zero(tmp_path, args, msg):
    p = glvox(*args, cwd=tmp_path)
    assert p.returncode == 1
    lines = p.stderr.strip().splitlines()
    assert lines[-1].startswith("glvox: error: ") and msg in lines[-1], p.stderr
    assert "Traceback" not in p.stderr


def test_nan_mesh_file_is_refused(tmp_path):
    bad = tmp_path / "nan.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    p = glvox("voxelize", bad, "-r", 8)
    assert p.returncode == 1 and "NaN or infinite" in p.stderr and "Traceback" not in p.stderr


def test_open_mesh_with_solid_method(tmp_path, shared_mesh):
    p = glvox("voxelize", shared_mesh("stanford_bunny_bun_zipper.ply"), "-r", 16, "-m", "reference-solid")
    assert p.returncode == 1 and "is not watertight" in p.stderr and "--allow-open" in p.stderr
