"""npz and binvox: keys, round trips, trimesh placement, bad files."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import glvox
from glvox import io
from glvox.errors import FormatError
from glvox.grid import GridSpec
from glvox.results.voxels import VoxelGrid


def random_grid(dims=(9, 9, 9), origin=(1.0, -2.0, 0.5), h=0.25, seed=0):
    occ = np.random.default_rng(seed).random(dims) < 0.3
    return VoxelGrid(occ, GridSpec(dims, origin, h))


def test_npz_keys_dtypes_and_round_trip(tmp_path):
    g = glvox.voxelize("gen:torus", 16, method="reference-solid")
    p = io.save(g, tmp_path / "t.npz")
    with np.load(p) as z:
        assert set(z.files) == {"occupancy", "origin", "voxel_size", "method", "kind"}
        assert z["occupancy"].dtype == bool and z["occupancy"].shape == (16, 16, 16)
        assert z["origin"].dtype == np.float64 and z["origin"].shape == (3,)
        assert z["voxel_size"].dtype == np.float64
        assert str(z["method"]) == "reference-solid" and str(z["kind"]) == "solid"
        np.testing.assert_array_equal(z["occupancy"], g.dense())
    back = io.load(p)
    assert back.equal(g) and back.spec == g.spec


def test_extra_masks_round_trip_and_are_checked(tmp_path):
    g = random_grid()
    mask = random_grid(seed=1)
    with_extra = VoxelGrid(g.dense(), g.spec, extras={"unclassifiable": mask})
    p = io.save(with_extra, tmp_path / "e.npz")
    with np.load(p) as z:
        assert "extra_unclassifiable" in z.files
    back = io.load(p)
    assert back.equal(g) and set(back.extras) == {"unclassifiable"}
    assert back.extras["unclassifiable"].equal(mask)
    other = VoxelGrid(mask.dense(), GridSpec((9, 9, 9), (0.0, 0.0, 0.0), 0.25))
    with pytest.raises(glvox.errors.GridError, match="must be a VoxelGrid on"):
        VoxelGrid(g.dense(), g.spec, extras={"m": other})
    with pytest.raises(glvox.errors.GridError, match="identifiers"):
        VoxelGrid(g.dense(), g.spec, extras={"a b": mask})


def test_binvox_is_read_by_trimesh_with_same_occupancy_and_placement(tmp_path):
    g = random_grid()
    p = io.save(g, tmp_path / "g.binvox")
    t = trimesh.load(p)
    np.testing.assert_array_equal(t.matrix, g.dense())
    # trimesh's points are voxel centers; ours too
    np.testing.assert_allclose(np.sort(t.points, axis=0), np.sort(g.points(), axis=0), atol=1e-12)
    back = io.load(p)
    assert back.equal(g)
    assert back.spec.same_placement(g.spec)


def test_binvox_written_by_trimesh_is_read_by_glvox(tmp_path):
    g = random_grid(seed=3)
    p = tmp_path / "from_trimesh.binvox"
    p.write_bytes(trimesh.exchange.binvox.export_binvox(g.to_trimesh()))
    back = io.load(p)
    assert back.equal(g) and back.spec.same_placement(g.spec)


def test_binvox_tool_convention_round_trip(tmp_path):
    g = random_grid(seed=5)
    p = io.save(g, tmp_path / "tool.binvox", convention="binvox")
    header = p.read_bytes().split(b"data\n")[0].decode()
    assert "translate 1.0 -2.0 0.5" in header and "scale 2.25" in header  # min corner, n * h
    assert io.load(p, convention="binvox").spec.same_placement(g.spec)


def test_binvox_runs_longer_than_255(tmp_path):
    occ = np.zeros((20, 20, 20), bool)
    occ[3:17, 2:18, 1:19] = True
    g = VoxelGrid(occ, GridSpec((20, 20, 20), (0, 0, 0), 1.0))
    assert io.load(io.save(g, tmp_path / "runs.binvox")).equal(g)


def test_binvox_refuses_non_cubic(tmp_path):
    g = random_grid(dims=(4, 5, 6))
    with pytest.raises(FormatError, match=r"binvox stores cubic grids only, got dims \(4, 5, 6\); save as \.npz"):
        io.save(g, tmp_path / "x.binvox")


def test_unknown_suffix_and_bad_files(tmp_path):
    g = random_grid()
    with pytest.raises(FormatError, match=r"unknown voxel file suffix '.ply'"):
        io.save(g, tmp_path / "x.ply")
    with pytest.raises(FormatError, match="voxel file not found"):
        io.load(tmp_path / "missing.npz")
    bad = tmp_path / "bad.binvox"
    bad.write_bytes(b"hello world")
    with pytest.raises(FormatError, match="is not a valid binvox file"):
        io.load(bad)
    good = io.save(g, tmp_path / "good.binvox").read_bytes()
    trunc = tmp_path / "trunc.binvox"
    trunc.write_bytes(good[: len(good) - 3])
    with pytest.raises(FormatError, match="trunc.binvox"):
        io.load(trunc)
    npz = tmp_path / "bad.npz"
    np.savez(npz, something=np.zeros(3))
    with pytest.raises(FormatError, match=r"lacks the npz keys \['occupancy', 'origin', 'voxel_size'\]"):
        io.load(npz)
    notzip = tmp_path / "notzip.npz"
    notzip.write_bytes(b"\x00" * 100)
    with pytest.raises(FormatError, match="cannot read .*notzip.npz as npz"):
        io.load(notzip)
