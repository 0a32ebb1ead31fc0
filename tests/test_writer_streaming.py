"""binvox and npz writers stream from the packed bits: the same bytes as encoding the dense
grid whole (the writers before streaming, kept here as the reference), and no dense grid."""

from __future__ import annotations

import io as _io
import zipfile

import numpy as np
import pytest

from glvox import io
from glvox.grid import GridSpec, pack_bits
from glvox.results import VoxelGrid, voxels


# -- the writers as they were before streaming: whole dense grid, whole-grid RLE ---------------

def old_binvox_data(dense: np.ndarray) -> bytes:
    """binvox data of dense (nx, ny, nz) bool: x slowest, then z, then y; runs <= 255."""
    flat = np.ascontiguousarray(dense.transpose(0, 2, 1)).reshape(-1)
    change = np.flatnonzero(flat[1:] != flat[:-1]) + 1
    starts = np.concatenate([[0], change])
    lengths = np.diff(np.concatenate([starts, [flat.size]]))
    values = flat[starts].astype(np.uint8)
    reps = (lengths + 254) // 255
    v = np.repeat(values, reps)
    c = np.full(int(reps.sum()), 255, dtype=np.int64)
    last = np.cumsum(reps) - 1
    c[last] = lengths - 255 * (reps - 1)
    return np.stack([v, c.astype(np.uint8)], axis=1).tobytes()


def old_npy(array: np.ndarray) -> bytes:
    buf = _io.BytesIO()
    np.lib.format.write_array(buf, array, allow_pickle=False)
    return buf.getvalue()


def grids(dims, seed=0):
    """Grids on ``dims`` held as packed words only (as the GPU methods return them):
    random, empty, full, and one whose runs are far longer than 255 and cross every slab."""
    rng = np.random.default_rng(seed)
    spec = GridSpec(dims, (0.5, -1.0, 2.0), 0.125)
    box = np.zeros(dims, bool)
    nx, ny, nz = dims
    box[nx // 4: max(nx // 4 + 1, 3 * nx // 4), :, nz // 3:] = True
    for occ in (rng.random(dims) < 0.3, np.zeros(dims, bool), np.ones(dims, bool), box):
        yield occ, VoxelGrid(words=pack_bits(occ), spec=spec)


def no_dense(monkeypatch):
    def refuse(self):
        raise AssertionError("the writer made the dense grid")
    monkeypatch.setattr(VoxelGrid, "dense", refuse)


# slab sizes: the default (one slab at these sizes), and 1 voxel (one byte column / z plane a slab)
SLABS = [None, 1]


@pytest.mark.parametrize("slab", SLABS)
@pytest.mark.parametrize("n", [1, 2, 7, 32, 33, 41])
def test_binvox_streamed_bytes_equal_the_whole_grid_encoding(tmp_path, monkeypatch, n, slab):
    if slab is not None:
        monkeypatch.setattr(voxels, "SLAB_VOXELS", slab)
    convention = "binvox" if n == 1 else "trimesh"  # trimesh's placement needs 2 voxels
    for t, (occ, g) in enumerate(grids((n, n, n), seed=n)):
        with monkeypatch.context() as m:
            no_dense(m)
            path = io.save(g, tmp_path / f"g{t}.binvox", convention=convention)
        data = path.read_bytes()
        header_end = data.index(b"data\n") + 5
        assert data[header_end:] == old_binvox_data(occ), (n, t)
        assert g._dense is None  # nor kept one
        back = io.load(path, convention=convention)
        assert np.array_equal(back.dense(), occ)


@pytest.mark.parametrize("slab", SLABS)
@pytest.mark.parametrize("dims", [(1, 1, 1), (32, 1, 1), (33, 1, 1), (1, 5, 3), (32, 3, 5), (64, 2, 1),
                                  (40, 7, 5), (33, 33, 33)])
def test_npz_streamed_members_equal_the_dense_arrays_npy(tmp_path, monkeypatch, dims, slab):
    if slab is not None:
        monkeypatch.setattr(voxels, "SLAB_VOXELS", slab)
    for t, (occ, g) in enumerate(grids(dims, seed=sum(dims))):
        mask = VoxelGrid(words=pack_bits(~occ), spec=g.spec)
        g.extras["inside"] = mask
        with monkeypatch.context() as m:
            no_dense(m)
            path = io.save(g, tmp_path / f"g{t}.npz")
        assert g._dense is None and mask._dense is None
        # the old writer wrote np.lib.format.write_array of dense(): the unpacked view, in its own order
        with zipfile.ZipFile(path) as zf:
            assert zf.read("occupancy.npy") == old_npy(g.dense()), (dims, t)
            assert zf.read("extra_inside.npy") == old_npy(mask.dense()), (dims, t)
        with np.load(path) as f:  # the documented reading
            assert f["occupancy"].dtype == bool and np.array_equal(f["occupancy"], occ)
            assert np.array_equal(f["extra_inside"], ~occ)


def test_grids_held_dense_write_their_own_array(tmp_path, monkeypatch):
    monkeypatch.setattr(voxels, "SLAB_VOXELS", 1)
    occ = np.random.default_rng(3).random((9, 9, 9)) < 0.5
    for a in (occ, np.asfortranarray(occ), occ[:, ::-1, :]):  # C, Fortran, neither
        g = VoxelGrid(a, GridSpec(a.shape, (0, 0, 0), 1.0))
        path = io.save(g, tmp_path / "d.npz")
        with zipfile.ZipFile(path) as zf:
            assert zf.read("occupancy.npy") == old_npy(a)
        data = io.save(g, tmp_path / "d.binvox").read_bytes()
        assert data[data.index(b"data\n") + 5:] == old_binvox_data(a)
