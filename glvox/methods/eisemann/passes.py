"""The slice-mask render of Eisemann & Decoret (:mod:`glvox.methods.eisemann.slicing`), reusable.

:func:`render_slice_masks` draws a mesh orthographically along an axis into
up to :data:`TARGETS` RGBA32UI render targets with a logic op (XOR: solid, OR:
surface), tile by tile and pass by pass of 1024 slices, and packs each pass
into glvox's bit grid on the GPU; its settings are a :class:`SliceRender`.
The render targets and mask textures are kept per context
(:func:`glvox.gpu.buffers.object_cache`).  Leung & Wang's T1 and T2 masks
(:mod:`glvox.methods.ldi.leung_wang_passes`) reuse its shaders (the setup, the
exact-coverage vertex stage, the column tests and mask writers), its target
layout and :func:`tile_limit`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import moderngl
import numpy as np

from ...errors import CapabilityError, LimitError, MethodError
from ...gl.shaders import compute_program, render_program
from ...gpu.buffers import buffer_pool, object_cache, release_object_cache
from ...gpu.dispatch import LOOP_BUDGET, barrier, bind, dispatch_1d, grid_uniforms, rendered, set_uniforms
from ...gpu.fixed_point import fixed_bits
from ...gpu.transform import transform_vertices

#: Render targets per pass (RGBA32UI, 128 slices each): 8 x 128 = 1024 slices.
TARGETS = 8
SLICES_PER_TARGET = 128

#: Largest tile side in pixels whatever GL allows: the targets take 16 bytes
#: per pixel each, 128 bytes with 8 targets, so a 2048^2 tile is 512 MiB.
MAX_TILE = 2048

#: Mask generation in the fragment shader: "bits" (shifts and selects) or
#: "texture" (a precomputed mask table, one texel fetch per target, as the
#: paper looks masks up in a texture).  The default is the bits: the table
#: was no faster for XOR and not consistently faster for OR (measured with
#: compare/bench_eisemann_masks.py; figures in compare/README.md), and the
#: bits need no texture unit.
MASKS = ("bits", "texture")
DEFAULT_MASKS = "bits"
COVERAGES = ("exact", "raster")
OPS = {"xor": 0, "or": 1}

# the pack pass: a fixed 32-iteration load, 80 swap steps and 4 x 32 stores
assert 32 + 80 + 4 * 32 < LOOP_BUDGET

_LOCAL = 64  # local_size_x of eisemann/pack.comp
_MASK_UNIT = 8  # texture unit of the mask table: the targets take image units 0..7 in the pack pass
#: Owner of the render targets and mask textures in :func:`glvox.gpu.buffers.object_cache`.
_CACHE = "eisemann"


def tile_limit(ctx, tile: int = 0) -> int:
    """Largest tile side (pixels) for ``ctx`` and option ``tile``: a multiple of 32.

    The minimum of GL_MAX_TEXTURE_SIZE, GL_MAX_RENDERBUFFER_SIZE, both
    GL_MAX_VIEWPORT_DIMS, :data:`MAX_TILE` and ``tile`` (unless 0), rounded
    down to a multiple of 32 so that tiles start at whole words of the packed
    grid (``tile=40`` draws 32-pixel tiles).

    Raises
    ------
    MethodError
        ``tile`` is negative.
    LimitError
        When that minimum is below 32.
    """
    if tile < 0:
        raise MethodError(f"option tile must be 0 (the context's limit) or a positive number of pixels, "
                          f"got {tile}")
    lim = ctx.limits()
    vp = lim.get("GL_MAX_VIEWPORT_DIMS") or (0, 0)
    names = {"GL_MAX_TEXTURE_SIZE": lim.get("GL_MAX_TEXTURE_SIZE", 0),
             "GL_MAX_RENDERBUFFER_SIZE": lim.get("GL_MAX_RENDERBUFFER_SIZE", 0),
             "GL_MAX_VIEWPORT_DIMS": min(vp), "glvox.methods.eisemann.passes.MAX_TILE": MAX_TILE}
    if tile:
        names["option tile"] = int(tile)
    which = min(names, key=lambda k: names[k])
    side = int(names[which])
    if side < 32:
        advice = ("give 0 (the context's limits) or at least 32" if which == "option tile"
                  else "use a compute method (ss-conservative, scanline-*) instead")
        raise LimitError(f"the Eisemann-Decoret render needs tiles of at least 32 x 32 pixels, but {which} is "
                         f"{side} ({ctx.renderer}); {advice}")
    return side - side % 32


def tile_spans(n: int, side: int) -> list[tuple[int, int]]:
    """(start, size) of the tiles covering ``n`` columns, ``side`` at a time."""
    return [(s, min(side, n - s)) for s in range(0, n, side)]


@dataclass(eq=False)
class _Targets:
    """The render targets of one context (up to :data:`TARGETS`, grown on
    demand) and a framebuffer per number of them attached."""

    textures: list
    fbos: dict
    size: tuple[int, int]

    def release(self, ctx) -> None:
        for fbo in self.fbos.values():
            ctx.release_framebuffer(fbo)
        for t in self.textures:
            t.release()


def _cache(ctx) -> dict:
    return object_cache(ctx, _CACHE, lambda cache: _release_cache(ctx, cache))


def release_targets(ctx) -> None:
    """Free the render targets and mask textures kept in ``ctx``."""
    release_object_cache(ctx, _CACHE)


def _release_cache(ctx, cache: dict) -> None:
    for obj in cache.values():
        if isinstance(obj, _Targets):
            obj.release(ctx)
        else:
            obj.release()
    cache.clear()


def _targets(ctx, n: int, size: tuple[int, int]) -> _Targets:
    """At least ``n`` RGBA32UI targets of at least ``size`` pixels."""
    cache = _cache(ctx)
    tg = cache.get("targets")
    if tg is not None and len(tg.textures) >= n and tg.size[0] >= size[0] and tg.size[1] >= size[1]:
        return tg
    if tg is not None:
        size = (max(size[0], tg.size[0]), max(size[1], tg.size[1]))
        n = max(n, len(tg.textures))
        tg.release(ctx)
    textures = []
    for _ in range(n):
        t = ctx.mgl.texture(size, 4, dtype="u4")
        t.filter = (moderngl.NEAREST, moderngl.NEAREST)  # integer textures are incomplete otherwise
        textures.append(t)
    tg = _Targets(textures, {}, size)
    cache["targets"] = tg
    return tg


def last_pass_targets(ctx) -> list:
    """The render targets as the last pass left them (RGBA32UI textures of the last tile;
    pixel (u, v) holds 128 slices a target, 32 a word): the masks before the pack, for
    :func:`glvox.testing.tie_probe.trace`.  Empty before any render in ``ctx``."""
    tg = _cache(ctx).get("targets")
    return [] if tg is None else list(tg.textures)


def _framebuffer(ctx, tg: _Targets, n: int):
    """The framebuffer of the first ``n`` targets."""
    fbo = tg.fbos.get(n)
    if fbo is None:
        fbo = tg.fbos[n] = ctx.mgl.framebuffer(color_attachments=tg.textures[:n])
    return fbo


def mask_table(op: str, targets: int = TARGETS) -> np.ndarray:
    """The precomputed masks of ``masks="texture"``.

    Returns
    -------
    (slices + 1, targets, 4) uint32
        Row ``r``: for ``op='xor'`` ones at every slice ``>= r`` of the pass,
        for ``op='or'`` the single slice ``r`` (row ``slices`` is empty);
        slice ``s`` is bit ``s % 32`` of channel ``(s // 32) % 4`` of target
        ``s // 128``.
    """
    slices = SLICES_PER_TARGET * targets
    r = np.arange(slices + 1)[:, None]
    s = np.arange(slices)[None, :]
    bits = (s >= r) if op == "xor" else (s == r)
    packed = np.packbits(bits, axis=1, bitorder="little").view("<u4")
    return np.ascontiguousarray(packed.reshape(slices + 1, targets, 4))


def _mask_texture(ctx, op: str, targets: int):
    cache = _cache(ctx)
    key = ("masks", op, targets)
    tex = cache.get(key)
    if tex is None:
        table = mask_table(op, targets)
        tex = ctx.mgl.texture((targets, table.shape[0]), 4, table.tobytes(), dtype="u4")
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        cache[key] = tex
    return tex


def _check_stage_storage(ctx) -> None:
    """The vertex stage reads the per-triangle setup, the fragment stage the
    voxel-space vertices and the faces, from shader storage blocks (GL only
    guarantees them in fragment shaders)."""
    info = ctx.mgl.info
    for stage, need, what in (("VERTEX", 1, "the triangle setup"),
                              ("FRAGMENT", 2, "the vertices and faces")):
        name = f"GL_MAX_{stage}_SHADER_STORAGE_BLOCKS"
        have = int(info.get(name, 0))
        if have < need:
            raise CapabilityError(
                f"the Eisemann-Decoret render reads {what} from {need} shader storage block(s) in its "
                f"{stage.lower()} shader, but {name} is {have} ({ctx.renderer})"
            )


@dataclass(frozen=True)
class SliceRender:
    """The settings of one slice-mask render (:func:`render_slice_masks`), checked when made.

    Attributes
    ----------
    op : {'xor', 'or'}
        ``'xor'``: each fragment flips every slice whose voxel center lies
        beyond its crossing (solid); ``'or'``: it sets the slice holding its
        crossing (surface).
    axis : {0, 1, 2}
        Render (ray) axis; the pixel grid is ``((axis+1) % 3, (axis+2) % 3)``.
    masks : {'bits', 'texture'}
        Mask generation in the fragment shader.
    coverage : {'exact', 'raster'}
        Who decides which column centers a triangle covers (module docstring).
    targets : int
        Render targets per pass at most, 1..8 (128 slices each); fewer means
        more passes (the tests use it to exercise passes on small grids).
    tile : int
        The ``tile`` option: 0 (the context's limits) or the largest tile
        side in pixels, rounded down to a multiple of 32 (:func:`tile_limit`).
    trace : moderngl.Buffer, optional
        A buffer that receives every fragment of the first pass (``EisTrace`` of
        ``eisemann/slices.frag``: a count, then 4 words per fragment), for
        :func:`glvox.testing.tie_probe.trace`; None (the methods) compiles no trace.

    Raises
    ------
    ValueError
        A setting out of its range (``tile`` is checked against the context
        by :func:`tile_limit`).
    """

    op: str
    axis: int = 2
    masks: str = DEFAULT_MASKS
    coverage: str = "exact"
    targets: int = TARGETS
    tile: int = 0
    trace: Any = None

    def __post_init__(self) -> None:
        if self.op not in OPS:
            raise ValueError(f"op must be one of {sorted(OPS)}, got {self.op!r}")
        if self.axis not in (0, 1, 2):
            raise ValueError(f"axis must be 0, 1 or 2, got {self.axis!r}")
        if self.masks not in MASKS:
            raise ValueError(f"masks must be one of {list(MASKS)}, got {self.masks!r}")
        if self.coverage not in COVERAGES:
            raise ValueError(f"coverage must be one of {list(COVERAGES)}, got {self.coverage!r}")
        if not 1 <= int(self.targets) <= TARGETS:
            raise ValueError(f"targets must be in 1..{TARGETS}, got {self.targets!r}")

    @property
    def kind_defines(self) -> dict[str, int]:
        """The defines of the op and the coverage, shared by the setup and the draw."""
        return {"EIS_OP": OPS[self.op], "EIS_COVERAGE": COVERAGES.index(self.coverage),
                "EIS_TRACE": int(self.trace is not None)}

    def targets_per_pass(self, n_a: int) -> list[int]:
        """Targets of each pass over ``n_a`` slices: only what its slices need (a 128^3
        grid: one), so shallow grids write and pack 16 bytes per fragment and pixel, not 128."""
        slices = SLICES_PER_TARGET * self.targets
        return [min(self.targets, -(-(min(n_a, lo + slices) - lo) // SLICES_PER_TARGET))
                for lo in range(0, n_a, slices)]


@dataclass(eq=False)
class _OnGrid:
    """The mesh in voxel space (double) with its per-triangle setup."""

    vox: Any
    faces: Any
    setup: Any
    n_triangles: int
    anchor: Any     # (3,) float64, the uploaded vertices' origin
    fix_bits: int   # F of :func:`fixed_bits`

    def bind(self, prog) -> None:
        """Bind the mesh's buffers to ``prog``'s blocks ``EisVox``, ``EisFaces``, ``EisSetups``,
        and set its fixed-point scale."""
        bind(prog, EisVox=self.vox, EisFaces=self.faces, EisSetups=self.setup)
        set_uniforms(prog, {"u_eis_fix_bits": self.fix_bits})


@dataclass(eq=False)
class _PassPrograms:
    """What a pass over ``used`` targets draws and packs with."""

    draw: Any       # eisemann/slices.* program
    vao: Any
    clear_vao: Any
    pack: Any
    table: Any      # the mask texture ('texture' masks), else None
    fbo: Any

    def release(self) -> None:
        self.vao.release()
        self.clear_vao.release()


def _prepare(ctx, mesh, spec, render: SliceRender, pool, timer, fix_bits: int) -> _OnGrid:
    """Stages ``transform`` and ``setup``: vertices to voxel space (double), then per
    triangle the column box, the slices it can reach and the corners to draw."""
    bufs, vox = transform_vertices(ctx, mesh, spec, timer, pool, double=True, fixed=(render.axis, fix_bits))
    n_tri = bufs.n_triangles
    per_tri = pool.get("setup", n_tri * 48, what="per-triangle setup", clear=False)
    prog = compute_program(ctx, "eisemann/setup.comp", {"EIS_AXIS": render.axis, **render.kind_defines})
    set_uniforms(prog, {"u_triangles": n_tri, "u_dims": tuple(spec.dims)})
    on_grid = _OnGrid(vox, bufs.faces, per_tri, n_tri, bufs.anchor, fix_bits)
    with timer.stage("setup"):
        on_grid.bind(prog)
        dispatch_1d(ctx, prog, n_tri, _LOCAL)
        barrier(ctx)
    return on_grid


def _pass_programs(ctx, render: SliceRender, spec, anchor, tg: _Targets, used: int) -> _PassPrograms:
    base = {"EIS_AXIS": render.axis, "EIS_TARGETS": used}
    draw = render_program(ctx, "eisemann/slices.vert", "eisemann/slices.frag",
                          defines={**base, **render.kind_defines, "EIS_MASKS": MASKS.index(render.masks)})
    set_uniforms(draw, {"u_axis_n": spec.dims[render.axis]})
    if render.masks == "texture":
        set_uniforms(draw, {"u_mask_table": _MASK_UNIT})
    clear = render_program(ctx, "eisemann/clear.vert", "eisemann/clear.frag", defines=base)
    pack = compute_program(ctx, "eisemann/pack.comp", base)
    set_uniforms(pack, grid_uniforms(spec, anchor))
    return _PassPrograms(draw, ctx.mgl.vertex_array(draw, []), ctx.mgl.vertex_array(clear, []), pack,
                         _mask_texture(ctx, render.op, used) if render.masks == "texture" else None,
                         _framebuffer(ctx, tg, used))


def _draw_pass(ctx, render: SliceRender, pp: _PassPrograms, on_grid: _OnGrid, tile: dict) -> None:
    """Zero the pass's targets (a full-screen draw), then draw the mesh with the logic op."""
    tw, th = tile["u_tile_size"]
    pp.fbo.viewport = (0, 0, tw, th)
    pp.fbo.use()
    pp.clear_vao.render(moderngl.TRIANGLES, vertices=3)
    set_uniforms(pp.draw, tile)
    on_grid.bind(pp.draw)
    if render.trace is not None:
        bind(pp.draw, EisTrace=render.trace)
    if pp.table is not None:
        pp.table.use(_MASK_UNIT)
    with ctx.logic_op(render.op):
        pp.vao.render(moderngl.TRIANGLES, vertices=3 * on_grid.n_triangles)
    rendered(ctx)


def _pack_pass(ctx, render: SliceRender, pp: _PassPrograms, tg: _Targets, used: int, grid, count,
               tile: dict) -> None:
    """The pass's targets into the packed grid: a copy along x, 32x32 bit transposes along y and z;
    the set bits stored are added to ``count``."""
    tw, th = tile["u_tile_size"]
    for t in range(used):
        tg.textures[t].bind_to_image(t, read=True, write=False)
    bind(pp.pack, Grid=grid, Count=count)
    if render.axis == 0:  # one invocation per pixel, its targets in turn
        count = tw * th
        words_x = 0
    else:
        x_n, other_n = (tw, th) if render.axis == 2 else (th, tw)
        words_x = -(-x_n // 32)
        count = words_x * other_n * used
    set_uniforms(pp.pack, {**tile, "u_words_x": words_x, "u_invocations": count})
    dispatch_1d(ctx, pp.pack, count, _LOCAL)
    barrier(ctx)


def render_slice_masks(ctx, mesh, spec, render: SliceRender, *, timer, owner: str = "eisemann"):
    """Render ``mesh`` along ``render.axis`` with logic op ``render.op`` into per-column
    slice masks, and pack them into glvox's bit grid on the GPU.

    Parameters
    ----------
    ctx : GLContext
    mesh : glvox.mesh.Mesh
    spec : GridSpec
    render : SliceRender
        The op, axis, mask generation, coverage, targets per pass and tile.
    timer : StageTimer
        Receives the stages ``transform``, ``setup``, then ``render`` and
        ``pack`` once per tile and pass; ``timer.stats`` gets ``tiles`` ([along u, along v]),
        ``passes`` (per tile), ``draws``, ``slices_per_pass``, ``tile_limit``.
    owner : str
        Name of the buffer pool (see :func:`glvox.gpu.buffers.buffer_pool`).

    Returns
    -------
    grid : moderngl.Buffer
        The pool's ``grid`` buffer holding ``spec.n_words`` uint32 words in
        the layout of ``common/voxel_space.glsl`` (zero bits past the grid);
        valid until the next call with the same ``owner``.
    count : moderngl.Buffer
        The pool's ``count`` buffer: one uint32, the set bits of ``grid``
        (counted by the pack passes as they store each word once).
    """
    _check_stage_storage(ctx)
    side = tile_limit(ctx, render.tile)
    axis = render.axis
    n_u, n_v, n_a = spec.dims[(axis + 1) % 3], spec.dims[(axis + 2) % 3], spec.dims[axis]
    slices = SLICES_PER_TARGET * render.targets
    tiles_u, tiles_v = tile_spans(n_u, side), tile_spans(n_v, side)
    passes = -(-n_a // slices)
    fix_bits = fixed_bits(mesh, spec, axis)
    pool = buffer_pool(ctx, owner)
    # the grid first: a grid over the SSBO limit is refused before any other work
    grid = pool.get("grid", spec.n_words * 4, what=f"the {spec.dims} bit grid")
    count = pool.get("count", 4)
    on_grid = _prepare(ctx, mesh, spec, render, pool, timer, fix_bits)
    per_pass = render.targets_per_pass(n_a)
    tg = _targets(ctx, max(per_pass), (tiles_u[0][1], tiles_v[0][1]))
    programs = {used: _pass_programs(ctx, render, spec, on_grid.anchor, tg, used) for used in set(per_pass)}
    # depth, culling and blending would change what the logic op sees
    ctx.mgl.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
    try:
        for u0, tw in tiles_u:
            for v0, th in tiles_v:
                for p, used in enumerate(per_pass):
                    tile = {"u_tile_lo": (u0, v0), "u_tile_size": (tw, th),
                            "u_slice_lo": p * slices, "u_slice_hi": min((p + 1) * slices, n_a)}
                    with timer.stage("render"):
                        _draw_pass(ctx, render, programs[used], on_grid, tile)
                    with timer.stage("pack"):
                        _pack_pass(ctx, render, programs[used], tg, used, grid, count, tile)
    finally:
        for pp in programs.values():
            pp.release()
    timer.stats.update({
        "axis": axis, "coverage": render.coverage, "masks": render.masks, "render_targets": max(per_pass),
        "slices_per_pass": slices, "passes": passes, "tiles": [len(tiles_u), len(tiles_v)],
        "draws": passes * len(tiles_u) * len(tiles_v), "tile_limit": side, "fixed_bits": fix_bits,
    })
    return grid, count
