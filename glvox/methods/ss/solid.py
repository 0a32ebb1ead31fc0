"""Schwarz & Seidel 2010 solid voxelization in compute shaders (Sec. 4).

``ss-solid`` (Sec. 4.1) runs one invocation per triangle (and chunk of its
columns): every voxel column along x whose center the triangle's (y, z)
projection covers, under the top-left fill rule, gets the voxels from
``floor(q + 1/2)`` to its end flipped.  The paper flips them with
``atomicXor`` word by word (up to nx / 32 atomics per crossing); here a
crossing flips one bit, voxel ``floor(q + 1/2)``, of the cleared grid, and a
``fill`` pass (``ss/solid_fill.comp``) turns each row into the prefix XOR of
its crossings in place: the same voxels (XOR commutes), with one atomic per
crossing and O(N^3 / 32) word operations at most.  The fill pass visits only
the rows inside the mesh's projected bounding box (:func:`mesh_rows`, from
the bounds kept with the uploaded mesh: no readback), writes only the words
that change, and counts the set voxels; only the z slices of those rows are
read back.  The first voxelization pass sets each triangle up once and does
its first chunk of columns; the rare triangles with more chunks are listed
for a second, indirect pass; on large grids the triangles go in
:func:`~glvox.methods.ss.solid_tuning.row_order`, so that neighbouring
invocations flip bits in nearby rows.  One bit per crossing and the in-place
fill over the mesh's rows each took less time than the paper's word-by-word
flips (measured with ``glvox bench`` on the bunny and the dragon; figures in
compare/README.md).

``ss-solid-tiled`` (Sec. 4.2) assigns triangles to tiles of 4 x 4 columns
instead and processes each tile's triangles without atomics:

* ``pairs``: per triangle, the tiles whose critical column center passes the
  edge tests are counted (``ss/tile_pairs.comp``), the counts are scanned
  (:func:`glvox.gpu.sort.exclusive_scan`) and the (tile, triangle) pairs
  written at each triangle's offset;
* ``sort``: the pairs are sorted by tile (:func:`glvox.gpu.sort.sort_pairs`,
  only the significant key bits);
* ``compact``: the first pair of each tile is flagged, the flags scanned and
  the active tiles compacted into a list with their ranges;
* ``tiles``: one work group of 16 invocations per active tile, one per
  column, walks the tile's triangles keeping an active 32-bit segment and a
  flip bitmask of the segments after it, and writes each row once per
  segment at the end, with plain (non-atomic) xor: a row belongs to one
  invocation.

Both share ``shaders/ss/solid.glsl`` with ``ss-octree``, so the three decide
every crossing with the same arithmetic (edge functions in double from the
float32 voxel-space vertices; see that file for why).

Only sizes are read back inside the tiled pipeline (the number of pairs, to
size the sort; the active tiles and the fullest tile's length, to size the tile
passes); scan, sort and compaction run on the GPU.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import LimitError
from ...gl.shaders import compute_program
from ...gpu.buffers import MAX_SLAB_VOXELS, buffer_pool, clear_buffer, read_grid_words, slab_reader, z_slabs
from ...gpu.sort import SHADERS as SORT_SHADERS, exclusive_scan, sort_pairs
from ...gpu.dispatch import LOOP_BUDGET, barrier, bind, dispatch_1d, grid_uniforms, set_uniforms
from ...gpu.fixed_point import fixed_bits
from ...gpu.transform import SHADERS as TRANSFORM_SHADERS, transform_vertices
from ...grid import GridSpec
from ...results.voxels import VoxelGrid
from ..base import Method, MethodInfo, Requirements, register
from .chunks import chunked_passes
from .solid_tuning import fill_defines, fill_rows, voxelize_faces

_PAPER = "Schwarz & Seidel 2010"
_LOCAL = 64  # local_size_x of ss/solid_classify.comp, ss/solid.comp, ss/tile_pairs.comp

#: Tile edge in columns (Sec. 4.2: 4 x 4 voxel columns per tile).
TILE = 4

#: Tiles tested per invocation of the pair passes (each test is a handful of
#: loop iterations at most, far below LOOP_BUDGET).
TILE_CHUNK = 4096

#: Triangles of one tile handled per pass of ``ss/tile_process.comp``: an
#: invocation loops over at most this many (each at most a dozen loop
#: iterations should the compiler keep the three-edge loops, plus the final
#: flush of at most MAX_SEGMENTS words), within LOOP_BUDGET.
TILE_TRIANGLES = 2048

#: Segments (32-bit words) per row the tiled flip bitmask holds (uvec4): rows
#: up to 4096 voxels.
MAX_SEGMENTS = 128

assert 12 * TILE_TRIANGLES + MAX_SEGMENTS < LOOP_BUDGET
assert 8 * TILE_CHUNK < LOOP_BUDGET


#: Columns per invocation of ``ss/solid.comp``: a column costs its three edge
#: tests and one atomic; the largest power of two keeping an invocation under
#: half of LOOP_BUDGET.
COLUMN_CHUNK = 1 << (((LOOP_BUDGET // 2) // 5).bit_length() - 1)


def rotation(axis: int) -> tuple[int, int, int]:
    """The axes of the frame whose x runs along grid axis ``axis``: ``(a, a+1, a+2) % 3``
    (a rotation, so ``reference-solid(axis=a)``'s (u, v) plane is that frame's (y, z))."""
    return (axis, (axis + 1) % 3, (axis + 2) % 3)


def rotated_spec(spec, axis: int):
    """``spec`` seen in the frame of :func:`rotation`: dims and origin permuted."""
    ax = list(rotation(axis))
    return GridSpec(tuple(spec.dims[a] for a in ax), np.asarray(spec.origin)[ax], spec.voxel_size)


def mesh_rows(spec, bufs, axis: int = 0) -> tuple[int, int, int, int]:
    """The rows (j, k) of ``spec`` that can hold a crossing of the mesh of
    ``bufs``: ``(j0, k0, nj, nk)``, the mesh's (y, z) bounding box widened by
    a row on each side, for the GPU's float32 rounding of the voxel-space
    vertices (the bounds here are float64; a bound that matters lies within
    the grid, at most 65536 voxels from its origin, where float32 is exact to
    1/128 voxel); ``nj * nk`` may be 0.  With ``axis`` the rows run along
    that grid axis, and (j, k) are the coordinates of :func:`rotation`'s
    frame (``spec`` is the grid's own).

    A row holds a crossing only when its center (j + 1/2, k + 1/2) lies in a
    triangle's projection, hence inside the mesh's projected bounding box.
    """
    ax = list(rotation(axis))
    origin = (np.asarray(spec.origin, np.float64) - bufs.anchor)[ax]
    lo = (bufs.bounds[0, ax[1:]] - origin[1:]) / spec.voxel_size
    hi = (bufs.bounds[1, ax[1:]] - origin[1:]) / spec.voxel_size
    first = np.maximum(np.floor(lo - 0.5) - 1, 0)
    last = np.minimum(np.ceil(hi - 0.5) + 1, np.asarray([spec.dims[a] for a in ax[1:]]) - 1)
    if not (np.all(np.isfinite(first)) and np.all(np.isfinite(last))) or np.any(last < first):
        return 0, 0, 0, 0
    (j0, k0), (j1, k1) = first.astype(np.int64), last.astype(np.int64)
    return int(j0), int(k0), int(j1 - j0 + 1), int(k1 - k0 + 1)


def _indirect_chunks(ctx, pool, n, stats, max_groups):
    """Indirect dispatch args over (triangle, chunk) from the GPU-side max chunk count."""
    args = pool.get("args", 3 * 4, clear=False)
    dargs = compute_program(ctx, "ss/dispatch_args.comp")
    set_uniforms(dargs, {"u_sorted": False, "u_groups_x": -(-n // _LOCAL), "u_max_groups": max_groups,
                         "u_local_size": _LOCAL})
    bind(dargs, Stats=stats, Args=args)
    dargs.run(1, 1, 1)
    barrier(ctx)
    return args


def _check_triangles(ctx, n, name):
    max_groups = int(ctx.limits()["GL_MAX_COMPUTE_WORK_GROUP_COUNT"][0])
    if n > max_groups * _LOCAL:
        raise LimitError(
            f"{name} dispatches one invocation per triangle along x, at most {max_groups * _LOCAL} "
            f"(GL_MAX_COMPUTE_WORK_GROUP_COUNT {max_groups} x {_LOCAL}); this mesh has {n} triangles"
        )
    return max_groups


def _classify(ctx, timer, bufs, vox, pool, unit, chunk, uniforms):
    """Stage ``classify``: chunks per triangle (tri_chunks) and their maximum (stats[3]);
    ``uniforms``: the grid's and ``u_solid_fix_bits``."""
    n = bufs.n_triangles
    stats = pool.get("stats", 8 * 4)
    tri_chunks = pool.get("tri_chunks", n * 4, what="per-triangle chunk counts", clear=False)
    prog = compute_program(ctx, "ss/solid_classify.comp", {"SOLID_UNIT": unit, "SOLID_CHUNK": chunk})
    set_uniforms(prog, {**uniforms, "u_triangles": n})
    with timer.stage("classify"):
        bind(prog, VoxVerts=vox, Faces=bufs.faces, Stats=stats, TriChunks=tri_chunks)
        dispatch_1d(ctx, prog, n, _LOCAL)
        barrier(ctx)
    return stats, tri_chunks


#: Defines of the tiled passes.
_TILE_DEFINES = {"TILE": TILE, "SOLID_CHUNK": TILE_CHUNK}
#: The compute shaders the solid passes compile (what a method reusing them adds
#: to its requirements).
COMPUTE = tuple((f"ss/{name}.comp", {}) for name in (
    "dispatch_args", "solid", "solid_big_args", "solid_classify", "solid_fill", "solid_fill_axis",
    "tile_compact", "tile_pairs")) + (("ss/tile_process.comp", _TILE_DEFINES),) + SORT_SHADERS + TRANSFORM_SHADERS
_REQUIRES = Requirements(gl_version=430, extensions=("GL_ARB_gpu_shader_fp64",),
                         limits={"GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 9}, compute=COMPUTE)


def _tile_pairs(ctx, pool, bufs, vox, tri_chunks, stats, common, max_groups):
    """The (tile, triangle) work queue: per triangle the tiles whose critical column
    center passes the edge tests are counted, the counts scanned, and the pairs written
    at each triangle's offset.  Returns (keys, values, n_pairs): tiles and triangles."""
    n = bufs.n_triangles
    args = _indirect_chunks(ctx, pool, n, stats, max_groups)
    counts = pool.get("counts", n * 4, what="per-triangle tile counts")
    total = pool.get("total", 4, clear=False)
    count = compute_program(ctx, "ss/tile_pairs.comp", {**_TILE_DEFINES, "EMIT": 0})
    set_uniforms(count, common)
    bind(count, VoxVerts=vox, Faces=bufs.faces, TriChunks=tri_chunks, Counts=counts)
    count.run_indirect(args)
    barrier(ctx)
    exclusive_scan(ctx, counts, counts, n, total=total)
    barrier(ctx)
    # the one value the CPU needs inside the pipeline: the queue length sizes the sort
    n_pairs = int(np.frombuffer(total.read(size=4), dtype="<u4")[0])
    keys = pool.get("keys", n_pairs * 4, what=f"{n_pairs} tile keys", clear=False)
    values = pool.get("values", n_pairs * 4, what=f"{n_pairs} tile triangles", clear=False)
    emit = compute_program(ctx, "ss/tile_pairs.comp", {**_TILE_DEFINES, "EMIT": 1})
    set_uniforms(emit, common)
    bind(emit, VoxVerts=vox, Faces=bufs.faces, TriChunks=tri_chunks, Counts=counts, Keys=keys, Values=values)
    emit.run_indirect(args)
    barrier(ctx)
    return keys, values, n_pairs


def _compact_tiles(ctx, pool, keys, n_pairs):
    """The active tiles with their ranges in the sorted queue: the first pair of each tile
    flagged, the flags scanned, the tiles compacted.  Returns (active, tile_stats): the
    list and (active tiles, the fullest tile's triangles, ...) as uint32."""
    flags = pool.get("flags", n_pairs * 4, what="tile start flags", clear=False)
    slots = pool.get("slots", n_pairs * 4, what="tile slots", clear=False)
    active = pool.get("active", n_pairs * 8, what="active tile list", clear=False)
    tstats = pool.get("tile_stats", 4 * 4)
    for phase in (0, 1, 2):
        if phase == 1:
            exclusive_scan(ctx, flags, slots, n_pairs, total=tstats)
            barrier(ctx)
        prog = compute_program(ctx, "ss/tile_compact.comp", {"PHASE": phase})
        set_uniforms(prog, {"u_pairs": n_pairs})
        bind(prog, Keys=keys, Flags=flags, Slots=slots, Active=active, Stats=tstats)
        # phase 2 runs over active tiles, of which there are at most as many as pairs
        dispatch_1d(ctx, prog, n_pairs, 256)
        barrier(ctx)
    return active, tstats


@dataclass
class Parity:
    """:func:`parity_on_gpu`'s buffers: the solid in ``grid`` (packed, the grid's own
    layout), along x also its voxel count in ``count`` and the rows it filled."""

    grid: Any
    count: Any
    big: Any
    rows: tuple[int, int, int, int]

    def read_stats(self, stats: dict) -> int:
        """Read the voxel count back and put the chunk and row statistics into ``stats``."""
        s = np.frombuffer(self.big.read(size=8), dtype="<u4")
        stats["triangles_with_several_chunks"] = int(s[0])
        stats["max_chunks"] = int(s[1]) + 1 if s[0] else 1
        stats["fill_rows"] = self.rows[2] * self.rows[3]
        return int(np.frombuffer(self.count.read(size=4), dtype="<u4")[0])


#: Cells of a y or z column one invocation of ``ss/solid_fill_axis.comp``
#: walks (one load and XOR each); longer columns take a dispatch per segment.
AXIS_SEGMENT = 16384
assert AXIS_SEGMENT < LOOP_BUDGET


def parity_on_gpu(ctx, mesh, spec, timer, pool, *, axis: int = 0, tag: str = "",
                  slabs: list[tuple[int, int]] | None = None, read_slab=None, trace=None) -> Parity:
    """ss-solid's parity of crossings along grid axis ``axis`` in GPU buffers, nothing
    read back: stages ``transform``, ``voxelize``, ``fill`` (each name + ``tag``).

    The building block of ``ss-solid`` (axis 0) and ``vote-solid`` (every
    axis).  Along y or z the transform rotates the vertices (:func:`rotation`),
    so the voxelize passes, written for x columns, run unchanged and decide
    every crossing exactly as ``reference-solid(axis=axis)`` does; they put
    the crossing bits into the grid's own layout (``FLIP_AXIS``), and
    ``ss/solid_fill_axis.comp`` runs the XOR down the columns along that axis.

    Parameters
    ----------
    ctx : GLContext
    mesh : Mesh
    spec : GridSpec
    timer : StageTimer
    pool : BufferPool
        The caller's pool; buffers ``grid``, ``vox_vertices``, ``big``,
        ``count`` and ``args`` (each name + ``tag``).
    axis : {0, 1, 2}
        Ray direction, as ``reference-solid``'s ``axis``.
    tag : str
        Suffix of the buffer and stage names, so several axes coexist.
    slabs : list of (k0, nk), optional
        Along x only: the grid in z slabs (:func:`~glvox.gpu.buffers.z_slabs`).
        The transform runs once, then each slab's crossings and fill (its rows
        alone, voxel for voxel those of the whole grid: a row's parity is its
        own) into the grid buffer, which holds one slab, and
        ``read_slab(k0, nk, grid)`` takes it before the next.  ``count`` then
        sums every slab's voxels; ``big`` holds the last slab's list.
    trace : moderngl.Buffer, optional
        Receives every crossing (``SolidTrace`` of ``ss/solid.comp``: a count, then
        4 words per crossing), for :func:`glvox.testing.tie_probe.trace`; None
        (the methods) compiles no trace.

    Returns
    -------
    Parity
        ``grid`` holds the uint32 (nz, ny, words_per_row) words of ``spec`` (with
        ``slabs``, the last slab's); ``count`` and ``rows`` are set along x only.
    """
    n = mesh.n_triangles
    max_groups = _check_triangles(ctx, n, "ss-solid")
    fix_bits = fixed_bits(mesh, spec, axis)
    rspec = rotated_spec(spec, axis)
    if slabs is not None and axis != 0:
        raise ValueError("slabs are z slabs of x rows: axis 0 only")
    # one buffer: the voxelize pass flips crossing bits into the cleared
    # grid, the fill pass turns them into voxels in place
    per_slice = spec.dims[1] * spec.words_per_row * 4
    slices = spec.dims[2] if slabs is None else max(nk for _, nk in slabs)
    grid = pool.get("grid" + tag, slices * per_slice, what=f"the {spec.dims} bit grid")
    bufs, vox = transform_vertices(ctx, mesh, spec, timer, pool, axes=rotation(axis), name="vox_vertices" + tag,
                                   stage="transform" + tag)
    big = pool.get("big" + tag, (n + 2) * 4, what="the triangles with several column chunks", clear=False)
    clear_buffer(ctx, big, 8)
    uniforms = {**grid_uniforms(rspec, bufs.anchor[list(rotation(axis))]), "u_solid_fix_bits": fix_bits}
    slab = {} if slabs is None else {"VOX_SLAB": 1}
    traced = {} if trace is None else {"SOLID_TRACE": 1}
    first, rest = (compute_program(ctx, "ss/solid.comp", {"SOLID_CHUNK": COLUMN_CHUNK, "FIRST": f,
                                                          "FLIP_AXIS": axis, **slab, **traced}) for f in (1, 0))
    for prog in (first, rest):
        set_uniforms(prog, {**uniforms, "u_triangles": n})
    count = pool.get("count" + tag, 4)
    args = pool.get("args" + tag, 3 * 4, clear=False)
    faces = voxelize_faces(ctx, mesh, spec, bufs)
    blocks = {"VoxVerts": vox, "Faces": faces, "Crossings": grid, **({} if trace is None else {"SolidTrace": trace})}
    rows = mesh_rows(spec, bufs, 0)
    if slabs is None:
        with timer.stage("voxelize" + tag):
            chunked_passes(ctx, (first, rest), n, max_groups, blocks, big, args, _LOCAL)
        with timer.stage("fill" + tag):
            _fill(ctx, spec, grid, count, rows, axis)
        return Parity(grid, count, big, rows)
    j0, k0_rows, nj, nk_rows = rows
    for i, (k0, nk) in enumerate(slabs):
        if k0:
            clear_buffer(ctx, grid, nk * per_slice)
            clear_buffer(ctx, big, 8)
        for prog in (first, rest):
            set_uniforms(prog, {"u_slab": (k0, nk)})
        with timer.stage("voxelize" + tag):
            chunked_passes(ctx, (first, rest), n, max_groups, blocks, big, args, _LOCAL)
        # the mesh's rows in this slab, k counted from the slab's first slice
        lo, hi = max(k0_rows, k0), min(k0_rows + nk_rows, k0 + nk)
        with timer.stage("fill" + tag):
            if hi > lo and nj:
                _fill(ctx, spec, grid, count, (j0, lo - k0, nj, hi - lo), axis)
        read_slab(k0, nk, grid)
        timer.slab_done(i + 1, len(slabs))
    return Parity(grid, count, big, rows)


def _fill(ctx, spec, grid, count, rows, axis: int) -> None:
    """The crossing bits of ``grid`` into voxels along ``axis``: the prefix XOR of the
    rows of ``rows`` (x, counted into ``count``), or of every y or z column."""
    wpr = spec.words_per_row
    vec = 4 if wpr % 4 == 0 else 2 if wpr % 2 == 0 else 1
    if axis == 0:
        defines = fill_defines(ctx, wpr)
        per = fill_rows(defines, wpr, rows[2] * rows[3], _LOCAL)
        fill = compute_program(ctx, "ss/solid_fill.comp", defines)
        set_uniforms(fill, {**grid_uniforms(spec, np.zeros(3)), "u_rows": rows, "u_rows_per": per})
        bind(fill, Grid=grid, Count=count)
        dispatch_1d(ctx, fill, -(-rows[2] * rows[3] // per), _LOCAL)
        barrier(ctx)
        return
    fill = compute_program(ctx, "ss/solid_fill_axis.comp", {"AXIS": axis, "VEC": vec, "SEGMENT": AXIS_SEGMENT})
    set_uniforms(fill, grid_uniforms(spec, np.zeros(3)))
    lines = wpr // vec * spec.dims[3 - axis]  # columns along y: (words, z); along z: (words, y)
    bind(fill, Grid=grid)
    for seg in range(-(-spec.dims[axis] // AXIS_SEGMENT)):
        set_uniforms(fill, {"u_segment": seg})
        dispatch_1d(ctx, fill, lines, _LOCAL)
        barrier(ctx)


@register
class SSSolid(Method):
    info = MethodInfo(
        name="ss-solid", kind="solid", pipeline="compute",
        paper=f"{_PAPER}, Sec. 4.1 (direct, triangle-parallel solid voxelization)",
        summary="solid, one compute invocation per triangle, one atomicXor per crossing, then a "
                "prefix-XOR fill of every row",
        reference="reference-solid",
        requires=_REQUIRES, max_voxels=MAX_SLAB_VOXELS,
    )

    def run(self, mesh, spec, *, ctx, timer):
        pool = buffer_pool(ctx, self.info.name)
        slabs = z_slabs(ctx, spec)
        if slabs is None:
            p = parity_on_gpu(ctx, mesh, spec, timer, pool)
            with timer.stage("readback", gpu=False):
                # slices outside the mesh's rows hold nothing: only the others are read
                words = read_grid_words(ctx, p.grid, spec, (p.rows[1], p.rows[3]))
                voxels = p.read_stats(timer.stats)
        else:  # over the storage-block limit: slab by slab, each read into its part of the result
            words, read_slab = slab_reader(ctx, spec, timer)
            p = parity_on_gpu(ctx, mesh, spec, timer, pool, slabs=slabs, read_slab=read_slab)
            voxels = p.read_stats(timer.stats)
            timer.stats["slabs"] = len(slabs)
            timer.merge_repeats()
        # ss/solid_fill.comp counts in a uint32: not where a grid has 2^32 voxels or more
        return VoxelGrid(words=words, spec=spec, count=voxels if spec.n_voxels < 2**32 else None)


@register
class SSSolidTiled(Method):
    info = MethodInfo(
        name="ss-solid-tiled", kind="solid", pipeline="compute",
        paper=f"{_PAPER}, Sec. 4.2 (tile-based solid voxelization)",
        summary="solid, (tile, triangle) work queue built by GPU scan and sort, 4x4-column tiles "
                "processed without atomics",
        reference="reference-solid",
        requires=_REQUIRES,
    )

    def run(self, mesh, spec, *, ctx, timer):
        n = mesh.n_triangles
        nx, ny, nz = spec.dims
        if spec.words_per_row > MAX_SEGMENTS:
            raise LimitError(
                f"ss-solid-tiled keeps a flip bitmask of at most {MAX_SEGMENTS} words per row, rows of "
                f"{32 * MAX_SEGMENTS} voxels; this grid has nx = {nx}: use ss-solid, or ss-octree"
            )
        max_groups = _check_triangles(ctx, n, "ss-solid-tiled")
        fix_bits = fixed_bits(mesh, spec, 0)
        pool = buffer_pool(ctx, self.info.name)
        grid = pool.get("grid", spec.n_words * 4, what=f"the {spec.dims} bit grid")
        count = pool.get("count", 4)
        bufs, vox = transform_vertices(ctx, mesh, spec, timer, pool)
        tiles_y, tiles_z = -(-ny // TILE), -(-nz // TILE)
        key_bits = max(1, (tiles_y * tiles_z - 1).bit_length())
        common = {**grid_uniforms(spec, bufs.anchor), "u_solid_fix_bits": fix_bits, "u_triangles": n}
        stats, tri_chunks = _classify(ctx, timer, bufs, vox, pool, TILE, TILE_CHUNK, common)
        with timer.stage("pairs"):
            keys, values, n_pairs = _tile_pairs(ctx, pool, bufs, vox, tri_chunks, stats, common, max_groups)
        with timer.stage("sort"):
            sort_pairs(ctx, keys, values, n_pairs, key_bits=key_bits)
        with timer.stage("compact"):
            active, tstats = _compact_tiles(ctx, pool, keys, n_pairs)
        # the second and last sizes read inside the pipeline: active tiles and the
        # fullest tile's triangles give the work groups and passes of the tile stage
        # (issuing an upper bound of passes from the pair count instead cost ~130
        # empty dispatches and barriers at 1024^3)
        active_tiles, most = (int(x) for x in np.frombuffer(tstats.read(size=8), dtype="<u4"))
        passes = -(-most // TILE_TRIANGLES)
        with timer.stage("tiles"):
            proc = compute_program(ctx, "ss/tile_process.comp", {**_TILE_DEFINES, "TILE_TRIANGLES": TILE_TRIANGLES})
            set_uniforms(proc, {**common, "u_pairs": n_pairs})
            bind(proc, VoxVerts=vox, Faces=bufs.faces, Grid=grid, Stats=tstats, Count=count, Active=active,
                 Values=values)
            gx = min(active_tiles, max_groups)
            for p in range(passes):
                set_uniforms(proc, {"u_pass": p})
                proc.run(gx, -(-active_tiles // gx), 1)
                barrier(ctx)
        with timer.stage("readback", gpu=False):
            words = read_grid_words(ctx, grid, spec)
            voxels = int(np.frombuffer(count.read(size=4), dtype="<u4")[0])
        timer.stats.update({
            "pairs": n_pairs, "active_tiles": active_tiles,
            "triangles_per_active_tile": round(n_pairs / active_tiles, 2) if active_tiles else 0.0,
            "max_triangles_per_tile": most, "tile_passes": passes,
        })
        return VoxelGrid(words=words, spec=spec, count=voxels)
