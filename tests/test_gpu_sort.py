"""GPU exclusive scan and stable radix sort (glvox.gpu_sort) against numpy."""

from __future__ import annotations

import numpy as np
import pytest

import glvox.gpu.sort as gs
from glvox.errors import LimitError
from glvox.gl.shaders import compute_program
from glvox.gpu.buffers import buffer_pool

#: Written after the n elements of every buffer: the primitives must leave it alone.
SENTINEL = np.uint32(0xDEADBEEF)
TAIL = 3


@pytest.fixture
def upload(gl_context):
    """upload(arr) -> GPU buffer of arr (uint32) followed by TAIL sentinel words."""
    made = []

    def make(arr):
        data = np.concatenate([np.asarray(arr, dtype=np.uint32), np.full(TAIL, SENTINEL, np.uint32)])
        buf = gl_context.mgl.buffer(data.tobytes())
        made.append(buf)
        return buf

    yield make
    for buf in made:
        buf.release()


def read(buf, n):
    """The n uint32 at the start of buf, and the sentinel tail after them."""
    words = np.frombuffer(buf.read(size=4 * (n + TAIL)), dtype=np.uint32)
    return words[:n], words[n:]


def exclusive_cumsum(a):
    out = np.zeros(len(a), dtype=np.uint64)
    np.cumsum(a[:-1], dtype=np.uint64, out=out[1:])
    return (out & 0xFFFFFFFF).astype(np.uint32)


# -- exclusive scan -------------------------------------------------------------------


@pytest.mark.parametrize("n", [0, 1, 2, 255, 256, 257, 1000, gs.SCAN_BLOCK, gs.SCAN_BLOCK + 1,
                               65536 + 3, 3_000_000])
def test_scan_matches_cumsum(gl_context, upload, n):
    # values below 1000: 3e6 of them sum to < 2**32, so numpy's sums are exact
    a = np.random.default_rng(n).integers(0, 1000, n, dtype=np.uint32)
    src, dst, total = upload(a), upload(np.zeros(n)), upload([7])
    gs.exclusive_scan(gl_context, src, dst, n, total=total)
    out, tail = read(dst, n)
    np.testing.assert_array_equal(out, exclusive_cumsum(a))
    assert (tail == SENTINEL).all()
    assert read(total, 1)[0][0] == int(a.sum(dtype=np.uint64))
    assert (read(src, n)[0] == a).all()  # src is read only


@pytest.mark.parametrize("n", [1, 1000, 300_001])
def test_scan_in_place(gl_context, upload, n):
    a = np.random.default_rng(n).integers(0, 1000, n, dtype=np.uint32)
    buf, total = upload(a), upload([0])
    gs.exclusive_scan(gl_context, buf, buf, n, total=total)
    out, tail = read(buf, n)
    np.testing.assert_array_equal(out, exclusive_cumsum(a))
    assert (tail == SENTINEL).all()
    assert read(total, 1)[0][0] == int(a.sum(dtype=np.uint64))


def test_scan_wraps_modulo_2_32(gl_context, upload):
    a = np.random.default_rng(5).integers(0, 2**32, 20_000, dtype=np.uint32)
    src, total = upload(a), upload([0])
    gs.exclusive_scan(gl_context, src, src, len(a), total=total)
    np.testing.assert_array_equal(read(src, len(a))[0], exclusive_cumsum(a))
    assert read(total, 1)[0][0] == int(a.sum(dtype=np.uint64)) % 2**32


def test_scan_without_total(gl_context, upload):
    a = np.arange(10_000, dtype=np.uint32)
    src, dst = upload(a), upload(np.zeros(len(a)))
    gs.exclusive_scan(gl_context, src, dst, len(a))
    np.testing.assert_array_equal(read(dst, len(a))[0], exclusive_cumsum(a))


def test_scan_many_levels(gl_context, upload, monkeypatch):
    # blocks of 32: 40000 -> 1250 -> 40 -> 2 -> 1, four levels of block sums
    monkeypatch.setattr(gs, "SCAN_WG", 16)
    monkeypatch.setattr(gs, "SCAN_ITEMS", 2)
    monkeypatch.setattr(gs, "SCAN_BLOCK", 32)
    a = np.random.default_rng(3).integers(0, 1000, 40_000, dtype=np.uint32)
    src, dst, total = upload(a), upload(np.zeros(len(a))), upload([0])
    gs.exclusive_scan(gl_context, src, dst, len(a), total=total)
    np.testing.assert_array_equal(read(dst, len(a))[0], exclusive_cumsum(a))
    assert read(total, 1)[0][0] == int(a.sum())


@pytest.fixture
def few_groups_per_row(gl_context, monkeypatch):
    """Pretend GL_MAX_COMPUTE_WORK_GROUP_COUNT is 7 along x, so dispatches split along y."""
    limits = dict(gl_context.limits())
    limits["GL_MAX_COMPUTE_WORK_GROUP_COUNT"] = (7,) + tuple(limits["GL_MAX_COMPUTE_WORK_GROUP_COUNT"][1:])
    monkeypatch.setattr(gl_context, "_limits", limits)


def test_scan_dispatch_split_along_y(gl_context, upload, few_groups_per_row):
    n = 40 * gs.SCAN_BLOCK + 5  # 41 blocks: 6 rows of 7 groups, the last one partly idle
    a = np.random.default_rng(4).integers(0, 1000, n, dtype=np.uint32)
    src, total = upload(a), upload([0])
    gs.exclusive_scan(gl_context, src, src, n, total=total)
    np.testing.assert_array_equal(read(src, n)[0], exclusive_cumsum(a))
    assert read(total, 1)[0][0] == int(a.sum())


def test_scan_refuses_small_buffers_and_negative_n(gl_context, upload):
    small = upload(np.zeros(4))
    with pytest.raises(ValueError, match=r"dst must hold at least 100 uint32 \(400 bytes\), got a buffer of 28 bytes"):
        gs.exclusive_scan(gl_context, upload(np.zeros(100)), small, 100)
    with pytest.raises(ValueError, match=r"n must be >= 0, got -1"):
        gs.exclusive_scan(gl_context, small, small, -1)


# -- radix sort -----------------------------------------------------------------------


def make_keys(kind, n, rng):
    """(keys, key_bits) of a test distribution."""
    if kind == "full":
        return rng.integers(0, 2**32, n, dtype=np.uint32), 32
    if kind == "few":  # many duplicates: stability shows in the values
        return rng.choice(np.array([0, 5, 2**31, 2**32 - 1], dtype=np.uint32), n), 32
    if kind == "low-bits":
        return rng.integers(0, 2**20, n, dtype=np.uint32), 20
    if kind == "sorted":
        return np.sort(rng.integers(0, 2**32, n, dtype=np.uint32)), 32
    if kind == "reversed":
        return np.sort(rng.integers(0, 2**32, n, dtype=np.uint32))[::-1].copy(), 32
    raise ValueError(kind)


def check_sort(ctx, upload, keys, key_bits=32, **kwargs):
    """Sort (keys, index) pairs on the GPU and compare with numpy's stable argsort."""
    n = len(keys)
    kb, vb = upload(keys), upload(np.arange(n, dtype=np.uint32))
    gs.sort_pairs(ctx, kb, vb, n, key_bits=key_bits, **kwargs)
    order = np.argsort(keys, kind="stable")
    out_keys, key_tail = read(kb, n)
    out_values, value_tail = read(vb, n)
    np.testing.assert_array_equal(out_keys, keys[order])
    np.testing.assert_array_equal(out_values, order)  # equal keys keep their input order
    assert (key_tail == SENTINEL).all() and (value_tail == SENTINEL).all()
    return kb, vb


@pytest.mark.parametrize("n", [0, 1, 2, 1023, 1024, 1025, 100_000, 1_000_000])
@pytest.mark.parametrize("kind", ["full", "few", "low-bits", "sorted", "reversed"])
def test_sort_matches_stable_argsort(gl_context, upload, kind, n):
    keys, key_bits = make_keys(kind, n, np.random.default_rng(n))
    check_sort(gl_context, upload, keys, key_bits)


@pytest.mark.parametrize("key_bits", [0, 1, 7, 8, 9, 16, 20, 31, 32])
def test_sort_key_bits(gl_context, upload, key_bits):
    # odd numbers of passes end in the scratch buffers and are copied back
    keys = np.random.default_rng(key_bits).integers(0, 2**key_bits, 50_000, dtype=np.uint64)
    check_sort(gl_context, upload, keys.astype(np.uint32), key_bits)


@pytest.mark.parametrize("digit_bits", sorted(gs.RADIX_CONFIGS))
@pytest.mark.parametrize("kind", ["full", "few", "low-bits"])
def test_sort_every_digit_width(gl_context, upload, digit_bits, kind):
    keys, key_bits = make_keys(kind, 70_001, np.random.default_rng(digit_bits))
    check_sort(gl_context, upload, keys, key_bits, digit_bits=digit_bits)


@pytest.mark.parametrize("bits", sorted(gs.RADIX_CONFIGS))
def test_radix_configs_fit(gl_context, bits):
    wg, items = gs.RADIX_CONFIGS[bits]
    assert wg * items < 65536, "tile counters are 16-bit fields"
    assert wg <= gl_context.limits()["GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS"]
    # linking fails when the shared arrays exceed GL_MAX_COMPUTE_SHARED_MEMORY_SIZE
    defines = {"WG_SIZE": wg, "ITEMS": items, "DIGIT_BITS": bits}
    compute_program(gl_context, "sort/radix_count.comp", defines)
    compute_program(gl_context, "sort/radix_scatter.comp", defines)


def test_sort_is_deterministic(gl_context, upload):
    keys = np.random.default_rng(9).integers(0, 50, 300_000, dtype=np.uint32)
    first = [b.read() for b in check_sort(gl_context, upload, keys)]
    second = [b.read() for b in check_sort(gl_context, upload, keys)]
    assert first == second


def test_sort_dispatch_split_along_y(gl_context, upload, few_groups_per_row):
    wg, items = gs.RADIX_CONFIGS[gs.DIGIT_BITS]
    keys = np.random.default_rng(6).integers(0, 2**32, 20 * wg * items + 17, dtype=np.uint32)
    check_sort(gl_context, upload, keys)


def test_sort_reuses_pooled_buffers(gl_context, upload, monkeypatch):
    keys = np.random.default_rng(2).integers(0, 2**32, 200_000, dtype=np.uint32)
    check_sort(gl_context, upload, keys)
    pool = buffer_pool(gl_context, gs.POOL)
    before = dict(pool._bufs)
    assert {"sort.keys", "sort.values", "sort.counts"} <= set(before)
    kb, vb = upload(keys), upload(np.arange(len(keys)))  # the test's own buffers, made first
    made = []
    real = gl_context.mgl.buffer
    monkeypatch.setattr(gl_context.mgl, "buffer", lambda *a, **k: made.append(a) or real(*a, **k))
    gs.sort_pairs(gl_context, kb, vb, len(keys))
    assert made == []
    assert pool._bufs == before


def test_sort_too_large_names_the_limit(gl_context, upload):
    limit = int(gl_context.limits()["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"])
    n = limit // 4 + 1
    small = upload(np.zeros(4))
    with pytest.raises(LimitError, match=rf"a sort of {n} key/value pairs needs .*GL_MAX_SHADER_STORAGE_BLOCK_SIZE"):
        gs.sort_pairs(gl_context, small, small, n)
    with pytest.raises(LimitError, match=rf"a scan of {n} uint32 needs .*GL_MAX_SHADER_STORAGE_BLOCK_SIZE"):
        gs.exclusive_scan(gl_context, small, small, n)


def test_sort_refuses_bad_arguments(gl_context, upload):
    keys, values = upload(np.zeros(10)), upload(np.zeros(10))
    with pytest.raises(ValueError, match=r"key_bits must be in 0..32, got 33"):
        gs.sort_pairs(gl_context, keys, values, 10, key_bits=33)
    with pytest.raises(ValueError, match=r"digit_bits must be one of \[4, 8\], got 5"):
        gs.sort_pairs(gl_context, keys, values, 10, digit_bits=5)
    with pytest.raises(ValueError, match=r"values must hold at least 100 uint32"):
        gs.sort_pairs(gl_context, upload(np.zeros(100)), values, 100)
    with pytest.raises(TypeError, match=r"n must be an integer, got float"):
        gs.sort_pairs(gl_context, keys, values, 1.5)
    with pytest.raises(ValueError, match=r"keys and values must be two different buffers"):
        gs.sort_pairs(gl_context, keys, keys, 10)


@pytest.mark.slow
def test_largest_scan_and_sort_this_context_allows(gl_context, upload):
    n = int(gl_context.limits()["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"]) // 4 - TAIL
    rng = np.random.default_rng(11)
    a = rng.integers(0, 64, n, dtype=np.uint32)  # 2**25 * 63 < 2**32
    src, total = upload(a), upload([0])
    gs.exclusive_scan(gl_context, src, src, n, total=total)
    np.testing.assert_array_equal(read(src, n)[0], exclusive_cumsum(a))
    assert read(total, 1)[0][0] == int(a.sum())
    src.release()
    check_sort(gl_context, upload, rng.integers(0, 2**32, n, dtype=np.uint32))
