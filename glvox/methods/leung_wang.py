"""Leung & Wang 2013 conservative LDI sampling, the exact depth-peeling LDI, and the CPU reference.

``leung-wang-ldi`` (Leung & Wang 2013, Sec. III; Alg. 1-2, Eq. 1-6).  Rays run
along ``axis`` through the pixel centers of the grid's other two axes
(:mod:`glvox.ldi`); along the rays the range of the grid is cut into
``lod_c`` cells (the paper's r_z, "Level of Details in Conservation").

* Phase 1 (Alg. 1): T1, the XOR solid voxelization of Eisemann & Decoret on
  the cells (bit k: inside at the top of cell k), and T2, an OR pass marking
  the cells that hold crossings while T1 is 0 on both sides (parts thinner
  than a cell).  Both render the mesh orthographically into
  :data:`TARGETS` RGBA32UI targets, 128 cells each (1024 per pass; more
  passes for a larger LOD-C), with the logic op; a compute pass copies each
  pass into a mask buffer holding each ray's words consecutively.  The render
  reuses the Eisemann & Decoret machinery (:mod:`glvox.methods.eisemann`'s
  shaders: per-triangle setup, the exact-coverage vertex stage, the column
  tests and mask writers); only the transform (per-axis scale to cells) and
  the two fragment shaders are this module's.
* The n_max pass: the samples per ray by Eq. 5 over the whole ray, the
  maximum and total reduced on the GPU by atomics; n_max (4 bytes) is the
  only value read back before the end.
* Phase 2 (Alg. 2): ceil(n_max / 32) passes of 32 layers through 8 RGBA32F
  targets with MAX blending.  Each fragment classifies its cell from T1 and T2
  (EV, LV, ELV; LEV taken as solid), finds its layer by fast bit checking
  (``bitCount`` over the ray's words, the shifts carried across words) and
  writes ``1 - d`` (entering: MAX keeps the nearest) or ``d`` (leaving) with
  d the depth normalized to [0, 1] (Eq. 6).  A compute pass per pass decodes
  the targets into the depth buffer (voxel units, rounded outwards to float32,
  NaN past the counts).
* A pass binds only the targets its cells or layers need (a LOD-C of 128 one
  target, n_max = 12 three): the passes are the paper's, and on llvmpipe each
  bound target costs about as much as a fragment's own work.

Samples are sorted by construction, counts are even, and every exact
interior segment of a ray lies inside one of the LDI's intervals
(conservative): an interval's end is the nearest (farthest) crossing in its
cell, so it can overshoot the exact one by up to a cell, and cells holding a
gap between two parts (LEV) are filled.  With a LOD-C at which no two
crossings of a ray share a cell, the samples are the crossings themselves.

Conventions beyond the paper (written down in the README): cell z is
``[z, z + 1)`` in cell units and a crossing on the grid's far face belongs to
the last cell, so a face lying on the grid's boundary (the default fit
touches it) is sampled; geometry outside the grid along the axis is clamped
to it (the solid is clipped, as every glvox result); a ray still inside at
the far face (open meshes only) is closed there.  Coverage of pixel centers
is decided exactly (double precision edge functions with the top-left rule,
as ``reference-solid``), not by GL's snapped rasterization, so T1, T2 and the
depth pass see the same fragments.

``peel-ldi``: the exact LDI by depth peeling (Everitt 2001; the peeling of
``passalis-peel``, Passalis et al. 2006 Sec. 3.3, reused from
:mod:`glvox.methods.depth_layers`): one pass per layer, every crossing
recorded in depth order (ties broken by triangle id, so crossings sharing a
depth are all kept), as many passes as the largest stencil count of the first
pass says (or until a pass draws nothing when the 8-bit stencil saturates).
The baseline of the paper's Table II comparison.

``reference-ldi``: the exact crossings on the CPU in float64
(:func:`glvox.reference.ldi.crossings`), rounded to float32.

:func:`intersecting_ldi` is the application of Sec. V-A: T1 and T2 of two
meshes on one grid, their AND (with a T2 for thin overlaps, see
``shaders/ldi/intersect.comp``), and Phase 2 drawing both meshes: the LDI of
the overlap, whose :attr:`~glvox.ldi.LDI.volume` is the intersecting volume.
"""

from __future__ import annotations

import ctypes
import warnings
from dataclasses import dataclass
from typing import Any

import moderngl
import numpy as np

from ..errors import CapabilityError, GridError, LimitError, MethodError, NotWatertightWarning
from ..gl import raw as rawgl
from ..gl.shaders import compute_program, render_program
from ..gpu.buffers import buffer_pool, check_buffer_size, mesh_buffers, object_cache, release_object_cache
from ..gpu.dispatch import LOOP_BUDGET, barrier, dispatch_1d, grid_uniforms, set_uniforms
from ..gpu.transform import transform_vertices
from ..grid import GridSpec, fit_grid, ldi_axes
from ..reference.ldi import crossings
from ..results.ldi import LDI, close_odd
from . import depth_layers, eisemann
from .envelope import run_in_envelope
from .base import Method, MethodInfo, Option, Requirements, register

_PAPER = "Leung & Wang 2013"

#: Render targets per pass (the paper's 8 MRTs): 1024 cells per Phase-1 pass, 32 layers per Phase-2 pass.
TARGETS = eisemann.TARGETS
CELLS_PER_TARGET = eisemann.SLICES_PER_TARGET  # 128: four 32-bit channels
LAYERS_PER_TARGET = 4                          # four float channels

#: The paper's LOD-C of Table II ("in most cases ... accurate enough").
DEFAULT_LOD_C = 1024

#: Largest LOD-C: a ray's masks are LOD-C / 32 words, and the fast bit
#: checking of one fragment and the n_max pass loop over them (2048
#: iterations here, far below the loop budget).
MAX_LOD_C = 1 << 16
assert MAX_LOD_C // 32 < LOOP_BUDGET // 4

#: When set, an upper bound on the tile side (pixels) below the context's
#: limits; the tests force a small one to exercise tiling on small grids.
TILE_LIMIT_OVERRIDE: int | None = None

_LOCAL = 64
#: Storage blocks the fragment shaders read: the mesh (voxel-space vertices,
#: faces), T1 and T2.
_FRAGMENT_BLOCKS = 4
_REQUIRES = Requirements(gl_version=450, limits={
    "GL_MAX_DRAW_BUFFERS": TARGETS, "GL_MAX_COLOR_ATTACHMENTS": TARGETS,
    "GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 12})
_NO_SLICE_CULL = 1 << 30


# ---------------------------------------------------------------------------
# render targets
# ---------------------------------------------------------------------------


@dataclass(eq=False)
class _Targets:
    """``n`` render targets of one format and their framebuffer, grown on demand."""

    textures: list
    fbo: Any
    size: tuple[int, int]

    def release(self, ctx) -> None:
        ctx.release_framebuffer(self.fbo)
        for t in self.textures:
            t.release()


def _cache(ctx) -> dict:
    return object_cache(ctx, "leung-wang", lambda cache: _release_cache(ctx, cache))


def _release_cache(ctx, cache: dict) -> None:
    for tg in cache.values():
        tg.release(ctx)
    cache.clear()


def _targets(ctx, dtype: str, n: int, size: tuple[int, int]) -> _Targets:
    """``n`` RGBA targets of ``dtype`` ('u4' masks, 'f4' depths) of at least ``size`` pixels."""
    cache = _cache(ctx)
    key = (dtype, n)
    tg = cache.get(key)
    if tg is not None and tg.size[0] >= size[0] and tg.size[1] >= size[1]:
        return tg
    if tg is not None:
        size = (max(size[0], tg.size[0]), max(size[1], tg.size[1]))
        tg.release(ctx)
        del cache[key]
    textures = []
    for _ in range(n):
        t = ctx.mgl.texture(size, 4, dtype=dtype)
        t.filter = (moderngl.NEAREST, moderngl.NEAREST)  # integer textures are incomplete otherwise
        textures.append(t)
    tg = _Targets(textures, ctx.mgl.framebuffer(color_attachments=textures), size)
    cache[key] = tg
    return tg


def _clear_targets(ctx, tg: _Targets, n: int, dtype: str) -> None:
    """Zero every target (glClear is undefined on integer buffers; glClearBuffer is not)."""
    tg.fbo.use()
    raw = ctx.raw
    if dtype == "u4":
        zeros = (rawgl.GLuint * 4)()
        for i in range(n):
            raw.fn("glClearBufferuiv")(rawgl.GL_COLOR, i, zeros)
    else:
        zeros = (ctypes.c_float * 4)()
        for i in range(n):
            raw.fn("glClearBufferfv")(rawgl.GL_COLOR, i, zeros)


def tile_limit(ctx) -> int:
    """Largest tile side in pixels: Eisemann & Decoret's (GL limits, memory), or the override."""
    side = eisemann.tile_limit(ctx)
    if TILE_LIMIT_OVERRIDE is not None:
        side = min(side, int(TILE_LIMIT_OVERRIDE))
    if side < 1:
        raise LimitError(f"tile side must be at least 1 pixel, got {side}")
    return side


def _tiles(n: int, side: int) -> list[tuple[int, int]]:
    return [(s, min(side, n - s)) for s in range(0, n, side)]


def _check_fragment_storage(ctx) -> None:
    have = int(ctx.mgl.info.get("GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS", 0))
    if have < _FRAGMENT_BLOCKS:
        raise CapabilityError(
            f"the LDI passes read the mesh and the bit masks from {_FRAGMENT_BLOCKS} shader storage blocks "
            f"in their fragment shaders, but GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS is {have} ({ctx.renderer})")


# ---------------------------------------------------------------------------
# the frame: rays, cells, words
# ---------------------------------------------------------------------------


def _split(units: int, per_target: int, max_targets: int) -> tuple[int, int]:
    """(passes, targets per pass) for ``units`` cells or layers: as few passes as
    ``max_targets`` allows, then as few targets as those passes need (on llvmpipe each
    target costs about as much as the fragment work itself; the paper always uses 8)."""
    need = -(-units // per_target)
    passes = -(-need // max_targets)
    return passes, (-(-need // passes) if passes else 1)


@dataclass(frozen=True)
class _Frame:
    """Rays and cells of one LDI run."""

    spec: Any
    axis: int
    cells: int      # LOD-C
    targets: int    # the most render targets per pass

    @property
    def n_u(self) -> int:
        return self.spec.dims[(self.axis + 1) % 3]

    @property
    def n_v(self) -> int:
        return self.spec.dims[(self.axis + 2) % 3]

    @property
    def n_a(self) -> int:
        return self.spec.dims[self.axis]

    @property
    def n_rays(self) -> int:
        return self.n_u * self.n_v

    @property
    def words(self) -> int:
        return -(-self.cells // 32)

    def phase1(self) -> tuple[int, int]:
        """(passes, targets per pass) of Phase 1: 128 cells per target."""
        return _split(self.cells, CELLS_PER_TARGET, self.targets)

    def phase2(self, n_max: int) -> tuple[int, int]:
        """(passes, targets per pass) of Phase 2: 4 layers per target."""
        return _split(n_max, LAYERS_PER_TARGET, self.targets)

    def column_uniforms(self) -> dict[str, Any]:
        return {"u_cells": self.cells, "u_words": self.words, "u_grid_uv": (self.n_u, self.n_v)}

    def out_shape(self) -> tuple[int, int]:
        p, q = ldi_axes(self.axis)
        return self.spec.dims[p], self.spec.dims[q]


@dataclass(eq=False)
class _OnGrid:
    """A mesh on the GPU in the frame's voxel space, with its per-triangle setup."""

    bufs: Any
    vox: Any
    setup: Any

    def bind(self) -> None:
        self.vox.bind_to_storage_buffer(0)
        self.bufs.faces.bind_to_storage_buffer(1)
        self.setup.bind_to_storage_buffer(3)


def _prepare(ctx, mesh, frame: _Frame, pool, tag: str, timer, suffix: str = "") -> _OnGrid:
    """Stages ``transform`` and ``setup``: vertices to the frame's voxel space (double),
    then Eisemann & Decoret's per-triangle setup (column box, drawn corners)."""
    spec, a = frame.spec, frame.axis
    # across the rays the grid's voxels; along them LOD-C cells, shifted by half a cell
    h = spec.voxel_size
    scale = [1.0 / h] * 3
    scale[a] = frame.cells / (frame.n_a * h)
    shift = [0.0] * 3
    shift[a] = 0.5
    bufs, vox = transform_vertices(ctx, mesh, spec, timer, pool, double=True, scale=scale, shift=shift,
                                   name=f"vox_{tag}", stage=f"transform{suffix}")
    setup = pool.get(f"setup_{tag}", bufs.n_triangles * 48, what="per-triangle setup", clear=False)
    prog = compute_program(ctx, "eisemann/setup.comp", {"EIS_AXIS": a, "EIS_OP": 0, "EIS_COVERAGE": 0})
    dims = list(spec.dims)
    dims[a] = frame.cells
    set_uniforms(prog, {"u_triangles": bufs.n_triangles, "u_dims": tuple(dims)})
    with timer.stage(f"setup{suffix}"):
        vox.bind_to_storage_buffer(0)
        bufs.faces.bind_to_storage_buffer(1)
        setup.bind_to_storage_buffer(3)
        dispatch_1d(ctx, prog, bufs.n_triangles, _LOCAL)
        barrier(ctx)
    return _OnGrid(bufs, vox, setup)


def _draw_defines(frame: _Frame, n_targets: int, **extra) -> dict[str, Any]:
    return {"EIS_AXIS": frame.axis, "EIS_TARGETS": n_targets, "EIS_MASKS": 0, "EIS_COVERAGE": 0,
            "EIS_OP": 0, **extra}


def _store_defines(frame: _Frame, dtype: str, n_targets: int) -> dict[str, Any]:
    fmt = {"u4": ("rgba32ui", "uimage2D", "uvec4"), "f4": ("rgba32f", "image2D", "vec4")}[dtype]
    return {"EIS_AXIS": frame.axis, "LDI_TARGETS": n_targets, "LDI_LAYERS": LAYERS_PER_TARGET * n_targets,
            "LDI_TARGET_FORMAT": fmt[0], "LDI_TARGET_TYPE": fmt[1], "LDI_TEXEL_TYPE": fmt[2]}


# ---------------------------------------------------------------------------
# Phase 1: T1 (XOR) and T2 (OR)
# ---------------------------------------------------------------------------


def _render_mask(ctx, frame: _Frame, mesh: _OnGrid, op: str, out, t1, timer, stage: str, stats) -> None:
    """One mask (``op`` 'xor': T1; 'or': T2, reading ``t1``) into ``out``, tile by tile and pass by pass."""
    fragment = "ldi/t1.frag" if op == "xor" else "ldi/t2.frag"
    passes, n_targets = frame.phase1()
    cells_per_pass = CELLS_PER_TARGET * n_targets
    prog = render_program(ctx, "eisemann/slices.vert", fragment, defines=_draw_defines(frame, n_targets))
    store = compute_program(ctx, "ldi/masks_store.comp", _store_defines(frame, "u4", n_targets))
    set_uniforms(prog, frame.column_uniforms())
    set_uniforms(store, frame.column_uniforms())
    side = tile_limit(ctx)
    tiles_u, tiles_v = _tiles(frame.n_u, side), _tiles(frame.n_v, side)
    tg = _targets(ctx, "u4", n_targets, (tiles_u[0][1], tiles_v[0][1]))
    n_tri = mesh.bufs.n_triangles
    vao = ctx.mgl.vertex_array(prog, [])
    try:
        for u0, tw in tiles_u:
            for v0, th in tiles_v:
                for p in range(passes):
                    lo = p * cells_per_pass
                    hi = lo + cells_per_pass
                    # culling by the setup's first flipped slice floor(q_cell) is exact below the
                    # last pass; the last keeps crossings clamped from the far face
                    tile = {"u_tile_lo": (u0, v0), "u_tile_size": (tw, th), "u_slice_lo": lo,
                            "u_slice_hi": hi if hi < frame.cells else _NO_SLICE_CULL}
                    with timer.stage(stage):
                        _clear_targets(ctx, tg, n_targets, "u4")
                        tg.fbo.viewport = (0, 0, tw, th)
                        set_uniforms(prog, tile)
                        mesh.bind()
                        if t1 is not None:
                            t1.bind_to_storage_buffer(4)
                        with ctx.logic_op(op):
                            vao.render(moderngl.TRIANGLES, vertices=3 * n_tri)
                    with timer.stage(f"{stage}_store"):
                        for t, tex in enumerate(tg.textures):
                            tex.bind_to_image(t, read=True, write=False)
                        out.bind_to_storage_buffer(2)
                        count = tw * th
                        set_uniforms(store, {**tile, "u_invocations": count})
                        dispatch_1d(ctx, store, count, _LOCAL)
                        barrier(ctx)
                    stats["draws"] += 1
    finally:
        vao.release()
    stats["phase1_passes"] = passes
    stats["render_targets"] = [n_targets, stats["render_targets"][1]]
    stats["tiles"] = [len(tiles_u), len(tiles_v)]


# ---------------------------------------------------------------------------
# n_max and Phase 2
# ---------------------------------------------------------------------------


def _count(ctx, frame: _Frame, t1, t2, counts, stats_buf, timer) -> tuple[int, int]:
    """Stage ``count`` (the n_max pass): samples per ray into ``counts``; returns (n_max, samples)."""
    prog = compute_program(ctx, "ldi/count.comp", {"EIS_AXIS": frame.axis})
    set_uniforms(prog, frame.column_uniforms())
    with timer.stage("count"):
        t1.bind_to_storage_buffer(4)
        t2.bind_to_storage_buffer(5)
        counts.bind_to_storage_buffer(6)
        stats_buf.bind_to_storage_buffer(7)
        dispatch_1d(ctx, prog, frame.n_rays, _LOCAL)
        barrier(ctx)
        n_max, samples = (int(x) for x in np.frombuffer(stats_buf.read(size=8), dtype="<u4"))
    return n_max, samples


def _chunks(ctx, n_rays: int, n_layers: int, step: int, what: str) -> list[tuple[int, int]]:
    """(first layer, layers) of the depth buffers: as few as the storage-block limit allows,
    each a whole number of ``step`` layers (one Phase-2 pass never straddles two)."""
    limit = int(ctx.limits()["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"])
    per_step = n_rays * step * 4
    if per_step > limit:
        check_buffer_size(ctx, per_step, f"{what} ({step} layers of {n_rays} rays)")
    cap = (limit // per_step) * step
    total = -(-n_layers // step) * step
    size = min(cap, total)
    return [(lo, min(size, total - lo)) for lo in range(0, total, size)] if total else []


def _read_chunks(bufs_and_chunks, n_rays: int, n_layers: int, shape) -> np.ndarray:
    parts = []
    for buf, (lo, n) in bufs_and_chunks:
        a = np.frombuffer(buf.read(size=n_rays * n * 4), dtype="<f4").reshape(n_rays, n)
        parts.append(a[:, : max(0, min(n, n_layers - lo))])
    if not parts:
        return np.zeros(shape + (0,), dtype=np.float32)
    return np.concatenate(parts, axis=1).reshape(*shape, n_layers)


def _phase2(ctx, frame: _Frame, meshes: list[_OnGrid], t1, t2, counts, n_max: int, pool, timer,
            stats) -> list:
    """Alg. 2: ceil(n_max / layers per pass) MAX-blended passes, each decoded into the depth
    buffers; returns [(buffer, (first layer, layers))] for :func:`_read_chunks`."""
    passes, n_targets = frame.phase2(n_max)
    layers_per_pass = LAYERS_PER_TARGET * n_targets
    chunks = _chunks(ctx, frame.n_rays, n_max, layers_per_pass, "the LDI depths")
    bufs = [pool.get(f"depths{i}", frame.n_rays * n * 4, what="the LDI depths", clear=False)
            for i, (_, n) in enumerate(chunks)]
    stats["phase2_passes"] = passes
    stats["render_targets"] = [stats["render_targets"][0], n_targets if passes else 0]
    if passes == 0:
        return []
    prog = render_program(ctx, "eisemann/slices.vert", "ldi/depths.frag",
                          defines=_draw_defines(frame, n_targets, LDI_TARGETS=n_targets,
                                                LDI_LAYERS=layers_per_pass, LDI_READ_T2=1))
    store = compute_program(ctx, "ldi/store.comp", _store_defines(frame, "f4", n_targets))
    set_uniforms(prog, {**frame.column_uniforms(), "u_slice_lo": -_NO_SLICE_CULL,
                        "u_slice_hi": _NO_SLICE_CULL})
    set_uniforms(store, {**frame.column_uniforms(), "u_n_max": n_max, "u_depth_n": frame.n_a})
    side = tile_limit(ctx)
    tiles_u, tiles_v = _tiles(frame.n_u, side), _tiles(frame.n_v, side)
    tg = _targets(ctx, "f4", n_targets, (tiles_u[0][1], tiles_v[0][1]))
    vao = ctx.mgl.vertex_array(prog, [])
    try:
        ctx.mgl.enable(moderngl.BLEND)
        ctx.mgl.blend_equation = moderngl.MAX
        for u0, tw in tiles_u:
            for v0, th in tiles_v:
                for p in range(passes):
                    lo = p * layers_per_pass
                    chunk = next(i for i, (c0, n) in enumerate(chunks) if c0 <= lo < c0 + n)
                    tile = {"u_tile_lo": (u0, v0), "u_tile_size": (tw, th), "u_layer_lo": lo}
                    with timer.stage("depths"):
                        _clear_targets(ctx, tg, n_targets, "f4")
                        tg.fbo.viewport = (0, 0, tw, th)
                        set_uniforms(prog, tile)
                        t1.bind_to_storage_buffer(4)
                        t2.bind_to_storage_buffer(5)
                        for m in meshes:
                            m.bind()
                            vao.render(moderngl.TRIANGLES, vertices=3 * m.bufs.n_triangles)
                            stats["draws"] += 1
                    with timer.stage("store"):
                        for t, tex in enumerate(tg.textures):
                            tex.bind_to_image(t, read=True, write=False)
                        t1.bind_to_storage_buffer(4)
                        counts.bind_to_storage_buffer(6)
                        bufs[chunk].bind_to_storage_buffer(2)
                        count = tw * th
                        set_uniforms(store, {**tile, "u_chunk_lo": chunks[chunk][0],
                                             "u_chunk_layers": chunks[chunk][1], "u_invocations": count})
                        dispatch_1d(ctx, store, count, _LOCAL)
                        barrier(ctx)
    finally:
        ctx.mgl.blend_equation = moderngl.FUNC_ADD
        ctx.mgl.disable(moderngl.BLEND)
        vao.release()
    return list(zip(bufs, chunks))


def _read_result(frame: _Frame, chunks: list, counts, n_max: int, timer) -> tuple[np.ndarray, np.ndarray]:
    """Stage ``readback``: the depths (n_p, n_q, n_max) float32 and counts (n_p, n_q) int32."""
    with timer.stage("readback", gpu=False):
        depths = _read_chunks(chunks, frame.n_rays, n_max, frame.out_shape())
        cnt = np.frombuffer(counts.read(size=frame.n_rays * 4), dtype="<u4").reshape(frame.out_shape())
    return depths, cnt.astype(np.int32)


# ---------------------------------------------------------------------------
# the pipelines
# ---------------------------------------------------------------------------


def _check(spec, axis: int, lod_c: int, targets: int) -> None:
    if axis not in (0, 1, 2):
        raise MethodError(f"option axis must be 0, 1 or 2, got {axis!r}")
    if not 1 <= int(lod_c) <= MAX_LOD_C:
        raise MethodError(f"option lod_c (cells along the rays) must be in 1..{MAX_LOD_C}, got {lod_c!r}")
    if not 1 <= int(targets) <= TARGETS:
        raise MethodError(f"option targets must be in 1..{TARGETS}, got {targets!r}")


def _new_stats() -> dict[str, Any]:
    return {"draws": 0, "render_targets": [0, 0]}


def conservative_ldi(ctx, mesh, spec, *, timer, axis: int = 2, lod_c: int = DEFAULT_LOD_C,
                     targets: int = TARGETS, owner: str = "leung-wang-ldi") -> LDI:
    """Leung & Wang's conservative LDI of ``mesh`` on ``spec`` (module docstring).

    Parameters
    ----------
    ctx : GLContext
    mesh : glvox.mesh.Mesh
    spec : GridSpec
        Pixels: the voxel columns along ``axis``; depths over the grid's range.
    timer : StageTimer
        Stages ``transform``, ``setup``, ``t1`` and ``t2`` (per tile and pass),
        ``count``, ``depths`` and ``store`` (per tile and Phase-2 pass),
        ``readback``; ``timer.stats`` gets ``lod_c``, ``axis``, ``n_max``,
        ``samples``, ``phase1_passes``, ``phase2_passes``, ``draws``,
        ``tiles``, ``render_targets`` (per pass, [Phase 1, Phase 2]: only as many as
        the cells or layers need).
    axis : {0, 1, 2}
    lod_c : int
        Cells along the rays (the paper's r_z), 1..MAX_LOD_C.
    targets : int
        Render targets per pass, 1..8: 128 cells each in Phase 1, 4 layers
        each in Phase 2 (fewer means more passes; the tests use it).
    owner : str
        Name of the buffer pool.

    Returns
    -------
    LDI
    """
    _check(spec, axis, lod_c, targets)
    _check_fragment_storage(ctx)
    frame = _Frame(spec, int(axis), int(lod_c), int(targets))
    pool = buffer_pool(ctx, owner)
    mask_bytes = frame.n_rays * frame.words * 4
    what = f"a bit mask of {frame.n_rays} rays x {frame.cells} cells"
    # the big buffers first: over the storage-block limit is refused before any work
    t1 = pool.get("t1", mask_bytes, what=what, clear=False)
    t2 = pool.get("t2", mask_bytes, what=what, clear=False)
    counts = pool.get("counts", frame.n_rays * 4, what="samples per ray", clear=False)
    stats_buf = pool.get("stats", 8)
    stats = _new_stats()
    on_grid = _prepare(ctx, mesh, frame, pool, "a", timer)
    ctx.mgl.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
    _render_mask(ctx, frame, on_grid, "xor", t1, None, timer, "t1", stats)
    _render_mask(ctx, frame, on_grid, "or", t2, t1, timer, "t2", stats)
    n_max, samples = _count(ctx, frame, t1, t2, counts, stats_buf, timer)
    chunks = _phase2(ctx, frame, [on_grid], t1, t2, counts, n_max, pool, timer, stats)
    depths, cnt = _read_result(frame, chunks, counts, n_max, timer)
    stats.update({"lod_c": frame.cells, "axis": frame.axis, "n_max": n_max, "samples": samples})
    timer.stats.update(stats)
    return LDI(depths, cnt, spec, frame.axis, lod_c=frame.cells)


def intersecting_ldi(ctx, mesh_a, mesh_b, spec, *, timer, axis: int = 2, lod_c: int = DEFAULT_LOD_C,
                     targets: int = TARGETS, owner: str = "leung-wang-intersection") -> LDI:
    """The conservative LDI of the overlap of two closed meshes (Leung & Wang 2013 Sec. V-A).

    T1 and T2 of each mesh on the same rays and cells (Phase 1 twice), their
    combination (``combine``: T1 = T1_A AND T1_B, T2 as in
    ``shaders/ldi/intersect.comp``), then the n_max pass and Phase 2 drawing
    the triangles of both meshes.  Parameters as :func:`conservative_ldi`;
    stages get ``_a`` / ``_b`` suffixes for the per-mesh ones.

    Returns
    -------
    LDI
        Its :attr:`~glvox.ldi.LDI.volume` is the intersecting volume (world
        units cubed), an upper bound of the overlap sampled on the rays.
    """
    _check(spec, axis, lod_c, targets)
    _check_fragment_storage(ctx)
    frame = _Frame(spec, int(axis), int(lod_c), int(targets))
    pool = buffer_pool(ctx, owner)
    mask_bytes = frame.n_rays * frame.words * 4
    what = f"a bit mask of {frame.n_rays} rays x {frame.cells} cells"
    names = ("t1", "t2", "t1_a", "t2_a", "t1_b", "t2_b")
    m = {n: pool.get(n, mask_bytes, what=what, clear=False) for n in names}
    counts = pool.get("counts", frame.n_rays * 4, what="samples per ray", clear=False)
    stats_buf = pool.get("stats", 8)
    stats = _new_stats()
    grids = {"a": _prepare(ctx, mesh_a, frame, pool, "a", timer, "_a"),
             "b": _prepare(ctx, mesh_b, frame, pool, "b", timer, "_b")}
    ctx.mgl.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
    for tag, g in grids.items():
        _render_mask(ctx, frame, g, "xor", m[f"t1_{tag}"], None, timer, f"t1_{tag}", stats)
        _render_mask(ctx, frame, g, "or", m[f"t2_{tag}"], m[f"t1_{tag}"], timer, f"t2_{tag}", stats)
    prog = compute_program(ctx, "ldi/intersect.comp")
    n_words = frame.n_rays * frame.words
    set_uniforms(prog, {"u_words": frame.words, "u_cells": frame.cells, "u_invocations": n_words})
    with timer.stage("combine"):
        m["t1"].bind_to_storage_buffer(0)
        m["t2"].bind_to_storage_buffer(1)
        for i, n in enumerate(("t1_a", "t2_a", "t1_b", "t2_b")):
            m[n].bind_to_storage_buffer(8 + i)
        dispatch_1d(ctx, prog, n_words, _LOCAL)
        barrier(ctx)
    n_max, samples = _count(ctx, frame, m["t1"], m["t2"], counts, stats_buf, timer)
    chunks = _phase2(ctx, frame, list(grids.values()), m["t1"], m["t2"], counts, n_max, pool, timer, stats)
    depths, cnt = _read_result(frame, chunks, counts, n_max, timer)
    stats.update({"lod_c": frame.cells, "axis": frame.axis, "n_max": n_max, "samples": samples})
    timer.stats.update(stats)
    return LDI(depths, cnt, spec, frame.axis, lod_c=frame.cells)


def peeled_ldi(ctx, mesh, spec, *, timer, axis: int = 2, tile: int = 0, owner: str = "peel-ldi") -> LDI:
    """The exact LDI by depth peeling, every crossing a layer (module docstring).

    Parameters
    ----------
    ctx : GLContext
    mesh : glvox.mesh.Mesh
    spec : GridSpec
    timer : StageTimer
        Stages ``peel`` (per tile: the peeling passes with their recording)
        and ``finish``, ``readback``; ``timer.stats`` gets ``axis``,
        ``n_max``, ``samples``, ``passes`` (raster passes), ``tiles``.
    axis : {0, 1, 2}
    tile : int
        Largest render-target side; 0: the context's limits.

    Returns
    -------
    LDI
    """
    if axis not in (0, 1, 2):
        raise MethodError(f"option axis must be 0, 1 or 2, got {axis!r}")
    if tile < 0:
        raise MethodError(f"option tile must be 0 (the context's limit) or a positive number of pixels, got {tile}")
    frame = _Frame(spec, int(axis), 1, TARGETS)
    limit = depth_layers.view_limit(ctx)
    side = limit if tile == 0 else min(tile, limit)
    pool = buffer_pool(ctx, owner)
    counts = pool.get("counts", frame.n_rays * 4, what="samples per ray")
    last = pool.get("last", frame.n_rays * 4, what="last depth per ray")
    stats_buf = pool.get("stats", 8)
    bufs = mesh_buffers(ctx, mesh)
    uniforms = grid_uniforms(spec, bufs.anchor)
    raster = render_program(ctx, "depth/raster.vert", "depth/raster.frag", "depth/raster.geom")
    count_prog = compute_program(ctx, "ldi/peel_count.comp")
    record = compute_program(ctx, "ldi/peel_record.comp", {"EIS_AXIS": frame.axis})
    finish = compute_program(ctx, "ldi/peel_finish.comp", {"EIS_AXIS": frame.axis})
    n_u, n_v = frame.n_u, frame.n_v
    size = (min(side, n_u), min(side, n_v))
    bounds = spec.world_to_voxel(mesh.bounds)
    lo, hi = float(bounds[0, axis]) - 2.0, float(bounds[1, axis]) + 2.0
    set_uniforms(raster, {**uniforms, "u_prev": 0, "u_axis": frame.axis, "u_target_size": size,
                          "u_depth_n": frame.n_a, "u_key_lo": lo, "u_key_scale": 1.0 / (hi - lo)})
    set_uniforms(count_prog, {"u_stencil": 0})
    set_uniforms(record, {"u_layer": 0, "u_axis": frame.axis, "u_grid_uv": (n_u, n_v),
                          "u_depth_n": frame.n_a, "u_origin_d": uniforms["u_origin_d"],
                          "u_inv_h_d": uniforms["u_inv_h_d"]})
    vao = ctx.mgl.vertex_array(raster, [(bufs.vertices, "3f", "in_pos")], index_buffer=bufs.faces,
                               index_element_size=4)
    target = depth_layers._target(ctx, size)
    run = depth_layers._Run(ctx, vao, raster, None, None, None, None)
    origins = [(x, y) for y in range(0, n_v, size[1]) for x in range(0, n_u, size[0])]
    groups = ((size[0] + 7) // 8, (size[1] + 7) // 8, 1)

    chunk_bufs: list = []
    chunk_ranges: list[tuple[int, int]] = []
    chunk_layers = 1

    def first_pass(origin) -> int:
        """Layer 0 of a tile with every crossing counted in the stencil; the largest count."""
        set_uniforms(raster, {"u_tile_origin": origin})
        run.draw(target, 0, count="restart")
        stats_buf.clear(size=4)
        target.stencil.use(0)
        stats_buf.bind_to_storage_buffer(7)
        count_prog.run(*groups)
        barrier(ctx)
        return int(np.frombuffer(stats_buf.read(size=4), dtype="<u4")[0])

    def ensure(layer: int) -> int:
        """The chunk holding ``layer`` (allocated on first use)."""
        while not chunk_ranges or layer >= chunk_ranges[-1][0] + chunk_ranges[-1][1]:
            lo_ = chunk_ranges[-1][0] + chunk_ranges[-1][1] if chunk_ranges else 0
            chunk_ranges.append((lo_, chunk_layers))
            chunk_bufs.append(pool.get(f"depths{len(chunk_bufs)}", frame.n_rays * chunk_layers * 4,
                                       what="the LDI depths", clear=False))
        return layer // chunk_layers

    def record_layer(layer_tex: int, origin, index: int) -> None:
        c = ensure(index)
        target.layers[layer_tex].use(0)
        bufs.vertices.bind_to_storage_buffer(0)
        bufs.faces.bind_to_storage_buffer(1)
        chunk_bufs[c].bind_to_storage_buffer(2)
        last.bind_to_storage_buffer(3)
        counts.bind_to_storage_buffer(6)
        set_uniforms(record, {"u_tile_origin": origin, "u_layer_index": index,
                              "u_chunk_lo": chunk_ranges[c][0], "u_chunk_layers": chunk_layers})
        record.run(*groups)
        barrier(ctx)

    layers = 0
    try:
        ctx.mgl.enable_only(moderngl.DEPTH_TEST)
        ctx.mgl.depth_func = "<"
        with timer.stage("peel"):
            # the largest crossing count of every tile first, to size the depth chunks; with
            # one tile that counting pass is its layer 0, with several each tile redraws it
            firsts = [first_pass(o) for o in origins]
            most = max(firsts, default=0)
            cap = depth_layers.STENCIL_MAX
            chunk_layers = _peel_chunk_layers(ctx, frame.n_rays, min(most, cap) + 1, most >= cap)
            for n_o, origin in enumerate(origins):
                n_here = firsts[n_o]
                if n_here == 0:
                    continue
                if len(origins) > 1:
                    first_pass(origin)
                record_layer(0, origin, 0)
                cur, prev, index = 1, 0, 1
                if n_here < cap:
                    for index in range(1, n_here):
                        run.draw(target, cur, prev=prev)
                        record_layer(cur, origin, index)
                        cur, prev = prev, cur
                    index = n_here
                else:
                    # the 8-bit stencil saturated: peel on until a pass draws nothing
                    query = run.query()
                    while True:
                        run.draw(target, cur, prev=prev, query=query)
                        if query.samples == 0:
                            break
                        record_layer(cur, origin, index)
                        cur, prev = prev, cur
                        index += 1
                layers = max(layers, index)
        passes = run.passes
    finally:
        ctx.raw.fn("glDisable")(rawgl.GL_STENCIL_TEST)
        ctx.mgl.enable_only(moderngl.NOTHING)
        ctx.mgl.depth_func = "<="
        vao.release()
    room = layers + 1  # the closing sample of a ray with an odd count
    if layers:
        ensure(room - 1)
    with timer.stage("finish"):
        counts.bind_to_storage_buffer(6)
        for c, (c0, n) in enumerate(chunk_ranges):
            if c0 >= room:
                break
            chunk_bufs[c].bind_to_storage_buffer(2)
            set_uniforms(finish, {"u_grid_uv": (n_u, n_v), "u_chunk_lo": c0, "u_chunk_layers": n,
                                  "u_layers": room, "u_depth_n": frame.n_a, "u_invocations": frame.n_rays * n})
            dispatch_1d(ctx, finish, frame.n_rays * n, _LOCAL)
        barrier(ctx)
    with timer.stage("readback", gpu=False):
        cnt = np.frombuffer(counts.read(size=frame.n_rays * 4), dtype="<u4").reshape(frame.out_shape())
        cnt = cnt.astype(np.int32) + (cnt % 2).astype(np.int32)
        n_max = int(cnt.max()) if cnt.size else 0
        used = [(b, r) for b, r in zip(chunk_bufs, chunk_ranges) if r[0] < room]
        depths = _read_chunks(used, frame.n_rays, n_max, frame.out_shape())
    timer.stats.update({"axis": frame.axis, "n_max": n_max, "samples": int(cnt.sum()), "passes": passes,
                        "tiles": len(origins)})
    return LDI(depths, cnt, spec, frame.axis)


def _peel_chunk_layers(ctx, n_rays: int, wanted: int, open_ended: bool) -> int:
    """Layers per depth chunk of the peeling LDI: all ``wanted`` when they fit one storage
    block (and the count is known), else as many as fit, at most 256 (more chunks follow)."""
    limit = int(ctx.limits()["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"])
    per_layer = n_rays * 4
    if per_layer > limit:
        check_buffer_size(ctx, per_layer, f"one layer of the LDI depths ({n_rays} rays)")
    fit = limit // per_layer
    return max(1, min(fit, 256 if open_ended else wanted))


# ---------------------------------------------------------------------------
# registered methods
# ---------------------------------------------------------------------------

def _warn_open(mesh, name: str) -> None:
    # run_method refuses open meshes for the solid kinds only; an LDI pairs crossings by
    # parity just the same, so say what the result means
    if not mesh.watertight:
        warnings.warn(
            f"{mesh.name} is not watertight: {name!r} pairs the crossings of each ray by parity, which "
            "bounds a solid only where the rays cross a closed part of the surface; a ray left inside "
            "is closed at the grid's far face", NotWatertightWarning, stacklevel=3)


_AXIS = Option(2, "ray direction (0=x, 1=y, 2=z); pixels are the other two axes in increasing order",
               (0, 1, 2))


@register
class LeungWangLDI(Method):
    info = MethodInfo(
        name="leung-wang-ldi", kind="ldi", family="raster",
        paper=f"{_PAPER}, Sec. III (Alg. 1-2, Eq. 1-6): XOR/OR bit masks, fast bit checking, MAX blending",
        summary="conservative LDI: T1 (XOR) and T2 (OR) masks on LOD-C cells, n_max pass, 32 sorted "
                "layers per pass by bitCount and MAX blending; encloses every exact interior segment",
        reference="reference-solid", exact=False, requires=_REQUIRES,
        options={
            "lod_c": Option(DEFAULT_LOD_C, f"cells along the rays (the paper's LOD-C, r_z), 1..{MAX_LOD_C}; "
                                           "1024 per Phase-1 pass"),
            "axis": _AXIS,
            "targets": Option(TARGETS, "render targets per pass (8 as in the paper: 1024 cells, 32 layers); "
                                       "fewer means more passes", tuple(range(1, TARGETS + 1))),
        },
    )

    def run(self, mesh, spec, *, ctx, timer, lod_c, axis, targets):
        _warn_open(mesh, self.info.name)
        return conservative_ldi(ctx, mesh, spec, timer=timer, axis=axis, lod_c=lod_c, targets=targets,
                                owner=self.info.name)

    def release(self, ctx) -> None:
        super().release(ctx)
        buffer_pool(ctx, "leung-wang-intersection").release()
        release_object_cache(ctx, "leung-wang")


@register
class PeelLDI(Method):
    info = MethodInfo(
        name="peel-ldi", kind="ldi", family="raster",
        paper="Everitt 2001 depth peeling as in Passalis et al. 2006, Sec. 3.3 (the baseline of "
              f"{_PAPER}, Sec. II and Table II)",
        summary="exact LDI by depth peeling: one raster pass per layer, every crossing in depth order",
        reference="reference-solid", exact=True,
        requires=Requirements(gl_version=450, limits={"GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 8}),
        options={
            "axis": _AXIS,
            "tile": Option(0, "largest render-target side in pixels (0: the context's limits)"),
        },
    )

    def run(self, mesh, spec, *, ctx, timer, axis, tile):
        _warn_open(mesh, self.info.name)
        return peeled_ldi(ctx, mesh, spec, timer=timer, axis=axis, tile=tile, owner=self.info.name)


@register
class ReferenceLDI(Method):
    info = MethodInfo(
        name="reference-ldi", kind="ldi", family="cpu",
        paper="exact ray/mesh crossings (float64) with the fill rule of reference-solid "
              "(Schwarz & Seidel 2010, Sec. 4.1)",
        summary="exact LDI on the CPU: every crossing of every pixel ray, sorted, rounded to float32",
        reference="reference-solid", exact=True,
        options={"axis": _AXIS},
    )

    def run(self, mesh, spec, *, ctx, timer, axis):
        _warn_open(mesh, self.info.name)
        with timer.stage("setup", gpu=False):
            tris = mesh.triangles_voxel(spec)
        with timer.stage("crossings", gpu=False):
            rc = crossings(tris, spec.dims, axis)
            depths, counts = close_odd(rc.depths, rc.counts, spec.dims[axis])
        timer.stats.update({"axis": axis, "n_max": int(depths.shape[2]), "samples": int(counts.sum())})
        return LDI(depths.astype(np.float32), counts, spec, axis)


# ---------------------------------------------------------------------------
# the intersecting-volume application (Sec. V-A), run like a method
# ---------------------------------------------------------------------------

#: The application's entry for the run envelope (two meshes, so not in the registry).
INTERSECTION = MethodInfo(
    name="leung-wang-intersection", kind="ldi", family="raster",
    paper=f"{_PAPER}, Sec. V-A (intersecting volume of two closed meshes)",
    summary="conservative LDI of the overlap of two closed meshes; its volume is the intersecting volume",
    exact=False, requires=_REQUIRES,
)


def overlap_bounds(mesh_a, mesh_b) -> np.ndarray | None:
    """(2, 3) float64 intersection of the two bounding boxes, or None when it has no volume
    (the solids cannot overlap in volume)."""
    lo = np.maximum(mesh_a.bounds[0], mesh_b.bounds[0])
    hi = np.minimum(mesh_a.bounds[1], mesh_b.bounds[1])
    if np.any(hi <= lo):
        return None
    return np.stack([lo, hi])


def overlap_grid(mesh_a, mesh_b, resolution: int | None = None, *, dims=None, voxel_size: float | None = None,
                 padding: int = 0) -> GridSpec:
    """The grid of the intersection application: fitted to :func:`overlap_bounds`, where the
    overlap lies, or to the union of the two boxes when those do not overlap in volume (the
    LDI is then empty)."""
    if resolution is None and dims is None and voxel_size is None:
        raise GridError("give a resolution (or dims, voxel_size or grid)")
    region = overlap_bounds(mesh_a, mesh_b)
    if region is None:
        region = np.stack([np.minimum(mesh_a.bounds[0], mesh_b.bounds[0]),
                           np.maximum(mesh_a.bounds[1], mesh_b.bounds[1])])
    return fit_grid(region, resolution, dims=dims, voxel_size=voxel_size, padding=padding)


def run_intersection(mesh_a, mesh_b, spec, *, ctx=None, backend: str | None = None, allow_open: bool = False,
                     debug: bool | None = None, lod_c: int = DEFAULT_LOD_C, axis: int = 2,
                     targets: int = TARGETS) -> LDI:
    """:func:`intersecting_ldi` with what :func:`glvox.methods.run_method` does around a method:
    the watertight check, the context and its capabilities, stage timings and ``result.run``.

    Parameters
    ----------
    mesh_a, mesh_b : glvox.mesh.Mesh
    spec : GridSpec
        One grid for both (e.g. fitted to :func:`overlap_bounds`).
    ctx, backend, allow_open, debug
        As :func:`glvox.methods.run_method`.
    lod_c, axis, targets
        As ``leung-wang-ldi``.

    Returns
    -------
    LDI
        The overlap; ``.volume`` is the intersecting volume in world units cubed.
    """
    opts = {"lod_c": int(lod_c), "axis": int(axis), "targets": int(targets)}

    def work(ctx, timer):
        result = intersecting_ldi(ctx, mesh_a, mesh_b, spec, timer=timer, owner=INTERSECTION.name, **opts)
        timer.stats.update({"triangles": [mesh_a.n_triangles, mesh_b.n_triangles], "volume": result.volume})
        return result

    return run_in_envelope(INTERSECTION, (mesh_a, mesh_b), spec, work, options=opts, ctx=ctx,
                           backend=backend, allow_open=allow_open, debug=debug)
