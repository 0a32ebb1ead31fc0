"""``peel-ldi``: the exact LDI by depth peeling (the baseline of Leung & Wang 2013, Table II).

Everitt 2001's depth peeling as ``passalis-peel`` runs it (Passalis et al.
2006 Sec. 3.3), on the raster machinery of :mod:`glvox.methods.depth.raster`:
one pass per layer, every crossing recorded in depth order (ties broken by
triangle id, so crossings sharing a depth are all kept), as many passes as
the largest stencil count of the first pass says (or until a pass draws
nothing when the 8-bit stencil saturates).

Steps: per tile of the view, a first pass counting every crossing in the
stencil (``shaders/ldi/peel_count.comp`` reduces the largest count), which
sizes the depth buffers; then per tile layer 0 and the layers behind it,
each recorded into the depth buffers (``peel_record.comp``: voxel units,
float32); ``finish`` closes rays with an odd count at the grid's far face and
fills NaN past the counts.  Depths larger than one storage block go into
several buffers (chunks of layers).
"""

from __future__ import annotations

import numpy as np

from ...errors import MethodError
from ...gl.shaders import compute_program
from ...gpu.buffers import buffer_pool, check_buffer_size, clear_buffer, mesh_buffers
from ...gpu.dispatch import barrier, bind, dispatch_1d, grid_uniforms, set_uniforms
from ...gpu.fixed_point import fixed_bits
from ...gpu.transform import SNAP_DEFINES
from ...results.ldi import LDI
from ..base import Method, MethodInfo, Option, Requirements, register
from ..depth.raster import RasterPass, depth_target, peel_behind, stencil_layers, tile_origins, tile_side
from .common import AXIS_OPTION, Rays, read_chunks, warn_open

_LOCAL = 64  # local_size_x of ldi/peel_finish.comp

#: Most layers per depth buffer while the number of layers is unknown (a
#: saturated stencil count); more buffers follow when needed.
OPEN_CHUNK_LAYERS = 256


def _chunk_layers(ctx, n_rays: int, wanted: int, open_ended: bool) -> int:
    """Layers per depth chunk: all ``wanted`` when they fit one storage block (and the
    count is known), else as many as fit, at most :data:`OPEN_CHUNK_LAYERS`."""
    limit = int(ctx.limits()["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"])
    per_layer = n_rays * 4
    if per_layer > limit:
        check_buffer_size(ctx, per_layer, f"one layer of the LDI depths ({n_rays} rays)")
    fit = limit // per_layer
    return max(1, min(fit, OPEN_CHUNK_LAYERS if open_ended else wanted))


class _DepthChunks:
    """The LDI depths in buffers of :attr:`layers` layers each, made as layers are recorded."""

    def __init__(self, pool, n_rays: int) -> None:
        self.pool, self.n_rays = pool, n_rays
        #: layers per buffer; set before the first :meth:`ensure`
        self.layers = 1
        self.bufs: list = []
        self.ranges: list[tuple[int, int]] = []

    def ensure(self, layer: int) -> int:
        """The index of the chunk holding ``layer`` (allocated on first use)."""
        while not self.ranges or layer >= self.ranges[-1][0] + self.ranges[-1][1]:
            lo = self.ranges[-1][0] + self.ranges[-1][1] if self.ranges else 0
            self.ranges.append((lo, self.layers))
            self.bufs.append(self.pool.get(f"depths{len(self.bufs)}", self.n_rays * self.layers * 4,
                                           what="the LDI depths", clear=False))
        return layer // self.layers


class _Peeling:
    """One peel-ldi run: its buffers and programs, and the steps over them."""

    def __init__(self, ctx, mesh, rays: Rays, size: tuple[int, int], owner: str, fix_bits: int) -> None:
        self.ctx, self.rays, self.size = ctx, rays, size
        pool = buffer_pool(ctx, owner)
        self.counts = pool.get("counts", rays.n_rays * 4, what="samples per ray")
        self.last = pool.get("last", rays.n_rays * 4, what="last depth per ray")
        self.stats = pool.get("stats", 8)
        self.bufs = mesh_buffers(ctx, mesh)
        self.uniforms = grid_uniforms(rays.spec, self.bufs.anchor)
        self.count_prog = compute_program(ctx, "ldi/peel_count.comp")
        self.record = compute_program(ctx, "ldi/peel_record.comp", {"EIS_AXIS": rays.axis, **SNAP_DEFINES})
        set_uniforms(self.count_prog, {"u_stencil": 0})
        set_uniforms(self.record, {"u_layer": 0, "u_axis": rays.axis, "u_grid_uv": (rays.n_u, rays.n_v),
                                   "u_depth_n": rays.n_a, "u_origin_d": self.uniforms["u_origin_d"],
                                   "u_inv_h_d": self.uniforms["u_inv_h_d"], "u_fix_bits": fix_bits})
        self.groups = ((size[0] + 7) // 8, (size[1] + 7) // 8, 1)
        self.chunks = _DepthChunks(pool, rays.n_rays)

    def first_pass(self, run: RasterPass, target, origin) -> int:
        """Layer 0 of a tile with every crossing counted in the stencil; the largest count."""
        run.set_tile(origin)
        run.draw(target, 0, count="restart")
        clear_buffer(self.ctx, self.stats, 4)
        target.stencil.use(0)
        bind(self.count_prog, Stats=self.stats)
        self.count_prog.run(*self.groups)
        barrier(self.ctx)
        return int(np.frombuffer(self.stats.read(size=4), dtype="<u4")[0])

    def record_layer(self, target, layer_tex: int, origin, index: int) -> None:
        """Layer ``index`` of the tile at ``origin``, held in ``target.layers[layer_tex]``,
        into its depth chunk."""
        chunks = self.chunks
        c = chunks.ensure(index)
        target.layers[layer_tex].use(0)
        bind(self.record, Verts=self.bufs.vertices, Faces=self.bufs.faces, Depths=chunks.bufs[c], Last=self.last,
             Counts=self.counts)
        set_uniforms(self.record, {"u_tile_origin": origin, "u_layer_index": index,
                                   "u_chunk_lo": chunks.ranges[c][0], "u_chunk_layers": chunks.layers})
        self.record.run(*self.groups)
        barrier(self.ctx)

    def peel(self, run: RasterPass, target, origins) -> int:
        """Every layer of every tile; returns the most layers of a ray.

        The largest crossing count of every tile comes first, to size the
        depth chunks; with one tile that counting pass is its layer 0, with
        several each tile redraws it.
        """
        firsts = [self.first_pass(run, target, o) for o in origins]
        known, open_ended = stencil_layers(max(firsts, default=0))
        self.chunks.layers = _chunk_layers(self.ctx, self.rays.n_rays, known + 1, open_ended)
        layers = 0
        for origin, counted in zip(origins, firsts):
            if counted == 0:
                continue
            if len(origins) > 1:
                self.first_pass(run, target, origin)
            self.record_layer(target, 0, origin, 0)
            n = peel_behind(run, target, counted,
                            lambda layer, index: self.record_layer(target, layer, origin, index))
            layers = max(layers, n)
        return layers

    def finish(self, layers: int) -> int:
        """Close odd rays and fill NaN past the counts in every chunk in use; returns the
        layers in use (one more than ``layers``: a ray with an odd count gets its closing sample)."""
        rays, chunks = self.rays, self.chunks
        room = layers + 1
        if layers:
            chunks.ensure(room - 1)
        prog = compute_program(self.ctx, "ldi/peel_finish.comp", {"EIS_AXIS": rays.axis})
        for c, (c0, n) in enumerate(chunks.ranges):
            if c0 >= room:
                break
            bind(prog, Depths=chunks.bufs[c], Counts=self.counts)
            set_uniforms(prog, {"u_grid_uv": (rays.n_u, rays.n_v), "u_chunk_lo": c0, "u_chunk_layers": n,
                                "u_layers": room, "u_depth_n": rays.n_a, "u_invocations": rays.n_rays * n})
            dispatch_1d(self.ctx, prog, rays.n_rays * n, _LOCAL)
        barrier(self.ctx)
        return room

    def read(self, room: int) -> tuple[np.ndarray, np.ndarray]:
        """The depths (n_p, n_q, n_max) float32 and the counts (n_p, n_q) int32, odd
        counts closed."""
        rays, chunks = self.rays, self.chunks
        cnt = np.frombuffer(self.counts.read(size=rays.n_rays * 4), dtype="<u4").reshape(rays.out_shape())
        cnt = cnt.astype(np.int32) + (cnt % 2).astype(np.int32)
        n_max = int(cnt.max()) if cnt.size else 0
        used = [(b, r) for b, r in zip(chunks.bufs, chunks.ranges) if r[0] < room]
        return read_chunks(used, rays.n_rays, n_max, rays.out_shape()), cnt


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
    owner : str
        Name of the buffer pool.

    Returns
    -------
    LDI
    """
    if axis not in (0, 1, 2):
        raise MethodError(f"option axis must be 0, 1 or 2, got {axis!r}")
    side = tile_side(ctx, tile)
    rays = Rays(spec, int(axis))
    fix_bits = fixed_bits(mesh, spec, rays.axis)  # before any work: a mesh out of the coverage test's range
    size, origins = tile_origins(rays.n_u, rays.n_v, side)
    peeling = _Peeling(ctx, mesh, rays, size, owner, fix_bits)
    target = depth_target(ctx, size)
    with RasterPass(ctx, peeling.bufs, peeling.uniforms) as run:
        run.set_view(spec, rays.axis, size, fix_bits)
        with timer.stage("peel"):
            layers = peeling.peel(run, target, origins)
    with timer.stage("finish"):
        room = peeling.finish(layers)
    with timer.stage("readback", gpu=False):
        depths, cnt = peeling.read(room)
    n_max = depths.shape[2]
    timer.stats.update({"axis": rays.axis, "n_max": n_max, "samples": int(cnt.sum()), "passes": run.passes,
                        "tiles": len(origins)})
    return LDI(depths, cnt, spec, rays.axis)


@register
class PeelLDI(Method):
    info = MethodInfo(
        name="peel-ldi", kind="ldi", pipeline="raster",
        paper="Everitt 2001 depth peeling as in Passalis et al. 2006, Sec. 3.3 (the baseline of "
              "Leung & Wang 2013, Sec. II and Table II)",
        summary="exact LDI by depth peeling: one raster pass per layer, every crossing in depth order",
        reference="reference-solid", exact=True,
        requires=Requirements(gl_version=450, limits={"GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 8},
                              compute=(("ldi/peel_*.comp", {}),)),
        options={
            "axis": AXIS_OPTION,
            "tile": Option(0, "largest render-target side in pixels; larger views are drawn in tiles "
                              "(0: the context's limits)"),
        },
    )

    def run(self, mesh, spec, *, ctx, timer, axis, tile):
        warn_open(mesh, self.info.name)
        return peeled_ldi(ctx, mesh, spec, timer=timer, axis=axis, tile=tile, owner=self.info.name)
