"""glvox bench --sdf: the SDF peers on glvox's voxel centers, and libigl's signed distance read right."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
import trimesh

import glvox
from glvox.cli import main
from glvox.errors import SuspiciousResultWarning
from glvox.study import sdf_bench

pytestmark = pytest.mark.usefixtures("gl_context")


def _torus_file(tmp_path, drop: int = 0):
    """gen:torus as a .ply, its first ``drop`` faces removed (an open mesh with a hole)."""
    m = glvox.load_mesh("gen:torus")
    path = tmp_path / f"torus{drop}.ply"
    trimesh.Trimesh(m.vertices, m.faces[drop:], process=False).export(path)
    return str(path)


def _glvox(path, n):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SuspiciousResultWarning)
        r = glvox.sdf(path, n)
    return r, r.spec.centers(np.indices(r.dims).reshape(3, -1).T)


def test_bench_sdf_runs_glvox_and_open3d_end_to_end(capsys):
    pytest.importorskip("open3d", reason="Open3D (pip install open3d) is the peer this test runs")
    assert main(["bench", "--sdf", "--meshes", "gen:torus", "-r", "16", "--json", "-q"]) == 0
    rows = {r["tool"]: r for r in json.loads(capsys.readouterr().out)}
    g, o = rows["glvox sdf (band 3)"], rows["Open3D RaycastingScene"]
    assert g["ratio"] == 1.0 and g["exact_voxels"] > 0 and o["seconds"] > 0
    assert o["ratio"] == pytest.approx(o["seconds"] / g["seconds"])
    assert o["max_diff_vox"] < 1e-4                  # Open3D's float32 distances on glvox's exact voxels
    assert o["sign_agreement"] == 1.0                 # a closed torus: every tool's sign is right
    assert "mesh2sdf" in rows and "skipped" in rows["mesh2sdf"]


def test_bench_sdf_needs_meshes_and_sizes(capsys):
    assert main(["bench", "--sdf", "-r", "16"]) == 1
    assert "glvox bench --sdf takes --meshes and -r" in capsys.readouterr().err


def test_libigl_signed_distance_agrees_on_a_closed_mesh(tmp_path):
    pytest.importorskip("igl", reason="libigl (pip install libigl) is the peer this test reads")
    path = _torus_file(tmp_path)
    r, centers = _glvox(path, 20)
    s = sdf_bench.igl_sdf(path, centers).reshape(r.dims)
    assert np.abs(s - r.sdf)[r.band].max() / r.voxel_size < 1e-4       # signed, on the band
    assert np.array_equal(s < 0, r.sdf < 0)                              # the sign everywhere


def test_libigl_distance_is_the_distance_near_a_hole(tmp_path):
    """With a winding-number sign libigl's S is (1 - 2w) d: near a hole |S| < d.  The bench
    takes d from the closest points, so the unsigned distances agree there too."""
    pytest.importorskip("igl", reason="libigl (pip install libigl) is the peer this test reads")
    path = _torus_file(tmp_path, drop=40)
    r, centers = _glvox(path, 20)
    s = sdf_bench.igl_sdf(path, centers).reshape(r.dims)
    assert np.abs(np.abs(s) - np.abs(r.sdf))[r.band].max() / r.voxel_size < 1e-4
    assert sdf_bench.agreement(r, s)["max_diff_vox"] < 1e-4


def test_agreement_by_hand():
    spec = glvox.GridSpec((3, 2, 2), (0.0, 0.0, 0.0), 0.5)
    sdf = np.full(spec.dims, 1.0, np.float32)
    sdf[0, 0, 0], sdf[1, 0, 0] = -0.25, 0.0
    band = np.zeros(spec.dims, bool)
    band[:2, 0, 0] = True
    r = glvox.SDFGrid(sdf, spec, band, band_width=2.0)
    peer = sdf.astype(np.float64).copy()
    peer[0, 0, 0] = 0.5                    # 0.25 world = 0.5 voxel farther, and the wrong sign
    peer[2, 1, 1] = 7.0                    # off the band: no distance difference counted
    peer[1, 0, 0] = -1e-9                  # on the surface: no sign counted
    a = sdf_bench.agreement(r, peer)
    assert a["max_diff_vox"] == pytest.approx(0.5) and a["sign_agreement"] == pytest.approx(10 / 11)
