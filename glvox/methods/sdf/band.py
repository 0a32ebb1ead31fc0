"""The GPU band pass of :mod:`glvox.methods.sdf`: exact unsigned distances near the surface.

``shaders/sdf/band.comp`` (its header has the scheme): every (triangle,
column) pair of the triangle's box dilated by the radius, one invocation
each, walks the column where it crosses the slab around the triangle's plane
and keeps, per voxel center, the least distance to a triangle (double
arithmetic, rounded once to float32).  The CPU only prepares per-triangle
boxes and the prefix sums of their column counts (numpy, O(F)).
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import LimitError
from ...gl.shaders import compute_program
from ...gpu.buffers import buffer_pool, check_buffer_size, clear_buffer
from ...gpu.dispatch import LOOP_BUDGET, barrier, bind, dispatch_1d, set_uniforms

_LOCAL = 64
_POOL = "sdf"
#: Columns per dispatch: bounded so that one dispatch does not hold the GPU
#: for long (a watchdog on desktop GPUs) and stays within 2^32 invocations.
COLUMNS_PER_DISPATCH = 1 << 20
#: The float bits of +inf: a voxel no triangle reached within the radius.
FAR_BITS = 0x7F800000


def triangle_columns(tri_vox: np.ndarray, dims, radius: float):
    """Per triangle the dilated box, its column axis, the slab half-width and the column counts.

    Parameters
    ----------
    tri_vox : (F, 3, 3) float64
        Triangles in voxel units (voxel (i, j, k)'s center at (i, j, k) + 0.5).
    dims : (3,) int
    radius : float
        Voxels.

    Returns
    -------
    geo : (F, 9) float64
        a, b - a, c - a.
    plane : (F, 4) float32
        Unit normal, slab half-width ``radius`` plus how far b and c lie off the
        float normal's plane through a, plus 1e-3 voxel.
    box : (F, 2, 4) int32
        Lowest and highest voxel of the dilated box (clipped to the grid), the
        column axis in ``box[:, 0, 3]``.
    counts : (F,) int64
        Columns per triangle (0 when the box misses the grid).
    """
    a = tri_vox[:, 0]
    ab, ac = tri_vox[:, 1] - a, tri_vox[:, 2] - a
    n = np.cross(ab, ac)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    n32 = n.astype(np.float32)
    off = np.maximum(np.abs(np.einsum("ij,ij->i", n32.astype(np.float64), ab)),
                     np.abs(np.einsum("ij,ij->i", n32.astype(np.float64), ac)))
    dims_a = np.asarray(dims, np.int64)
    lo = np.maximum(np.ceil(tri_vox.min(axis=1) - radius - 0.5), 0).astype(np.int64)
    hi = np.minimum(np.floor(tri_vox.max(axis=1) + radius - 0.5), dims_a - 1).astype(np.int64)
    axis = np.argmax(np.abs(n), axis=1)
    ext = np.maximum(hi - lo + 1, 0)
    rows = np.arange(len(tri_vox))
    counts = ext[rows, (axis + 1) % 3] * ext[rows, (axis + 2) % 3] * (ext[rows, axis] > 0)
    box = np.zeros((len(tri_vox), 2, 4), np.int32)
    box[:, 0, :3], box[:, 0, 3] = lo, axis
    box[:, 1, :3] = hi
    plane = np.empty((len(tri_vox), 4), np.float32)
    plane[:, :3] = n32
    plane[:, 3] = radius + off + 1e-3
    geo = np.concatenate([a, ab, ac], axis=1)
    return geo, plane, box, counts


def column_chunk(radius: float) -> int:
    """Columns per work item: at most 64, fewer for wide bands, so that one invocation
    loops at most about 4096 times (each column crosses at most 2 sqrt(3) radius + 2
    voxels of the slab), far below llvmpipe's loop budget (:data:`LOOP_BUDGET`)."""
    per_column = 2.0 * math.sqrt(3.0) * radius + 3.0
    chunk = max(1, min(64, int(4096 // per_column)))
    if chunk * per_column + chunk > LOOP_BUDGET:  # a radius past the grid's reach
        raise LimitError(f"an SDF band of {radius:g} voxels is too wide for one shader invocation; "
                         "use band='all' instead")
    return chunk


def work_items(counts: np.ndarray, chunk: int) -> np.ndarray:
    """(M, 2) uint32 work items: (triangle, first column), ``chunk`` columns each, for
    triangles with ``counts`` columns."""
    per = (counts + chunk - 1) // chunk
    total = int(per.sum())
    if total >= 2 ** 32:
        raise LimitError(f"the SDF band pass has {total} work items, over 2^32; use a smaller grid or a "
                         "narrower band")
    tri = np.repeat(np.arange(len(counts), dtype=np.uint32), per)
    starts = np.zeros(len(counts), np.int64)
    np.cumsum(per[:-1], out=starts[1:])
    first = (np.arange(total, dtype=np.int64) - np.repeat(starts, per)) * chunk
    return np.ascontiguousarray(np.stack([tri, first.astype(np.uint32)], axis=1))


def band_distances(ctx, tri_vox: np.ndarray, dims, radius: float, timer) -> np.ndarray:
    """Unsigned distances (voxels) from the voxel centers to the triangles, where at most ``radius``.

    Parameters
    ----------
    ctx : GLContext
    tri_vox : (F, 3, 3) float64
        Triangles in voxel units.
    dims : (3,) int
    radius : float
        Voxels.
    timer : StageTimer

    Returns
    -------
    (nx, ny, nz) float32, C order
        The distance in voxels to the nearest triangle at voxels within
        ``radius`` of one, ``inf`` elsewhere.
    """
    nx, ny, nz = (int(x) for x in dims)
    n_vox = nx * ny * nz
    with timer.stage("sdf_prepare", gpu=False):
        geo, plane, box, counts = triangle_columns(tri_vox, dims, radius)
        chunk = column_chunk(radius)
        items = work_items(counts, chunk)
        total = len(items)
        arrays = {"geo": np.ascontiguousarray(geo), "plane": plane, "box": np.ascontiguousarray(box),
                  "items": items}
        check_buffer_size(ctx, n_vox * 4, "the SDF distance grid")
        pool = buffer_pool(ctx, _POOL)
        bufs = {}
        for name, arr in arrays.items():
            buf = pool.get(name, arr.nbytes, what=f"the SDF {name}", clear=False)
            buf.write(arr.tobytes())
            bufs[name] = buf
        dist = pool.get("dist", n_vox * 4, what="the SDF distance grid", clear=False)
        clear_buffer(ctx, dist, n_vox * 4, FAR_BITS)
    with timer.stage("sdf_band"):
        prog = compute_program(ctx, "sdf/band.comp")
        bind(prog, Geo=bufs["geo"], Plane=bufs["plane"], Box=bufs["box"], Items=bufs["items"], Dist=dist)
        set_uniforms(prog, {"u_dims": (nx, ny, nz), "u_chunk": chunk, "u_radius": float(radius)})
        for first in range(0, total, COLUMNS_PER_DISPATCH):
            count = min(COLUMNS_PER_DISPATCH, total - first)
            set_uniforms(prog, {"u_first": first, "u_count": count})
            dispatch_1d(ctx, prog, count, _LOCAL)
        barrier(ctx)
    with timer.stage("sdf_readback", gpu=False):
        out = np.empty((nx, ny, nz), dtype=np.float32)  # read_into: no bytes object, no second copy
        dist.read_into(out, size=n_vox * 4)
    timer.stats["sdf_columns"] = int(counts.sum())
    timer.stats["sdf_items"] = total
    return out
