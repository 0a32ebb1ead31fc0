"""The GPU passes of Leung & Wang's conservative LDI (:mod:`glvox.methods.ldi.leung_wang`).

* render targets: ``n`` RGBA targets of one format (``u4`` masks in Phase 1,
  ``f4`` depths in Phase 2) and their framebuffer, kept per context;
* the frame (:class:`Frame`): the rays, the LOD-C cells along them, the
  words of a ray's masks, the passes and targets of each phase, the tiles;
* :func:`prepare`: the mesh in the frame's voxel space with Eisemann &
  Decoret's per-triangle setup (``shaders/eisemann/setup.comp``);
* :func:`render_mask`: Phase 1, T1 (XOR) or T2 (OR) tile by tile and pass by
  pass, each pass stored into a mask buffer holding each ray's words;
* :func:`count_samples`: the n_max pass;
* :func:`phase2`: the MAX-blended depth passes, each decoded into the depth
  buffers (:func:`depth_chunks`), and :func:`read_result`.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from typing import Any

import moderngl
import numpy as np

from ...errors import CapabilityError, MethodError
from ...gl import raw as rawgl
from ...gl.shaders import compute_program, render_program
from ...gpu.buffers import check_buffer_size, mesh_buffers, object_cache, release_object_cache
from ...gpu.dispatch import barrier, bind, dispatch_1d, rendered, set_uniforms
from ...gpu.fixed_point import fixed_bits
from ...gpu.transform import transform_vertices
from ..eisemann import passes as eisemann_passes
from .common import Rays, read_chunks

#: Render targets per pass (the paper's 8 MRTs): 1024 cells per Phase-1 pass, 32 layers per Phase-2 pass.
TARGETS = eisemann_passes.TARGETS
CELLS_PER_TARGET = eisemann_passes.SLICES_PER_TARGET  # 128: four 32-bit channels
LAYERS_PER_TARGET = 4                          # four float channels

_LOCAL = 64
#: Storage blocks the fragment shaders read: the mesh (voxel-space vertices,
#: faces), T1 and T2.
_FRAGMENT_BLOCKS = 4
_NO_SLICE_CULL = 1 << 30
#: Owner of the render targets in :func:`glvox.gpu.buffers.object_cache`.
_CACHE = "leung-wang"

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
    return object_cache(ctx, _CACHE, lambda cache: _release_cache(ctx, cache))


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


def release_targets(ctx) -> None:
    """Free the render targets kept in ``ctx``."""
    release_object_cache(ctx, _CACHE)


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


def tile_limit(ctx, tile: int = 0) -> int:
    """Largest tile side in pixels for option ``tile``: Eisemann & Decoret's for the
    context (GL limits, memory; :func:`glvox.methods.eisemann.passes.tile_limit`), or ``tile``
    when smaller.  Any side of 1 pixel or more works: the store passes here copy whole
    rays, so tiles need not start at whole words of a packed grid.

    Raises
    ------
    MethodError
        ``tile`` is negative.
    """
    if tile < 0:
        raise MethodError(f"option tile must be 0 (the context's limit) or a positive number of pixels, "
                          f"got {tile}")
    side = eisemann_passes.tile_limit(ctx)
    return side if tile == 0 else min(side, int(tile))


def check_fragment_storage(ctx) -> None:
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
class Frame(Rays):
    """Rays, cells and tiles of one LDI run."""

    cells: int      # LOD-C
    targets: int    # the most render targets per pass
    side: int       # the largest tile side in pixels (:func:`tile_limit`)

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

    def tiles(self) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
        """(start, size) of the tiles along u and along v."""
        return eisemann_passes.tile_spans(self.n_u, self.side), eisemann_passes.tile_spans(self.n_v, self.side)


@dataclass(eq=False)
class OnGrid:
    """A mesh on the GPU in the frame's voxel space, with its per-triangle setup."""

    bufs: Any
    vox: Any
    setup: Any
    fix_bits: int        # F of :func:`glvox.gpu.fixed_point.fixed_bits`
    motion: float = 0.0  # voxels, per coordinate: :func:`mesh_motion` and the fixed-point rounding
    snap_motion: Any = None  # float32 per vertex: the snap's move (common/transform.comp)

    def bind(self, prog, motion: bool = False) -> None:
        """Bind the mesh's buffers to ``prog``'s blocks ``EisVox``, ``EisFaces``, ``EisSetups``
        and set its fixed-point scale; ``motion``: the snap's per-vertex motion to ``Motion``
        too (Phase 2's depths widen by it)."""
        bind(prog, EisVox=self.vox, EisFaces=self.bufs.faces, EisSetups=self.setup)
        set_uniforms(prog, {"u_eis_fix_bits": self.fix_bits})
        if motion and self.snap_motion is not None:
            bind(prog, Motion=self.snap_motion)


def mesh_motion(mesh, spec) -> float:
    """How far the float32 upload can move the mesh the GPU sees, per coordinate, in voxels.

    The upload relative to the anchor rounds a coordinate by at most 2^-24 of its distance
    from the anchor (half an ulp, doubled for safety).  The plane snap
    (:func:`glvox.grid.snap_to_planes`) then moves a vertex by up to ``SNAP_EPS`` more;
    ``common/transform.comp`` measures that per vertex.  Phase 2 widens every sample by
    what the sum can do to its crossing (``ldi/depths.frag``), so the LDI encloses the true
    mesh's intervals, not only those of the snapped one.  An upper bound for tests:
    this plus ``SNAP_EPS``.
    """
    reach = float(np.abs(mesh.vertices - mesh.anchor).max()) if len(mesh.vertices) else 0.0
    return 2.0 ** -24 * reach / float(spec.voxel_size)


def prepare(ctx, mesh, frame: Frame, pool, tag: str, timer, suffix: str = "") -> OnGrid:
    """Stages ``transform`` and ``setup``: vertices to the frame's voxel space (double),
    then Eisemann & Decoret's per-triangle setup (column box, drawn corners)."""
    spec, a = frame.spec, frame.axis
    # across the rays the grid's voxels; along them LOD-C cells, shifted by half a cell
    stretch = [1.0] * 3
    stretch[a] = frame.cells / frame.n_a
    shift = [0.0] * 3
    shift[a] = 0.5
    # the fixed point of the coverage test: (u, v) rounded by up to half a unit, in the motion below
    fix_bits = fixed_bits(mesh, spec, a)
    snap_motion = pool.get(f"snap_motion_{tag}", max(mesh_buffers(ctx, mesh).n_vertices, 1) * 4,
                           what="the snap's move per vertex", clear=False)
    bufs, vox = transform_vertices(ctx, mesh, spec, timer, pool, double=True, stretch=stretch, shift=shift,
                                   name=f"vox_{tag}", stage=f"transform{suffix}", motion=snap_motion,
                                   fixed=(a, fix_bits))
    setup = pool.get(f"setup_{tag}", bufs.n_triangles * 48, what="per-triangle setup", clear=False)
    prog = compute_program(ctx, "eisemann/setup.comp", {"EIS_AXIS": a, "EIS_OP": 0, "EIS_COVERAGE": 0})
    dims = list(spec.dims)
    dims[a] = frame.cells
    set_uniforms(prog, {"u_triangles": bufs.n_triangles, "u_dims": tuple(dims)})
    on_grid = OnGrid(bufs, vox, setup, fix_bits, mesh_motion(mesh, spec) + 2.0 ** -(fix_bits + 1), snap_motion)
    with timer.stage(f"setup{suffix}"):
        on_grid.bind(prog)
        dispatch_1d(ctx, prog, bufs.n_triangles, _LOCAL)
        barrier(ctx)
    return on_grid


def _draw_defines(frame: Frame, n_targets: int, **extra) -> dict[str, Any]:
    return {"EIS_AXIS": frame.axis, "EIS_TARGETS": n_targets, "EIS_MASKS": 0, "EIS_COVERAGE": 0,
            "EIS_OP": 0, **extra}


def _store_defines(frame: Frame, dtype: str, n_targets: int) -> dict[str, Any]:
    fmt = {"u4": ("rgba32ui", "uimage2D", "uvec4"), "f4": ("rgba32f", "image2D", "vec4")}[dtype]
    return {"EIS_AXIS": frame.axis, "LDI_TARGETS": n_targets, "LDI_LAYERS": LAYERS_PER_TARGET * n_targets,
            "LDI_TARGET_FORMAT": fmt[0], "LDI_TARGET_TYPE": fmt[1], "LDI_TEXEL_TYPE": fmt[2]}


# ---------------------------------------------------------------------------
# Phase 1: T1 (XOR) and T2 (OR)
# ---------------------------------------------------------------------------


def render_mask(ctx, frame: Frame, mesh: OnGrid, op: str, out, t1, timer, stage: str, stats) -> None:
    """One mask (``op`` 'xor': T1; 'or': T2, reading ``t1``) into ``out``, tile by tile and pass by pass."""
    fragment = "ldi/t1.frag" if op == "xor" else "ldi/t2.frag"
    passes, n_targets = frame.phase1()
    cells_per_pass = CELLS_PER_TARGET * n_targets
    prog = render_program(ctx, "eisemann/slices.vert", fragment, defines=_draw_defines(frame, n_targets))
    store = compute_program(ctx, "ldi/masks_store.comp", _store_defines(frame, "u4", n_targets))
    set_uniforms(prog, frame.column_uniforms())
    set_uniforms(store, frame.column_uniforms())
    tiles_u, tiles_v = frame.tiles()
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
                        mesh.bind(prog)
                        if t1 is not None:
                            bind(prog, LdiT1=t1)
                        with ctx.logic_op(op):
                            vao.render(moderngl.TRIANGLES, vertices=3 * n_tri)
                        rendered(ctx)
                    with timer.stage(f"{stage}_store"):
                        for t, tex in enumerate(tg.textures):
                            tex.bind_to_image(t, read=True, write=False)
                        bind(store, Masks=out)
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


def count_samples(ctx, frame: Frame, t1, t2, counts, stats_buf, timer) -> tuple[int, int]:
    """Stage ``count`` (the n_max pass): samples per ray into ``counts``; returns (n_max, samples)."""
    prog = compute_program(ctx, "ldi/count.comp", {"EIS_AXIS": frame.axis})
    set_uniforms(prog, frame.column_uniforms())
    with timer.stage("count"):
        bind(prog, LdiT1=t1, LdiT2=t2, Counts=counts, Stats=stats_buf)
        dispatch_1d(ctx, prog, frame.n_rays, _LOCAL)
        barrier(ctx)
        n_max, samples = (int(x) for x in np.frombuffer(stats_buf.read(size=8), dtype="<u4"))
    return n_max, samples


def depth_chunks(ctx, n_rays: int, n_layers: int, step: int, what: str) -> list[tuple[int, int]]:
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


def phase2(ctx, frame: Frame, meshes: list[OnGrid], t1, t2, counts, n_max: int, pool, timer,
            stats) -> list:
    """Alg. 2: ceil(n_max / layers per pass) MAX-blended passes, each decoded into the depth
    buffers; returns [(buffer, (first layer, layers))] for :func:`~glvox.methods.ldi.common.read_chunks`."""
    passes, n_targets = frame.phase2(n_max)
    layers_per_pass = LAYERS_PER_TARGET * n_targets
    chunks = depth_chunks(ctx, frame.n_rays, n_max, layers_per_pass, "the LDI depths")
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
    tiles_u, tiles_v = frame.tiles()
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
                        bind(prog, LdiT1=t1, LdiT2=t2)
                        for m in meshes:
                            m.bind(prog, motion=True)
                            set_uniforms(prog, {"u_motion": m.motion, "u_cells_per_voxel": frame.cells / frame.n_a})
                            vao.render(moderngl.TRIANGLES, vertices=3 * m.bufs.n_triangles)
                            stats["draws"] += 1
                        rendered(ctx)
                    with timer.stage("store"):
                        for t, tex in enumerate(tg.textures):
                            tex.bind_to_image(t, read=True, write=False)
                        bind(store, LdiT1=t1, LdiT2=t2, Counts=counts, Depths=bufs[chunk])
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


def read_result(frame: Frame, chunks: list, counts, n_max: int, timer) -> tuple[np.ndarray, np.ndarray]:
    """Stage ``readback``: the depths (n_p, n_q, n_max) float32 and counts (n_p, n_q) int32."""
    with timer.stage("readback", gpu=False):
        depths = read_chunks(chunks, frame.n_rays, n_max, frame.out_shape())
        # samples widened by the mesh's motion (ldi/depths.frag) can pass those of a
        # neighbouring cell; the running maximum keeps them sorted and the union of the
        # intervals unchanged (an entering sample raised to the leaving one before it)
        valid = ~np.isnan(depths)
        depths = np.where(valid, np.fmax.accumulate(depths, axis=2), np.float32(np.nan)).astype(np.float32)
        cnt = np.frombuffer(counts.read(size=frame.n_rays * 4), dtype="<u4").reshape(frame.out_shape())
    return depths, cnt.astype(np.int32)


