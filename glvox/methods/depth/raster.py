"""The raster machinery of the depth-buffer methods and of ``peel-ldi``.

Shared by :mod:`glvox.methods.depth.layers` (``karabassi``, ``passalis-*``)
and :mod:`glvox.methods.ldi.peel`: both render the mesh orthographically
along an axis with ``shaders/depth/raster.*``, one z-buffer per pass, into
render targets of one size, and both peel layer after layer.

* :class:`DepthTarget` / :func:`depth_target`: three RGBA32UI layer textures
  sharing one ``DEPTH32F_STENCIL8`` texture (the stencil counts crossings and
  is readable in shaders), made through the raw binding, kept per context
  and size in the context's declared caches.
* :func:`view_limit`, :func:`tile_side`, :func:`tile_origins`: the largest
  render-target side the context allows, the ``tile`` option, and the tiles
  of a view.
* :class:`RasterPass`: the raster program over the uploaded mesh; ``draw``
  renders one z-buffer (a facing class, nearest or farthest, peeled behind a
  previous layer, counted in the stencil or not).
* :func:`peel_behind`: the layers behind the first one, as many as the
  stencil counted, or until a pass draws nothing when the count saturated
  (:func:`stencil_layers`).
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass, field
from typing import Any, Callable

import moderngl

from ...errors import CapabilityError, MethodError
from ...gl import raw as rawgl
from ...gl.shaders import render_program
from ...gpu.buffers import object_cache
from ...gpu.dispatch import rendered, set_uniforms
from ...gpu.transform import SNAP_DEFINES

#: Largest count the 8-bit stencil holds (GL_INCR saturates there).  A view
#: whose first peeling pass counts this many crossings keeps peeling until a
#: pass draws nothing (occlusion query); the tests lower it to reach that
#: path on small meshes.
STENCIL_MAX = 255

#: Owner of this module's objects in :func:`glvox.gpu.buffers.object_cache`.
_CACHE = "depth-raster"

#: ``shaders/depth/key.glsl``'s codes stay below 2 ** KEY_BITS: the float32 bit
#: patterns from the smallest normal float up to 1 hold more values than that.
KEY_BITS = 29


def key_uniforms(n_axis: int) -> dict[str, Any]:
    """``shaders/depth/key.glsl``'s uniforms for a view with ``n_axis`` voxels along its
    rays: keys that order the slots (the first voxel beyond a crossing) exactly, with
    ``KEY_BITS - bits(n_axis + 1)`` bits for the order within a slot (at least 10 on any
    grid: :data:`glvox.grid.MAX_DIM` voxels, times 4 for binvox's ``down``)."""
    return {"u_depth_n": n_axis, "u_key_frac_bits": KEY_BITS - (n_axis + 1).bit_length()}


# ---------------------------------------------------------------------------
# render targets: layer textures and a depth-stencil texture, made through the raw binding
# ---------------------------------------------------------------------------


@dataclass(eq=False)
class DepthTarget:
    """Render targets of one size: three RGBA32UI layers sharing one depth-stencil texture.

    Attributes
    ----------
    size : (w, h)
        Pixels; a tile of a view.
    layers : list of moderngl.Texture
        uint32 (key bits, triangle id, first voxel beyond, valid) per pixel.
    fbos : list of moderngl.Framebuffer
        ``fbos[i]`` draws into ``layers[i]`` with the shared depth-stencil.
    depth_stencil : int
        GL name of the ``DEPTH32F_STENCIL8`` texture (stencil readable in shaders).
    stencil : moderngl.Texture
        The same texture wrapped for binding to a sampler (its stencil index).
    """

    size: tuple[int, int]
    layers: list = field(default_factory=list)
    fbos: list = field(default_factory=list)
    depth_stencil: int = 0
    stencil: Any = None

    def release(self, ctx) -> None:
        for fbo in self.fbos:
            ctx.release_framebuffer(fbo)
        for tex in self.layers:
            tex.release()
        if self.depth_stencil:
            name = (rawgl.GLuint * 1)(self.depth_stencil)
            ctx.raw.fn("glDeleteTextures")(1, name)
        self.fbos, self.layers, self.depth_stencil = [], [], 0


def _make_target(ctx, size: tuple[int, int]) -> DepthTarget:
    """Three layer textures and a depth-stencil texture of ``size``, in three framebuffers.

    moderngl's depth attachments carry no stencil, so the depth-stencil texture
    and the framebuffers are made through the raw binding and wrapped with
    ``detect_framebuffer``.  The depth is 32-bit float so that the key a
    fragment writes is stored unchanged (the peeling comparisons need it).
    """
    raw, mgl = ctx.raw, ctx.mgl
    target = DepthTarget(size=size)
    try:
        for _ in range(3):
            tex = mgl.texture(size, 4, dtype="u4")
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            target.layers.append(tex)
        unit = raw.get_integer(rawgl.GL_ACTIVE_TEXTURE)
        bound = raw.get_integer(rawgl.GL_TEXTURE_BINDING_2D)
        name = (rawgl.GLuint * 1)()
        raw.fn("glGenTextures")(1, name)
        target.depth_stencil = int(name[0])
        raw.fn("glBindTexture")(rawgl.GL_TEXTURE_2D, target.depth_stencil)
        raw.fn("glTexStorage2D")(rawgl.GL_TEXTURE_2D, 1, rawgl.GL_DEPTH32F_STENCIL8, size[0], size[1])
        raw.fn("glTexParameteri")(rawgl.GL_TEXTURE_2D, rawgl.GL_TEXTURE_MIN_FILTER, rawgl.GL_NEAREST)
        raw.fn("glTexParameteri")(rawgl.GL_TEXTURE_2D, rawgl.GL_TEXTURE_MAG_FILTER, rawgl.GL_NEAREST)
        raw.fn("glTexParameteri")(rawgl.GL_TEXTURE_2D, rawgl.GL_DEPTH_STENCIL_TEXTURE_MODE,
                                  rawgl.GL_STENCIL_INDEX)
        raw.fn("glActiveTexture")(unit)
        raw.fn("glBindTexture")(rawgl.GL_TEXTURE_2D, bound)
        target.stencil = mgl.external_texture(target.depth_stencil, size, 1, 0, "u1")
        for tex in target.layers:
            target.fbos.append(_framebuffer(ctx, tex.glo, target.depth_stencil))
    except Exception:
        target.release(ctx)
        raise
    return target


def _framebuffer(ctx, color: int, depth_stencil: int):
    raw = ctx.raw
    previous = raw.get_integer(rawgl.GL_DRAW_FRAMEBUFFER_BINDING)
    name = (rawgl.GLuint * 1)()
    raw.fn("glGenFramebuffers")(1, name)
    fb = int(name[0])
    raw.fn("glBindFramebuffer")(rawgl.GL_FRAMEBUFFER, fb)
    raw.fn("glFramebufferTexture2D")(rawgl.GL_FRAMEBUFFER, rawgl.GL_COLOR_ATTACHMENT0,
                                     rawgl.GL_TEXTURE_2D, color, 0)
    raw.fn("glFramebufferTexture2D")(rawgl.GL_FRAMEBUFFER, rawgl.GL_DEPTH_STENCIL_ATTACHMENT,
                                     rawgl.GL_TEXTURE_2D, depth_stencil, 0)
    status = int(raw.fn("glCheckFramebufferStatus")(rawgl.GL_FRAMEBUFFER))
    raw.fn("glBindFramebuffer")(rawgl.GL_FRAMEBUFFER, previous)
    if status != rawgl.GL_FRAMEBUFFER_COMPLETE:
        raw.fn("glDeleteFramebuffers")(1, name)
        raise CapabilityError(
            f"a framebuffer with an RGBA32UI colour texture and a DEPTH32F_STENCIL8 texture is "
            f"not complete on this context (status {status:#x}, expected "
            f"{rawgl.GL_FRAMEBUFFER_COMPLETE:#x}); the depth-buffer methods need it ({ctx.renderer})")
    return ctx.mgl.detect_framebuffer(fb)


def _cache(ctx) -> dict:
    """This module's objects in ``ctx``: targets keyed by size, and the samples query."""
    return object_cache(ctx, _CACHE, lambda cache: _release_cache(ctx, cache))


def _release_cache(ctx, cache: dict) -> None:
    for key, obj in cache.items():
        if key != "query":  # moderngl cannot release queries: dropping it is all there is
            obj.release(ctx)
    cache.clear()


def depth_target(ctx, size: tuple[int, int]) -> DepthTarget:
    """The render targets of ``size`` (w, h) pixels in ``ctx``, made on first use and
    kept until the context is released."""
    cache = _cache(ctx)
    key = ("target", tuple(size))
    target = cache.get(key)
    if target is None:
        target = cache[key] = _make_target(ctx, size)
    return target


def samples_query(ctx):
    """The context's samples-passed query, made on first use and kept (moderngl
    cannot release queries, so one per context rather than one per run)."""
    cache = _cache(ctx)
    query = cache.get("query")
    if query is None:
        query = cache["query"] = ctx.mgl.query(samples=True)
    return query


# ---------------------------------------------------------------------------
# views and tiles
# ---------------------------------------------------------------------------


def view_limit(ctx) -> int:
    """Largest render-target side the context allows (texture, renderbuffer, viewport)."""
    lim = ctx.limits()
    sides = [int(lim["GL_MAX_TEXTURE_SIZE"]), int(lim["GL_MAX_RENDERBUFFER_SIZE"])]
    sides += [int(v) for v in lim["GL_MAX_VIEWPORT_DIMS"]]
    return min(sides)


def tile_side(ctx, tile: int) -> int:
    """The render-target side for option ``tile``: :func:`view_limit`, or ``tile``
    pixels when that is smaller.

    Raises
    ------
    MethodError
        ``tile`` is negative.
    """
    if tile < 0:
        raise MethodError(f"option tile must be 0 (the context's limit) or a positive "
                          f"number of pixels, got {tile}")
    limit = view_limit(ctx)
    return limit if tile == 0 else min(tile, limit)


def tile_origins(n_u: int, n_v: int, side: int) -> tuple[tuple[int, int], list[tuple[int, int]]]:
    """The target size (w, h) and the origins (u, v) of the tiles covering an
    ``n_u`` x ``n_v`` view, ``side`` pixels at most along each, rows of tiles along u first."""
    size = (min(side, n_u), min(side, n_v))
    return size, [(x, y) for y in range(0, n_v, size[1]) for x in range(0, n_u, size[0])]


# ---------------------------------------------------------------------------
# the raster pass and peeling
# ---------------------------------------------------------------------------


class RasterPass:
    """The raster program over an uploaded mesh: one z-buffer per :meth:`draw`.

    Use as a context manager: entering makes the vertex array and sets the
    pass state (depth test LESS); leaving restores what moderngl starts with
    (no stencil test, no flags, LEQUAL) and releases the vertex array.

    Parameters
    ----------
    ctx : GLContext
    bufs : glvox.gpu.buffers.MeshBuffers
    uniforms : mapping
        The grid's uniforms (:func:`glvox.gpu.dispatch.grid_uniforms`).
    snap : mapping
        The snap distance's define (:func:`glvox.gpu.transform.snap_defines`).
    """

    def __init__(self, ctx, bufs, uniforms, snap: dict = SNAP_DEFINES) -> None:
        self.ctx, self.bufs = ctx, bufs
        self.program = render_program(ctx, "depth/raster.vert", "depth/raster.frag", "depth/raster.geom",
                                      defines=snap)
        set_uniforms(self.program, {**uniforms, "u_prev": 0})
        self.vao = None
        #: raster passes drawn so far
        self.passes = 0
        self._zeros = (rawgl.GLuint * 4)()
        self._one = (ctypes.c_float * 1)(1.0)

    def __enter__(self) -> "RasterPass":
        self.vao = self.ctx.mgl.vertex_array(self.program, [(self.bufs.vertices, "3f", "in_pos")],
                                             index_buffer=self.bufs.faces, index_element_size=4)
        self.ctx.mgl.enable_only(moderngl.DEPTH_TEST)
        self.ctx.mgl.depth_func = "<"
        return self

    def __exit__(self, *exc) -> None:
        self.ctx.raw.fn("glDisable")(rawgl.GL_STENCIL_TEST)
        self.ctx.mgl.enable_only(moderngl.NOTHING)
        self.ctx.mgl.depth_func = "<="
        self.vao.release()
        self.vao = None

    def set_view(self, spec, axis: int, size: tuple[int, int], fix_bits: int) -> None:
        """Rays along ``axis``, targets of ``size``; coverage decided on (u, v) in
        multiples of 2^-``fix_bits`` voxel (:func:`glvox.gpu.fixed_point.fixed_bits` of the
        mesh, the grid and ``axis``); the depth keys of :func:`key_uniforms`."""
        set_uniforms(self.program, {"u_axis": axis, "u_target_size": size, "u_fix_bits": fix_bits,
                                    **key_uniforms(spec.dims[axis])})

    def set_tile(self, origin: tuple[int, int]) -> None:
        set_uniforms(self.program, {"u_tile_origin": origin})

    def draw(self, target: DepthTarget, layer: int, *, cls: int = 0, far: bool = False,
             prev: int | None = None, count: str | None = None, query=None) -> None:
        """One z-buffer: draw the mesh into ``target.layers[layer]``.

        Parameters
        ----------
        cls : {0, 1, -1}
            Facing class drawn (sign of the normal along the rays; 0 both).
        far : bool
            Keep the farthest crossing instead of the nearest.
        prev : int, optional
            Peel behind the crossings of ``target.layers[prev]``.
        count : {None, 'restart', 'continue'}
            Count every crossing in the stencil, from zero or on top of the
            previous pass's count.
        query : moderngl.Query, optional
            Wraps the draw (:func:`samples_query`).
        """
        raw = self.ctx.raw
        fbo = target.fbos[layer]
        fbo.use()
        raw.fn("glClearBufferuiv")(rawgl.GL_COLOR, 0, self._zeros)
        raw.fn("glStencilMask")(0xFF)
        if count == "restart":
            raw.fn("glClearBufferfi")(rawgl.GL_DEPTH_STENCIL, 0, 1.0, 0)
        else:
            raw.fn("glClearBufferfv")(rawgl.GL_DEPTH, 0, self._one)
        if count is None:
            raw.fn("glDisable")(rawgl.GL_STENCIL_TEST)
        else:
            raw.fn("glEnable")(rawgl.GL_STENCIL_TEST)
            raw.fn("glStencilFunc")(rawgl.GL_ALWAYS, 0, 0xFF)
            # every fragment that survives the coverage test counts, in front or behind
            raw.fn("glStencilOp")(rawgl.GL_KEEP, rawgl.GL_INCR, rawgl.GL_INCR)
        # from the far face, the last of equal keys in primitive order wins (largest id),
        # so that a class's nearest and farthest crossings differ whenever it has two
        self.ctx.mgl.depth_func = "<=" if far else "<"
        set_uniforms(self.program, {"u_class": cls, "u_far": far, "u_peel": prev is not None})
        if prev is not None:
            target.layers[prev].use(0)
        if query is not None:
            with query:
                self.vao.render(moderngl.TRIANGLES)
        else:
            self.vao.render(moderngl.TRIANGLES)
        rendered(self.ctx)
        self.passes += 1


def stencil_layers(count: int) -> tuple[int, bool]:
    """(layers a stencil ``count`` vouches for, whether it saturated at :data:`STENCIL_MAX`
    so that more layers may follow)."""
    return min(count, STENCIL_MAX), count >= STENCIL_MAX


def peel_behind(run: RasterPass, target: DepthTarget, counted: int, record: Callable[[int, int], None],
                *, cls: int = 0) -> int:
    """Peel the layers behind ``target.layers[0]``, which the caller drew with every
    crossing of class ``cls`` counted in the stencil, ``counted`` the tile's largest count.

    Layer ``index`` = 1, 2, ... is drawn into ``target.layers[1]`` and
    ``[0]`` in turn, each behind the one before, and handed to
    ``record(layer, index)`` (``layer`` the texture holding it).  Up to the
    count when it is below :data:`STENCIL_MAX`; at a saturated count, on
    until a pass draws nothing.

    Returns
    -------
    int
        The number of layers, layer 0 included (``counted`` below saturation).
    """
    known, saturated = stencil_layers(counted)
    cur, prev = 1, 0
    for index in range(1, known):
        run.draw(target, cur, cls=cls, prev=prev)
        record(cur, index)
        cur, prev = prev, cur
    if not saturated:
        return known
    # the 8-bit stencil saturated: peel on until a pass finds no crossing left
    query = samples_query(run.ctx)
    index = known
    while True:
        run.draw(target, cur, cls=cls, prev=prev, query=query)
        if query.samples == 0:
            return index
        record(cur, index)
        cur, prev = prev, cur
        index += 1
