"""GPU prefix scan and radix sort of uint32 buffers (compute shaders in ``shaders/sort/``).

Both primitives work on ``moderngl.Buffer`` objects already on the GPU and
never read data back to the CPU, so the stages of a voxelizer can chain them
(scan of per-triangle counts, sort of (tile, triangle) pairs, compaction)
without a round trip through numpy.

* :func:`exclusive_scan`: multi-level exclusive prefix sum.  Blocks of
  :data:`SCAN_BLOCK` uints are reduced to one sum each
  (``scan_reduce.comp``), the sums are scanned recursively (in place, in a
  pooled buffer per level), and each block is then scanned in shared memory
  with its offset added (``scan_block.comp``).  The deepest level is a single
  block, which also writes the grand total when asked.
* :func:`sort_pairs`: stable LSD radix sort of uint32 keys carrying uint32
  values, :data:`DIGIT_BITS` bits per pass.  A pass counts the digits of each
  tile (``radix_count.comp``), scans the digit-major (digit, tile) counts with
  :func:`exclusive_scan` to get every tile's output position per digit, and
  scatters each tile with ranks computed by counting in shared memory
  (``radix_scatter.comp``), so the result is stable and bit for bit the same on
  every run.

Everything is deterministic: the only atomics (shared-memory histogram
counts) add ones, whose order cannot change the result.

Scratch buffers come from ``buffer_pool(ctx, "gpu_sort")``, are grown when
needed and reused by later calls.  Each call starts and ends with a
``glMemoryBarrier`` (all bits), so it sees the caller's earlier shader writes
and later dispatches, copies and reads see its results.
"""

from __future__ import annotations

import operator
from typing import Any

from ..gl.shaders import compute_program
from .buffers import buffer_pool, check_buffer_size
from .dispatch import bind, dispatch_1d, set_uniforms

#: Pool owner name of the scratch buffers (``buffer_pool(ctx, POOL)``).
POOL = "gpu_sort"

# The sizes below were chosen on Mesa llvmpipe (CPU cores, 256-bit SIMD),
# where every barrier switches between the coroutines of all SIMD chunks of a
# work group and every shared or storage access of non-uniform address is a
# loop over the lanes: few invocations with many items each win there (a GPU
# would want wider groups; the shaders take any sizes as defines).  Measured
# with compare/bench_gpu_sort.py; figures in compare/README.md.

#: Scan: invocations per work group, uints per invocation, uints per block
#: (64 x 64 was faster than 256 x 16, as the note above leads to expect).
SCAN_WG = 64
SCAN_ITEMS = 64
SCAN_BLOCK = SCAN_WG * SCAN_ITEMS

#: Radix digit width used by :func:`sort_pairs` unless told otherwise: 8-bit
#: digits (4 passes for 32-bit keys) sort faster than 4-bit digits (8
#: passes), as a pass costs about the same with either width: the scatter
#: dominates.
DIGIT_BITS = 8

#: Per digit width: (invocations per work group, keys per invocation).  The
#: scatter kernel's shared count matrix takes 2 ** (bits - 1) * wg * 4 bytes,
#: which must stay within GL's guaranteed 32 KiB (hence only 32 invocations
#: for 8-bit digits); the tile (wg * items keys) must stay below 65536 for its
#: 16-bit counters.
RADIX_CONFIGS = {4: (64, 64), 8: (32, 256)}
#: Every ``(shader, defines)`` the scan and the sort compile: what a method that
#: scans or sorts adds to its ``Requirements(compute=...)`` (the work group
#: sizes and shared memory are read from these, glvox.gl.workgroups).
SHADERS = tuple(("sort/scan_block.comp", {"WG_SIZE": SCAN_WG, "ITEMS": SCAN_ITEMS, "HAS_OFFSETS": h}) for h in (0, 1)) + (
    ("sort/scan_reduce.comp", {"WG_SIZE": SCAN_WG, "ITEMS": SCAN_ITEMS}),) + tuple(
    (f"sort/{k}.comp", {"WG_SIZE": wg, "ITEMS": items, "DIGIT_BITS": bits})
    for bits, (wg, items) in RADIX_CONFIGS.items() for k in ("radix_count", "radix_scatter"))


def _u32_count(n: Any, name: str = "n") -> int:
    if isinstance(n, bool):
        raise TypeError(f"{name} must be an integer, got bool")
    try:
        n = operator.index(n)
    except TypeError:
        raise TypeError(f"{name} must be an integer, got {type(n).__name__}") from None
    if n < 0:
        raise ValueError(f"{name} must be >= 0, got {n}")
    return n


def _check_capacity(buf, n: int, name: str) -> None:
    if buf.size < 4 * n:
        raise ValueError(
            f"{name} must hold at least {n} uint32 ({4 * n} bytes), got a buffer of {buf.size} bytes"
        )


def _barrier(ctx) -> None:
    ctx.mgl.memory_barrier()


def _run(ctx, prog, groups: int) -> None:
    # the kernels number their groups linearly over x then y (common.glsl)
    prog["u_groups"].value = groups
    dispatch_1d(ctx, prog, groups, 1)
    _barrier(ctx)


def exclusive_scan(ctx, src, dst, n: int, *, total=None) -> None:
    """Exclusive prefix sum of ``n`` uint32 on the GPU.

    ``dst[i] = src[0] + ... + src[i - 1]`` (``dst[0] = 0``), modulo 2**32.

    Parameters
    ----------
    ctx : glvox.gl.context.GLContext
    src : moderngl.Buffer
        ``n`` uint32 (little-endian, tightly packed) from offset 0; read only
        (unless it is ``dst``).  May be larger.
    dst : moderngl.Buffer
        Receives ``n`` uint32 from offset 0; bytes after ``4 * n`` are left
        untouched.  May be ``src`` itself (in-place scan).
    n : int
        Number of elements, ``0 <= n`` and ``4 * n`` within
        GL_MAX_SHADER_STORAGE_BLOCK_SIZE (128 MiB, so n <= 2**25, on
        llvmpipe; the kernels themselves index up to 2**32 and split group
        counts over 65535 along y).  ``n = 0`` writes nothing to ``dst``.
    total : moderngl.Buffer, optional
        Receives the sum of all ``n`` values (uint32, modulo 2**32; 0 when
        ``n = 0``) at offset 0, e.g. to size the next stage.  Read that one
        word back only if the CPU needs it.

    Raises
    ------
    LimitError
        ``4 * n`` bytes exceed GL_MAX_SHADER_STORAGE_BLOCK_SIZE.
    ValueError
        ``n`` is negative or a buffer is smaller than ``4 * n`` bytes.
    """
    n = _u32_count(n)
    check_buffer_size(ctx, 4 * n, f"a scan of {n} uint32")
    _check_capacity(src, n, "src")
    _check_capacity(dst, n, "dst")
    if total is not None:
        _check_capacity(total, 1, "total")
    _barrier(ctx)  # the caller's writes to src are visible to the first dispatch
    pool = buffer_pool(ctx, POOL)
    write_total = total is not None
    if total is None:  # the Total block still needs a buffer
        total = pool.get("scan.total", 4, what="scan total", clear=False)
    _scan_level(ctx, pool, src, dst, n, total, write_total, level=0)


def _scan_level(ctx, pool, src, dst, n: int, total, write_total: bool, level: int) -> None:
    groups = (n + SCAN_BLOCK - 1) // SCAN_BLOCK
    defines = {"WG_SIZE": SCAN_WG, "ITEMS": SCAN_ITEMS}
    if groups <= 1:
        prog = compute_program(ctx, "sort/scan_block.comp", {**defines, "HAS_OFFSETS": 0})
        set_uniforms(prog, {"u_n": n, "u_write_total": int(write_total)})
        bind(prog, Src=src, Dst=dst, Total=total)
        _run(ctx, prog, 1)  # one group even for n = 0, so that the total is written
        return
    # every block writes its sum, so the level buffer needs no clearing
    sums = pool.get(f"scan.sums{level}", 4 * groups, what=f"scan level {level + 1} sums", clear=False)
    reduce = compute_program(ctx, "sort/scan_reduce.comp", defines)
    set_uniforms(reduce, {"u_n": n})
    bind(reduce, Src=src, Sums=sums)
    _run(ctx, reduce, groups)
    _scan_level(ctx, pool, sums, sums, groups, total, write_total, level + 1)
    prog = compute_program(ctx, "sort/scan_block.comp", {**defines, "HAS_OFFSETS": 1})
    set_uniforms(prog, {"u_n": n, "u_write_total": 0})
    bind(prog, Src=src, Dst=dst, Offsets=sums, Total=total)
    _run(ctx, prog, groups)


def sort_pairs(ctx, keys, values, n: int, *, key_bits: int = 32, digit_bits: int | None = None) -> None:
    """Stable LSD radix sort of ``n`` (key, value) pairs of uint32, in place on the GPU.

    After the call, ``keys[:n]`` is sorted ascending and ``values[:n]`` holds
    the values permuted alike; pairs with equal keys keep their input order
    (stable), so the result equals ``order = np.argsort(keys, kind="stable")``
    applied to both, bit for bit, on every run.

    Parameters
    ----------
    ctx : glvox.gl.context.GLContext
    keys, values : moderngl.Buffer
        ``n`` uint32 each (little-endian, tightly packed) from offset 0; may
        be larger (bytes after ``4 * n`` are left untouched).
    n : int
        Number of pairs, ``0 <= n`` and ``4 * n`` within
        GL_MAX_SHADER_STORAGE_BLOCK_SIZE (n <= 2**25 on llvmpipe).
    key_bits : int, 0..32
        Every key is known to be ``< 2 ** key_bits``; only those low bits are
        sorted on (``ceil(key_bits / digit_bits)`` passes).  Keys with higher
        bits set end up ordered by their low ``key_bits`` bits only.
    digit_bits : {4, 8}, optional
        Bits per pass; default :data:`DIGIT_BITS` (the faster one measured).

    Notes
    -----
    Scratch from ``buffer_pool(ctx, "gpu_sort")``: ping-pong copies of keys and
    values (``sort.keys``, ``sort.values``, ``4 * n`` bytes each) and the
    per-tile digit counts (``sort.counts``, ``4 * 2**digit_bits *
    ceil(n / tile)`` bytes), plus the scan's level buffers.  They are grown
    when needed and reused, so a second call of the same size allocates
    nothing.  When the number of passes is odd the result is copied back
    from the scratch buffers.

    Raises
    ------
    LimitError
        ``4 * n`` bytes (or the counts buffer) exceed
        GL_MAX_SHADER_STORAGE_BLOCK_SIZE.
    ValueError
        ``n`` is negative, ``key_bits`` or ``digit_bits`` out of range, a
        buffer is smaller than ``4 * n`` bytes, or keys and values are the
        same buffer.
    """
    n = _u32_count(n)
    key_bits = _u32_count(key_bits, "key_bits")
    if key_bits > 32:
        raise ValueError(f"key_bits must be in 0..32, got {key_bits}")
    bits = DIGIT_BITS if digit_bits is None else digit_bits
    if bits not in RADIX_CONFIGS:
        raise ValueError(f"digit_bits must be one of {sorted(RADIX_CONFIGS)}, got {digit_bits!r}")
    check_buffer_size(ctx, 4 * n, f"a sort of {n} key/value pairs")
    _check_capacity(keys, n, "keys")
    _check_capacity(values, n, "values")
    if keys.glo == values.glo:
        raise ValueError("keys and values must be two different buffers, got the same one twice")
    passes = (key_bits + bits - 1) // bits
    if n <= 1 or passes == 0:
        return
    _radix_passes(ctx, keys, values, n, bits, passes)


def _radix_passes(ctx, keys, values, n: int, bits: int, passes: int) -> None:
    """``passes`` LSD passes of ``bits`` each (count, scan, scatter), ping-ponging
    through the pool's scratch copies; the result ends in ``keys`` and ``values``."""
    wg, items = RADIX_CONFIGS[bits]
    tile = wg * items
    groups = (n + tile - 1) // tile
    radix = 1 << bits
    pool = buffer_pool(ctx, POOL)
    n_counts = radix * groups
    check_buffer_size(ctx, 4 * n_counts, f"the digit counts of a sort of {n} pairs")
    # fully written by each pass before being read: no clearing needed
    tmp_keys = pool.get("sort.keys", 4 * n, what=f"a sort of {n} keys", clear=False)
    tmp_values = pool.get("sort.values", 4 * n, what=f"a sort of {n} values", clear=False)
    counts = pool.get("sort.counts", 4 * n_counts, what="radix sort digit counts", clear=False)
    _barrier(ctx)  # the caller's writes to keys and values are visible to the first dispatch

    defines = {"WG_SIZE": wg, "ITEMS": items, "DIGIT_BITS": bits}
    count = compute_program(ctx, "sort/radix_count.comp", defines)
    scatter = compute_program(ctx, "sort/radix_scatter.comp", defines)
    src, dst = (keys, values), (tmp_keys, tmp_values)
    for p in range(passes):
        shift = p * bits
        set_uniforms(count, {"u_n": n, "u_shift": shift})
        bind(count, KeysIn=src[0], Counts=counts)
        _run(ctx, count, groups)
        exclusive_scan(ctx, counts, counts, n_counts)
        set_uniforms(scatter, {"u_n": n, "u_shift": shift})
        bind(scatter, KeysIn=src[0], ValuesIn=src[1], KeysOut=dst[0], ValuesOut=dst[1], Offsets=counts)
        _run(ctx, scatter, groups)
        src, dst = dst, src
    if src[0] is not keys:
        ctx.mgl.copy_buffer(keys, src[0], size=4 * n)
        ctx.mgl.copy_buffer(values, src[1], size=4 * n)
        _barrier(ctx)
