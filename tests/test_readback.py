"""Reading results back: dense, indices/points, trimesh, binvox and npz from the packed words,
and the voxel counts methods take on the GPU."""

from __future__ import annotations

import numpy as np
import pytest

import glvox
from glvox.gpu.buffers import clear_buffer
from glvox.grid import pack_bits, set_indices, unpack_bits
from glvox.methods import method_names, get_method, run_method
from glvox.results.voxels import c_order


@pytest.mark.parametrize("dims", [(37, 20, 5), (64, 33, 17), (100, 1, 3), (1, 1, 1), (32, 2, 64)])
def test_unpack_indices_and_orders_match_numpy(dims):
    rng = np.random.default_rng(sum(dims))
    dense = rng.random(dims) < 0.1
    words = pack_bits(dense)
    out = unpack_bits(words, dims)
    assert out.dtype == bool and out.shape == dims
    np.testing.assert_array_equal(out, dense)
    np.testing.assert_array_equal(set_indices(words, dims), np.argwhere(dense))
    c = c_order(out)
    assert c.flags.c_contiguous
    np.testing.assert_array_equal(c, dense)


def test_points_trimesh_and_files_agree_with_the_dense_grid(tmp_path):
    mesh = glvox.load_mesh("gen:bunny-like")
    grid = glvox.voxelize(mesh, 40, method="ss-conservative")
    dense = grid.dense()
    np.testing.assert_array_equal(grid.points(), grid.spec.centers(np.argwhere(dense)))
    tm = grid.to_trimesh()
    np.testing.assert_array_equal(tm.matrix, dense)
    np.testing.assert_allclose(tm.points, grid.points())
    for suffix in (".npz", ".binvox"):
        back = glvox.load(glvox.save(grid, tmp_path / f"g{suffix}"))
        np.testing.assert_array_equal(back.dense(), dense)


DENSE_GPU = [n for n in method_names()
             if get_method(n).info.uses_gl and get_method(n).info.kind in ("surface", "solid")]


@pytest.mark.parametrize("name", DENSE_GPU)
def test_voxel_count_equals_the_set_bits(name, gl_context):
    mesh = glvox.load_mesh("gen:torus")
    spec = glvox.grid_for(mesh, 45)  # 45: words with unused high bits in every row
    r = run_method(name, mesh, spec, ctx=gl_context)
    assert r.run.stats["voxels"] == r.count == int(np.bitwise_count(np.asarray(r.words())).sum()) > 0


@pytest.mark.parametrize("value", [0, 0xFFFFFFFF, 0x7F7FFFFF])
def test_buffers_are_cleared_on_the_gpu_to_a_word(gl_context, value):
    """clear_buffer fills whole words from an offset, leaves the rest alone, and takes
    moderngl's way for a size that is not whole words (zeros only)."""
    buf = gl_context.mgl.buffer(np.arange(64, dtype="<u4").tobytes())
    clear_buffer(gl_context, buf, 100, value, offset=16)
    got = np.frombuffer(buf.read(), dtype="<u4")
    want = np.arange(64, dtype="<u4")
    want[4:29] = value
    np.testing.assert_array_equal(got, want)
    clear_buffer(gl_context, buf)  # to its end
    assert not np.frombuffer(buf.read(), dtype="<u4").any()
    buf.write(b"\xff" * 256)
    clear_buffer(gl_context, buf, 6)  # 1.5 words: zeros on the host
    assert np.frombuffer(buf.read(), dtype="<u1")[:8].tolist() == [0, 0, 0, 0, 0, 0, 255, 255]
    with pytest.raises(ValueError, match="whole words"):
        clear_buffer(gl_context, buf, 6, 1)
    buf.release()
