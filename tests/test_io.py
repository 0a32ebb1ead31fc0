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
    assert "translate 1 -2 0.5" in header and "scale 2.25" in header  # min corner, n * h, as %g
    assert io.load(p, convention="binvox").spec.same_placement(g.spec)


def test_binvox_header_is_byte_for_byte_what_binvox_writes(tmp_path):
    """binvox (C++ ostream defaults, %g) wrote this header for a ShapeNet chair's placement:
    translate = the mesh's box minimum, scale = its longest side.  glvox writes the same
    bytes for that placement, and runs split at 255 as binvox splits them."""
    spec = GridSpec((4, 4, 4), (-0.42806, -0.038727, -0.241275), 0.85617 / 4)
    occ = np.zeros((4, 4, 4), bool)
    occ[1:3, 1:3, 1:3] = True
    data = io.save(VoxelGrid(occ, spec), tmp_path / "chair.binvox", convention="binvox").read_bytes()
    assert data.startswith(b"#binvox 1\ndim 4 4 4\ntranslate -0.42806 -0.038727 -0.241275\nscale 0.85617\ndata\n")
    with open(tmp_path / "chair.binvox", "rb") as f:  # trimesh's reader: the same voxels
        np.testing.assert_array_equal(trimesh.exchange.binvox.load_binvox(f).matrix, occ)
    full = VoxelGrid(np.ones((8, 8, 8), bool), GridSpec((8, 8, 8), (0.0, 0.0, 0.0), 0.125))
    data = io.save(full, tmp_path / "full.binvox", convention="binvox").read_bytes()
    assert data == b"#binvox 1\ndim 8 8 8\ntranslate 0 0 0\nscale 1\ndata\n" + bytes([1, 255, 1, 255, 1, 2])


def test_binvox_header_numbers_keep_the_placement_where_g_would_move_it(tmp_path):
    """%g keeps 6 digits: an origin of 1234.56789 would move by 0.00011 (a tenth of a voxel
    here); glvox then writes the shortest exact number instead."""
    g = VoxelGrid(np.ones((4, 4, 4), bool), GridSpec((4, 4, 4), (1234.56789, 0.0, 0.0), 0.001))
    p = io.save(g, tmp_path / "far.binvox", convention="binvox")
    assert b"translate 1234.56789 0 0\n" in p.read_bytes()
    assert io.load(p, convention="binvox").spec.same_placement(g.spec)


def test_binvox_header_read_as_binvox_reads_it(tmp_path):
    """binvox's reference reader takes keywords in any order and skips comments, blank lines
    and keywords it does not know (files from ShapeNet pipelines carry such lines)."""
    occ = np.zeros((3, 3, 3), bool)
    occ[0, 1, 2] = occ[2, 2, 0] = True
    rle = io.save(VoxelGrid(occ, GridSpec((3, 3, 3), (0, 0, 0), 1.0)), tmp_path / "a.binvox").read_bytes()
    rle = rle[rle.index(b"data\n") + 5:]
    p = tmp_path / "commented.binvox"
    p.write_bytes(b"#binvox 1\n# written by a ShapeNet script\n\nscale 0.9\n  # indented comment\n"
                  b"source chair.obj 12 3\ntranslate -0.5 0.25  1\ndim 3 3 3\n\ndata\n" + rle)
    g = io.load(p, convention="binvox")
    assert g.equal(VoxelGrid(occ, g.spec))
    np.testing.assert_array_equal(g.origin, [-0.5, 0.25, 1.0])
    assert g.voxel_size == pytest.approx(0.3, rel=1e-15)
    t = io.load(p)  # trimesh's reading of the same numbers: scale spans the first to the last center
    assert t.voxel_size == pytest.approx(0.45) and t.equal(VoxelGrid(occ, t.spec))
    # without translate and scale the reference reader places the grid in the unit cube
    p.write_bytes(b"#binvox 1\ndim 3 3 3\ndata\n" + rle + b"trailing bytes are ignored")
    g = io.load(p, convention="binvox")
    assert g.equal(VoxelGrid(occ, g.spec)) and g.spec.same_placement(GridSpec((3, 3, 3), (0, 0, 0), 1 / 3))


@pytest.mark.parametrize("head, data, message", [
    (b"#binvox 1\ntranslate 0 0 0\nscale 1\ndata\n", bytes([0, 27]), r"no 'dim' line before 'data'"),
    (b"#binvox\ndim 3 3 3\ndata\n", bytes([0, 27]), r"'#binvox' must be followed by an integer version"),
    (b"#binvox 1\ndim 3 3 3\nscale x\ndata\n", bytes([0, 27]), r"'scale' takes numbers, got 'x'"),
    (b"#binvox 1\ndim 3 3 3\n", b"", r"the header ends without 'data'"),
    (b"#binvox 1\ndim 3 3 3\ndata\n", bytes([0, 20]), r"truncated binvox data: 20 voxels, header says 3x3x3"),
    (b"#binvox 1\ndim 3 3 3\ndata\n", bytes([0, 20, 1, 9]), r"overrun: a run ends at voxel 29, past the 3x3x3"),
])
def test_binvox_bad_headers_and_data(tmp_path, head, data, message):
    p = tmp_path / "bad.binvox"
    p.write_bytes(head + data)
    with pytest.raises(FormatError, match=message):
        io.load(p, convention="binvox")


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
