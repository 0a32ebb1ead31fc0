"""Grid fit (the convention and its edges), bit packing, VoxelGrid."""

from __future__ import annotations

import threading

import numpy as np
import pytest

import glvox.grid as grid_module
from glvox.errors import GridError
from glvox.grid import GridSpec, fit_grid, host_threads, pack_bits, unpack_bits
from glvox.results.voxels import VoxelGrid

BOX = np.array([[0.0, 0.0, 0.0], [2.0, 1.0, 1.0]])


def test_default_fit_is_the_worked_example_of_the_docs():
    s = fit_grid(BOX, 4)
    assert s.dims == (4, 4, 4)
    assert s.voxel_size == 0.5
    np.testing.assert_array_equal(s.origin, [0.0, -0.5, -0.5])
    np.testing.assert_allclose(s.centers([[0, 1, 1]]), [[0.25, 0.25, 0.25]])
    # the grid closely encompasses the model: the longest axis is covered exactly
    np.testing.assert_allclose(s.bounds, [[0, -0.5, -0.5], [2, 1.5, 1.5]])


def test_tight_fit_gives_non_cubic_dims():
    s = fit_grid(BOX, 4, tight=True)
    assert s.dims == (4, 2, 2)
    np.testing.assert_array_equal(s.origin, [0.0, 0.0, 0.0])


def test_padding_keeps_dims_and_shrinks_the_model():
    s = fit_grid(BOX, 6, padding=1)
    assert s.dims == (6, 6, 6) and s.voxel_size == 0.5
    v = s.world_to_voxel(BOX)
    np.testing.assert_allclose(v[:, 0], [1.0, 5.0])  # one empty voxel each side along x


def test_explicit_dims_are_isotropic_and_centered():
    s = fit_grid(BOX, dims=(8, 2, 6))
    assert s.dims == (8, 2, 6)
    assert s.voxel_size == 0.5  # y needs 1/2 = 0.5, x needs 2/8 = 0.25: the larger wins
    np.testing.assert_allclose(s.origin + 0.5 * np.array(s.dims) * s.voxel_size, [1.0, 0.5, 0.5])


def test_explicit_voxel_size():
    s = fit_grid(BOX, voxel_size=0.3)
    assert s.dims == (7, 4, 4)  # ceil(2/0.3) = 7, ceil(1/0.3) = 4
    np.testing.assert_allclose(s.origin + 0.5 * np.array(s.dims) * 0.3, [1.0, 0.5, 0.5])


def test_exact_multiple_voxel_size_gives_no_extra_layer():
    s = fit_grid(BOX, voxel_size=0.25)
    assert s.dims == (8, 4, 4)
    np.testing.assert_allclose(s.origin, [0, 0, 0], atol=1e-12)


def test_flat_mesh_fits():
    flat = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0]])
    s = fit_grid(flat, 3)
    assert s.dims == (3, 3, 3)
    np.testing.assert_allclose(s.world_to_voxel([[0.0, 0.0, 0.0]])[0, 2], 1.5)  # centered in z


@pytest.mark.parametrize("kwargs, msg", [
    ({"resolution": 0}, r"resolution must be a positive integer, got 0"),
    ({"resolution": 4.5}, r"resolution must be a positive integer, got 4.5"),
    ({"resolution": 4, "padding": 2}, r"padding 2 leaves no voxel inside a grid of resolution 4"),
    ({"resolution": 4, "padding": -1}, r"padding must be >= 0 voxels, got -1"),
    ({"voxel_size": -1.0}, r"voxel_size must be a finite positive number, got -1.0"),
    ({"dims": (4, 0, 4)}, r"dims must be at least 1 along every axis, got \(4, 0, 4\)"),
    ({"resolution": 4, "dims": (4, 4, 4)}, r"give exactly one of resolution, dims or voxel_size"),
    ({"resolution": 2**16 + 1}, r"dims must be at most 65536 along every axis"),
])
def test_bad_fits_are_refused(kwargs, msg):
    with pytest.raises(GridError, match=msg):
        fit_grid(BOX, **kwargs)


def test_point_bounds_are_refused():
    with pytest.raises(GridError, match="zero extent"):
        fit_grid(np.zeros((2, 3)), 4)


def test_bounds_must_be_finite_and_ordered():
    with pytest.raises(GridError, match=r"bounds must be a finite \(2, 3\) array"):
        fit_grid(np.array([[0, 0, 0], [np.nan, 1, 1]]), 4)
    with pytest.raises(GridError, match=r"bounds max must be >= min"):
        fit_grid(np.array([[0, 0, 0], [-1, 1, 1]]), 4)


@pytest.mark.parametrize("dims", [(1, 1, 1), (31, 3, 2), (32, 1, 5), (33, 4, 4), (100, 7, 3)])
def test_pack_unpack_round_trip(dims):
    rng = np.random.default_rng(7)
    occ = rng.random(dims) < 0.5
    words = pack_bits(occ)
    assert words.dtype == np.dtype("<u4")
    assert words.shape == (dims[2], dims[1], (dims[0] + 31) // 32)
    np.testing.assert_array_equal(unpack_bits(words, dims), occ)


@pytest.mark.parametrize("dims", [(64, 7, 5), (33, 4, 9), (100, 3, 1), (5, 2, 1)])
def test_unpacking_in_threads_gives_every_row_once(dims, monkeypatch):
    """Past THREADED_UNPACK_BYTES the rows are split among GLVOX_THREADS threads, each
    unpacking UNPACK_CHUNK_BYTES at a time: forced here on small grids (3 threads, chunks
    of 1-2 rows, uneven splits), every voxel must still come back where pack_bits put it."""
    monkeypatch.setattr(grid_module, "THREADED_UNPACK_BYTES", 0)
    monkeypatch.setattr(grid_module, "UNPACK_CHUNK_BYTES", 64 * 2)
    monkeypatch.setenv("GLVOX_THREADS", "3")
    calls: list[tuple[str, int]] = []
    real = np.unpackbits

    def spy(a, *args, **kwargs):
        calls.append((threading.current_thread().name, a.shape[0]))
        return real(a, *args, **kwargs)

    monkeypatch.setattr(np, "unpackbits", spy)
    occ = np.random.default_rng(11).random(dims) < 0.5
    out = unpack_bits(pack_bits(occ), dims)
    np.testing.assert_array_equal(out, occ)
    assert out.shape == dims and out.dtype == bool
    rows, wpr = dims[1] * dims[2], (dims[0] + 31) // 32
    assert sum(n for _, n in calls) == rows  # every row unpacked once
    threads = min(3, rows)
    assert max(n for _, n in calls) == min(max(1, 128 // (32 * wpr)), -(-rows // threads))  # in chunks
    helpers = {f"glvox-unpack-{t}" for t in range(1, threads)}
    assert {name for name, _ in calls} == {threading.current_thread().name} | helpers
    if dims[0] % 32 == 0:
        assert out.flags.f_contiguous  # the GPU's layout, as without threads
    monkeypatch.setenv("GLVOX_THREADS", "1")  # one thread: one call in this thread
    calls.clear()
    np.testing.assert_array_equal(unpack_bits(pack_bits(occ), dims), occ)
    assert calls == [(threading.current_thread().name, rows)]


@pytest.mark.parametrize("value", ["0", "-2", "four", "1.5"])
def test_bad_glvox_threads_is_one_line(value, monkeypatch):
    monkeypatch.setenv("GLVOX_THREADS", value)
    with pytest.raises(GridError, match=r"^GLVOX_THREADS must be a positive integer, got '.*'$"):
        host_threads()
    with pytest.raises(GridError, match="GLVOX_THREADS"):  # on a grid too small for threads too
        unpack_bits(np.zeros((1, 1, 1), "<u4"), (5, 1, 1))
    monkeypatch.setenv("GLVOX_THREADS", "5")
    assert host_threads() == 5
    monkeypatch.delenv("GLVOX_THREADS")
    assert 1 <= host_threads() <= 8


def test_pack_bit_positions_by_hand():
    occ = np.zeros((40, 2, 1), dtype=bool)
    occ[0, 0, 0] = occ[31, 0, 0] = occ[32, 1, 0] = occ[39, 1, 0] = True
    w = pack_bits(occ).reshape(-1)
    # rows (j=0), (j=1), two words each
    assert w.tolist() == [(1 << 0) | (1 << 31), 0, 0, (1 << 0) | (1 << 7)]


def test_voxelgrid_compare_and_iou():
    spec = GridSpec((4, 4, 4), (0, 0, 0), 1.0)
    a = np.zeros((4, 4, 4), bool)
    b = np.zeros((4, 4, 4), bool)
    a[0, 0, 0] = a[1, 1, 1] = a[2, 2, 2] = True
    b[1, 1, 1] = b[2, 2, 2] = b[3, 3, 3] = True
    c = VoxelGrid(a, spec).compare(VoxelGrid(b, spec))
    assert c.missing.tolist() == [[3, 3, 3]]
    assert c.extra.tolist() == [[0, 0, 0]]
    assert c.iou == pytest.approx(2 / 4)
    assert not c.equal
    assert VoxelGrid(a, spec).count == 3


LAYOUTS = {
    "C": lambda a: np.ascontiguousarray(a),
    "Fortran": np.asfortranarray,
    "binvox file (x, z, y)": lambda a: np.ascontiguousarray(a.transpose(0, 2, 1)).transpose(0, 2, 1),
    "strided view": lambda a: np.ascontiguousarray(a[:, ::-1, :])[:, ::-1, :],
}


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("dims", [(1, 1, 1), (9, 3, 2), (33, 4, 4), (64, 5, 3)])
def test_pack_bits_in_any_memory_layout(dims, layout):
    """Fortran order packs row by row as it lies; any other layout is packed plane by plane
    of x: the words must be the same, and unpack to the array."""
    occ = np.random.default_rng(3).random(dims) < 0.5
    arr = LAYOUTS[layout](occ)
    np.testing.assert_array_equal(arr, occ)
    words = pack_bits(arr)
    np.testing.assert_array_equal(words, pack_bits(np.asfortranarray(occ)))
    np.testing.assert_array_equal(unpack_bits(words, dims), occ)


@pytest.mark.parametrize("dims", [(37, 5, 4), (64, 3, 6), (5, 1, 1)])
def test_compare_from_words_is_the_dense_comparison(dims):
    """compare() works on the packed words: the same missing and extra voxels, in
    np.argwhere's order, counts and IoU as the dense arrays give, whichever of the two
    grids holds words or a dense array; bits past nx in the last word are no voxels."""
    rng = np.random.default_rng(5)
    spec = GridSpec(dims, (0, 0, 0), 1.0)
    a, b = rng.random(dims) < 0.3, rng.random(dims) < 0.3
    wa = pack_bits(a)
    if dims[0] % 32:
        wa[..., -1] |= np.uint32(0xFFFFFFFF) << np.uint32(dims[0] % 32)  # stray bits past the grid
    for ga, gb in ((VoxelGrid(words=wa, spec=spec), VoxelGrid(b, spec)),
                   (VoxelGrid(a, spec), VoxelGrid(words=pack_bits(b), spec=spec))):
        c = ga.compare(gb)
        np.testing.assert_array_equal(c.missing, np.argwhere(b & ~a))
        np.testing.assert_array_equal(c.extra, np.argwhere(a & ~b))
        assert c.missing.dtype == c.extra.dtype == np.int64
        assert (c.count, c.reference_count) == (a.sum(), b.sum())
        assert c.iou == pytest.approx((a & b).sum() / (a | b).sum())
    assert VoxelGrid(a, spec).compare(VoxelGrid(words=wa, spec=spec)).equal


def test_voxelgrid_refuses_other_placement_and_bad_arrays():
    s1 = GridSpec((2, 2, 2), (0, 0, 0), 1.0)
    s2 = GridSpec((2, 2, 2), (0.5, 0, 0), 1.0)
    g = VoxelGrid(np.zeros((2, 2, 2), bool), s1)
    with pytest.raises(GridError, match="cannot compare grids on different placements"):
        g.compare(VoxelGrid(np.zeros((2, 2, 2), bool), s2))
    with pytest.raises(GridError, match=r"occupancy must have shape \(2, 2, 2\) \(nx, ny, nz\), got \(2, 2\)"):
        VoxelGrid(np.zeros((2, 2), bool), s1)
    with pytest.raises(GridError, match=r"occupancy must be a bool array, got dtype float64"):
        VoxelGrid(np.zeros((2, 2, 2)), s1)


def test_points_and_trimesh_placement():
    spec = GridSpec((3, 2, 2), (10.0, -1.0, 0.0), 0.5)
    occ = np.zeros((3, 2, 2), bool)
    occ[2, 1, 0] = True
    g = VoxelGrid(occ, spec)
    np.testing.assert_allclose(g.points(), [[11.25, -0.25, 0.25]])
    tm = g.to_trimesh()
    np.testing.assert_allclose(tm.points, g.points())
    np.testing.assert_array_equal(tm.matrix, occ)


def test_dense_is_read_only():
    g = VoxelGrid(np.zeros((2, 2, 2), bool), GridSpec((2, 2, 2), (0, 0, 0), 1.0))
    with pytest.raises(ValueError):
        g.dense()[0, 0, 0] = True
