"""Depth-buffer solid voxelization of Passalis et al. 2006 (Sec. 2-3), three generations.

The general method (Sec. 2): render the mesh with orthographic projections
along the three axes; the pixel grid of a view is the voxel columns (pixel
centers are column centers, depths are in voxel units along the axis), and
each z-buffer holds one crossing of each column's ray with the surface.  A
voxel is inside when, in every direction, its center lies between a pair of
z-buffers (step 2).  The three implementations differ in how many z-buffers
they get:

* ``karabassi`` (Sec. 3.1, Karabassi et al. 1999): two z-buffers per axis,
  the nearest crossing seen from each of the two faces of the bounding box
  (depth test LESS on the depth key, then LEQUAL on the reversed key).  A voxel is
  inside iff ``first < center <= last`` along all three axes.  Wrong by
  design where a concavity is hidden from all six views (Fig. 2).
* ``passalis-stencil`` (Sec. 3.2): four z-buffers per axis, the nearest
  crossing of each facing class (sign of the normal along the rays, what face
  culling selects) from each face, with the stencil buffer counting every
  crossing of the column.  A column with at most :data:`CLASSIFIABLE_COUNT`
  crossings is complete, and one complete direction decides a voxel; voxels
  with no complete direction are returned in ``result.extras['unclassifiable']``
  (Fig. 3b) and set as the double-layer buffers of every direction say.
* ``passalis-peel`` (Sec. 3.3): depth peeling per facing class, the previous
  layer held in a 32-bit texture, as many passes as the largest stencil count
  of the first pass requires: every crossing is recorded, so the result is
  the exact parity solid for any depth complexity (up to ties).

How it runs (all on the GPU; only the pass counts and the result come back):

* one raster program (``shaders/depth/raster.*``): the vertex shader puts the
  mesh in voxel space (double), the geometry shader selects the facing class
  and draws a proxy slightly larger than the triangle, and the fragment
  shader decides coverage and the crossing depth exactly as
  ``reference-solid`` does (edge functions in double with its top-left rule;
  depth from the plane, in voxel units).  GL's own coverage is not used:
  its vertex snapping (1/256 pixel) adds or drops crossing pairs next to
  silhouette edges far from any tie;
* the depth test runs on a key written as ``gl_FragDepth`` into a 32-bit
  float depth buffer (``DEPTH32F_STENCIL8``; the stencil counts crossings);
  the fragment writes (key, triangle id, first voxel beyond the crossing) to
  an RGBA32UI layer;
* step 2 (``record``, ``scan``, ``combine``): each layer marks the first
  voxel beyond its crossing with an XOR bit in a packed grid; a prefix XOR
  along the axis turns the marks into the parity of crossings before each
  center (``first < center <= last`` for a pair); the directions are ANDed
  into the packed result grid.  This is the paper's per-voxel test
  reorganized to O(n^2) per layer plus O(n^3 / 32) per axis.

Options: ``axes`` (the directions, ``'xyz'`` as in the paper; one axis is
enough for passalis-peel on a closed mesh) and ``tile``.  Views larger than
the context's texture, renderbuffer or viewport limits are rendered in tiles
(``tile`` forces a smaller side), with identical results.  Stages per axis
``layers_<axis>`` (step 1 with its recording) and ``classify_<axis>`` (scan
and combine), then ``finish`` (passalis-stencil) and ``readback``; stats:
raster ``passes``, ``tiles`` and, for passalis-peel, the stencil maxima per
facing class (``max_crossings_per_class``) per axis; for passalis-stencil the
number of ``unclassifiable`` voxels.

Open meshes (``allow_open=True``; :func:`glvox.methods.run_method` warns):
every direction still counts the crossings its rays see, so passalis-peel
returns the voxels with an odd number of crossings along *each* of its axes
(the AND of the three parity solids); karabassi and passalis-stencil apply
their pairing rules to the crossings they see.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass, field
from typing import Any

import moderngl
import numpy as np

from ..errors import CapabilityError, MethodError
from ..gl import raw as rawgl
from ..gl.shaders import compute_program, render_program
from ..gpu.buffers import buffer_pool, mesh_buffers, read_grid_words
from ..gpu.dispatch import LOOP_BUDGET, barrier, dispatch_1d, grid_uniforms, set_uniforms
from ..results.voxels import VoxelGrid
from .base import Method, MethodInfo, Option, Requirements, register

_PAPER = "Passalis et al. 2006"

#: Crossings a column may hold for the double-layer buffers of Sec. 3.2 to
#: see them all (two nearest from each face); more and the column's verdict
#: is incomplete ("stencil values greater than 4").
CLASSIFIABLE_COUNT = 4

#: Largest count the 8-bit stencil holds (GL_INCR saturates there).  A view
#: whose first peeling pass counts this many crossings of one class keeps
#: peeling until a pass draws nothing (occlusion query).  Tests lower it to
#: exercise that path on small meshes.
STENCIL_MAX = 255

#: Slices per dispatch of the y/z prefix XOR: one invocation walks this many
#: words, far below the loop budget.
SCAN_SEGMENT = 16384
assert SCAN_SEGMENT + 64 < LOOP_BUDGET

_AXES = ("xyz", "xy", "xz", "yz", "x", "y", "z")
_AXIS_NAMES = "xyz"
_REQUIRES = Requirements(gl_version=450, limits={"GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 5})
_OPTIONS = {
    "axes": Option("xyz", "directions of projection (the paper uses all three)", _AXES),
    "tile": Option(0, "largest render-target side in pixels; larger views are drawn in tiles "
                      "(0: the context's texture, renderbuffer and viewport limits)"),
}


# ---------------------------------------------------------------------------
# render targets: layer textures and a depth-stencil texture, made through the raw binding
# ---------------------------------------------------------------------------


@dataclass(eq=False)
class _Target:
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


def _make_target(ctx, size: tuple[int, int]) -> _Target:
    """Three layer textures and a depth-stencil texture of ``size``, in three framebuffers.

    moderngl's depth attachments carry no stencil, so the depth-stencil texture
    and the framebuffers are made through the raw binding and wrapped with
    ``detect_framebuffer``.  The depth is 32-bit float so that the key a
    fragment writes is stored unchanged (the peeling comparisons need it).
    """
    raw, mgl = ctx.raw, ctx.mgl
    target = _Target(size=size)
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


def _targets(ctx) -> dict:
    """Render targets of ``ctx`` by size, released with the context."""
    targets = getattr(ctx, "_glvox_depth_targets", None)
    if targets is None:
        targets = {}
        ctx._glvox_depth_targets = targets

        def drop(targets=targets):
            for t in targets.values():
                t.release(ctx)
            targets.clear()

        ctx.on_release.append(drop)
    return targets


def _target(ctx, size: tuple[int, int]) -> _Target:
    targets = _targets(ctx)
    t = targets.get(size)
    if t is None:
        t = targets[size] = _make_target(ctx, size)
    return t


def view_limit(ctx) -> int:
    """Largest render-target side the context allows (texture, renderbuffer, viewport)."""
    lim = ctx.limits()
    sides = [int(lim["GL_MAX_TEXTURE_SIZE"]), int(lim["GL_MAX_RENDERBUFFER_SIZE"])]
    sides += [int(v) for v in lim["GL_MAX_VIEWPORT_DIMS"]]
    return min(sides)


# ---------------------------------------------------------------------------
# the methods
# ---------------------------------------------------------------------------


class _DepthLayers(Method):
    """The pipeline shared by the three implementations; ``_views`` differs."""

    #: 'karabassi', 'stencil' or 'peel'
    algorithm = ""

    def run(self, mesh, spec, *, ctx, timer, axes, tile):
        if tile < 0:
            raise MethodError(f"option tile must be 0 (the context's limit) or a positive "
                              f"number of pixels, got {tile}")
        limit = view_limit(ctx)
        side = limit if tile == 0 else min(tile, limit)
        axis_ids = [_AXIS_NAMES.index(a) for a in axes]
        pool = buffer_pool(ctx, self.info.name)
        n_words = spec.n_words
        # the grids first: a grid over the SSBO limit is refused before any other work
        what = f"the {spec.dims} bit grid"
        flips = pool.get("flips", n_words * 4, what=what)
        acc = [pool.get("acc0", n_words * 4, what=what, clear=False)]
        if self.algorithm == "stencil":
            acc += [pool.get(f"acc{i}", n_words * 4, what=what, clear=False) for i in (1, 2)]
        # per-column flags of Sec. 3.2 (a placeholder for the others, which bind but never read it)
        most_columns = max(spec.dims[(a + 1) % 3] * spec.dims[(a + 2) % 3] for a in axis_ids)
        crowded = pool.get("crowded", most_columns * 4 if self.algorithm == "stencil" else 4,
                           what="per-column crossing flags", clear=False)
        stats_buf = pool.get("stats", 16)

        bufs = mesh_buffers(ctx, mesh)
        uniforms = grid_uniforms(spec, bufs.anchor)
        raster = render_program(ctx, "depth/raster.vert", "depth/raster.frag", "depth/raster.geom")
        record = compute_program(ctx, "depth/record.comp", {"CLASSIFIABLE_COUNT": CLASSIFIABLE_COUNT})
        scan = compute_program(ctx, "depth/scan.comp")
        combine = compute_program(ctx, "depth/combine.comp")
        for prog in (raster, record, scan, combine):
            set_uniforms(prog, uniforms)
        set_uniforms(record, {"u_layer": 0, "u_dedupe": 1, "u_stencil": 2})
        set_uniforms(raster, {"u_prev": 0})
        vao = ctx.mgl.vertex_array(raster, [(bufs.vertices, "3f", "in_pos")],
                                   index_buffer=bufs.faces, index_element_size=4)
        bounds = spec.world_to_voxel(mesh.bounds)
        run = _Run(ctx, vao, raster, record, flips, stats_buf, crowded)
        passes, counts, tiles = {}, {}, {}
        try:
            ctx.mgl.enable_only(moderngl.DEPTH_TEST)
            ctx.mgl.depth_func = "<"
            for n_axis, axis in enumerate(axis_ids):
                name = _AXIS_NAMES[axis]
                n_u, n_v = spec.dims[(axis + 1) % 3], spec.dims[(axis + 2) % 3]
                size = (min(side, n_u), min(side, n_v))
                target = _target(ctx, size)
                # the depth key maps the mesh's extent along the rays into (0, 1), with room
                # for float32 vertices slightly outside the float64 bounds
                lo, hi = float(bounds[0, axis]) - 2.0, float(bounds[1, axis]) + 2.0
                set_uniforms(raster, {"u_axis": axis, "u_target_size": size,
                                      "u_depth_n": spec.dims[axis], "u_key_lo": lo,
                                      "u_key_scale": 1.0 / (hi - lo)})
                set_uniforms(record, {"u_axis": axis, "u_view_size": (n_u, n_v)})
                origins = [(x, y) for y in range(0, n_v, size[1]) for x in range(0, n_u, size[0])]
                with timer.stage(f"layers_{name}"):
                    run.passes, run.counts = 0, [0, 0]
                    for origin in origins:
                        set_uniforms(raster, {"u_tile_origin": origin})
                        set_uniforms(record, {"u_tile_origin": origin})
                        self._views(run, target, size)
                    barrier(ctx)
                passes[name], counts[name], tiles[name] = run.passes, run.counts, len(origins)
                with timer.stage(f"classify_{name}"):
                    self._classify(ctx, spec, axis, n_axis == 0, scan, combine, flips, acc, crowded)
            if self.algorithm == "stencil":
                with timer.stage("finish"):
                    prog = compute_program(ctx, "depth/finish.comp")
                    set_uniforms(prog, uniforms)
                    for i, buf in enumerate(acc):
                        buf.bind_to_storage_buffer(1 + i)
                    dispatch_1d(ctx, prog, n_words, 256)
                    barrier(ctx)
        finally:
            # leave the state as moderngl starts it (no stencil test, no flags, LEQUAL)
            ctx.raw.fn("glDisable")(rawgl.GL_STENCIL_TEST)
            ctx.mgl.enable_only(moderngl.NOTHING)
            ctx.mgl.depth_func = "<="
            vao.release()
        with timer.stage("readback", gpu=False):
            words = read_grid_words(acc[0], spec)
            extras = {}
            if self.algorithm == "stencil":
                extras["unclassifiable"] = VoxelGrid(words=read_grid_words(acc[2], spec), spec=spec)
        timer.stats["passes"] = passes
        timer.stats["tiles"] = tiles
        if self.algorithm == "peel":
            timer.stats["max_crossings_per_class"] = counts
        if self.algorithm == "stencil":
            timer.stats["unclassifiable"] = extras["unclassifiable"].count
        return VoxelGrid(words=words, spec=spec, extras=extras)

    def _views(self, run: "_Run", target: _Target, size) -> None:
        raise NotImplementedError

    def _classify(self, ctx, spec, axis, first, scan, combine, flips, acc, crowded) -> None:
        """Prefix XOR along ``axis`` (segments for y and z), then AND into the accumulators."""
        set_uniforms(scan, {"u_axis": axis})
        flips.bind_to_storage_buffer(0)
        wpr = spec.words_per_row
        nx, ny, nz = spec.dims
        if axis == 0:
            set_uniforms(scan, {"u_first": 0, "u_count": 0})
            dispatch_1d(ctx, scan, ny * nz, 64)
            barrier(ctx)
        else:
            lines = wpr * (nz if axis == 1 else ny)
            n = spec.dims[axis]
            for start in range(0, n, SCAN_SEGMENT):
                set_uniforms(scan, {"u_first": start, "u_count": min(SCAN_SEGMENT, n - start)})
                dispatch_1d(ctx, scan, lines, 64)
                barrier(ctx)
        stencil = self.algorithm == "stencil"
        set_uniforms(combine, {"u_axis": axis, "u_mode": (2 if stencil else 0) + (0 if first else 1)})
        for i, buf in enumerate(acc):
            buf.bind_to_storage_buffer(1 + i)
        # unused bindings of the non-stencil modes still need a buffer bound
        for i in range(len(acc), 3):
            acc[0].bind_to_storage_buffer(1 + i)
        crowded.bind_to_storage_buffer(4)
        dispatch_1d(ctx, combine, spec.n_words, 256)
        barrier(ctx)


class _Run:
    """One run's raster and record passes (the state every pass needs)."""

    def __init__(self, ctx, vao, raster, record, flips, stats, crowded):
        self.ctx, self.vao, self.raster, self.record = ctx, vao, raster, record
        self.flips, self.stats, self.crowded = flips, stats, crowded
        self.passes = 0
        #: the largest stencil count of each facing class (+, -) over the tiles of a view
        self.counts = [0, 0]
        self._zeros = (rawgl.GLuint * 4)()
        self._one = (ctypes.c_float * 1)(1.0)

    def draw(self, target: _Target, layer: int, *, cls: int = 0, far: bool = False,
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
        set_uniforms(self.raster, {"u_class": cls, "u_far": far, "u_peel": prev is not None})
        if prev is not None:
            target.layers[prev].use(0)
        if query is not None:
            with query:
                self.vao.render(moderngl.TRIANGLES)
        else:
            self.vao.render(moderngl.TRIANGLES)
        self.passes += 1

    def record_layer(self, target: _Target, size, layer: int, *, dedupe: int | None = None,
                     stencil: int = 0) -> int | None:
        """Mark the crossings of ``target.layers[layer]`` in the flip grid.

        ``stencil`` 1 also returns the largest stencil count of the tile; 2
        marks the tile's columns holding more than CLASSIFIABLE_COUNT crossings.
        """
        ctx = self.ctx
        target.layers[layer].use(0)
        target.layers[dedupe if dedupe is not None else layer].use(1)
        target.stencil.use(2)
        set_uniforms(self.record, {"u_use_dedupe": dedupe is not None, "u_stencil_mode": stencil})
        self.flips.bind_to_storage_buffer(0)
        self.stats.bind_to_storage_buffer(1)
        self.crowded.bind_to_storage_buffer(2)
        if stencil == 1:
            self.stats.clear(size=4)
        self.record.run((size[0] + 7) // 8, (size[1] + 7) // 8, 1)
        if stencil == 1:
            barrier(ctx)
            return int(np.frombuffer(self.stats.read(size=4), dtype="<u4")[0])
        return None

    def query(self):
        """The context's samples-passed query, made on first use and kept (moderngl
        cannot release queries, so one per context rather than one per run)."""
        query = getattr(self.ctx, "_glvox_depth_query", None)
        if query is None:
            query = self.ctx.mgl.query(samples=True)
            self.ctx._glvox_depth_query = query
        return query


@register
class Karabassi(_DepthLayers):
    info = MethodInfo(
        name="karabassi", kind="solid", family="raster",
        paper=f"{_PAPER}, Sec. 3.1 (Karabassi et al. 1999: six single-layer z-buffers)",
        summary="solid from six orthographic z-buffers (nearest crossing from each face); "
                "fills concavities hidden from all six views",
        reference="reference-solid", exact=False, requires=_REQUIRES, options=_OPTIONS,
    )
    algorithm = "karabassi"

    def _views(self, run, target, size):
        # a voxel is inside iff first < center <= last: the two crossings flip its parity
        # (one crossing seen from both faces flips twice: an empty interval)
        run.draw(target, 0)
        run.record_layer(target, size, 0)
        run.draw(target, 1, far=True)
        run.record_layer(target, size, 1)


@register
class PassalisStencil(_DepthLayers):
    info = MethodInfo(
        name="passalis-stencil", kind="solid", family="raster",
        paper=f"{_PAPER}, Sec. 3.2 (double-layer z-buffers by face culling, stencil counts)",
        summary="solid from four z-buffers per axis with stencil counting; voxels whose columns "
                "hold more than 4 crossings in every direction are marked unclassifiable",
        reference="reference-solid", exact=False, requires=_REQUIRES, options=_OPTIONS,
    )
    algorithm = "stencil"

    def _views(self, run, target, size):
        # the nearest crossing of each class from this face, counting every crossing ...
        run.draw(target, 0, cls=1, count="restart")
        run.record_layer(target, size, 0)
        run.draw(target, 1, cls=-1, count="continue")
        run.record_layer(target, size, 1, stencil=2)
        # ... and from the opposite face, each recorded unless it is the same crossing
        # (a class with one crossing in the column shows it from both faces)
        run.draw(target, 2, cls=1, far=True)
        run.record_layer(target, size, 2, dedupe=0)
        run.draw(target, 2, cls=-1, far=True)
        run.record_layer(target, size, 2, dedupe=1)


@register
class PassalisPeel(_DepthLayers):
    info = MethodInfo(
        name="passalis-peel", kind="solid", family="raster",
        paper=f"{_PAPER}, Sec. 3.3 (depth peeling with the previous layer in a 32-bit texture)",
        summary="exact parity solid from depth-peeled z-buffer pairs, as many as the largest "
                "stencil count requires (any depth complexity)",
        reference="reference-solid", exact=True, requires=_REQUIRES, options=_OPTIONS,
    )
    algorithm = "peel"

    def _views(self, run, target, size):
        for n_cls, cls in enumerate((1, -1)):
            # the first layer of the class, counting the class's crossings per column
            run.draw(target, 0, cls=cls, count="restart")
            most = min(run.record_layer(target, size, 0, stencil=1), STENCIL_MAX)
            run.counts[n_cls] = max(run.counts[n_cls], most)
            cur, prev = 1, 0
            for _ in range(1, most):
                run.draw(target, cur, cls=cls, prev=prev)
                run.record_layer(target, size, cur)
                cur, prev = prev, cur
            if most >= STENCIL_MAX:
                # the stencil saturated: peel on until a pass finds no crossing left
                query = run.query()
                while True:
                    run.draw(target, cur, cls=cls, prev=prev, query=query)
                    if query.samples == 0:
                        break
                    run.record_layer(target, size, cur)
                    cur, prev = prev, cur
