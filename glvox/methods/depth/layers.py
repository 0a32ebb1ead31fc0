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

The render targets, the raster pass and the peeling loop live in
:mod:`glvox.methods.depth.raster`, shared with ``peel-ldi``.

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

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...gl.shaders import compute_program
from ...gpu.buffers import buffer_pool, clear_buffer, mesh_buffers, read_grid_words
from ...gpu.dispatch import LOOP_BUDGET, barrier, bind, dispatch_1d, grid_uniforms, set_uniforms
from ...gpu.fixed_point import fixed_bits
from ...results.voxels import VoxelGrid
from ..base import Method, MethodInfo, Option, Requirements, register
from .raster import DepthTarget, RasterPass, depth_target, peel_behind, stencil_layers, tile_origins, tile_side

_PAPER = "Passalis et al. 2006"

#: Crossings a column may hold for the double-layer buffers of Sec. 3.2 to
#: see them all (two nearest from each face); more and the column's verdict
#: is incomplete ("stencil values greater than 4").
CLASSIFIABLE_COUNT = 4

#: Slices per dispatch of the y/z prefix XOR: one invocation walks this many
#: words, far below the loop budget.
SCAN_SEGMENT = 16384
assert SCAN_SEGMENT + 64 < LOOP_BUDGET

_AXES = ("xyz", "xy", "xz", "yz", "x", "y", "z")
_AXIS_NAMES = "xyz"
_REQUIRES = Requirements(gl_version=450, limits={"GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 6},
                         compute=(("depth/*.comp", {}),))
_OPTIONS = {
    "axes": Option("xyz", "directions of projection (the paper uses all three)", _AXES),
    "tile": Option(0, "largest render-target side in pixels; larger views are drawn in tiles "
                      "(0: the context's texture, renderbuffer and viewport limits)"),
}


def prefix_xor(ctx, spec, axis: int, scan, flips) -> None:
    """``depth/scan.comp``: the prefix XOR of the packed ``flips`` grid along ``axis``, in place
    (x within each row's words at once; y and z in segments of :data:`SCAN_SEGMENT` slices,
    one dispatch each, under llvmpipe's loop budget).  Shared with ``binvox-solid``."""
    set_uniforms(scan, {"u_axis": axis})
    bind(scan, Flips=flips)
    nx, ny, nz = spec.dims
    if axis == 0:
        set_uniforms(scan, {"u_first": 0, "u_count": 0})
        dispatch_1d(ctx, scan, ny * nz, 64)
        barrier(ctx)
        return
    lines = spec.words_per_row * (nz if axis == 1 else ny)
    n = spec.dims[axis]
    for start in range(0, n, SCAN_SEGMENT):
        set_uniforms(scan, {"u_first": start, "u_count": min(SCAN_SEGMENT, n - start)})
        dispatch_1d(ctx, scan, lines, 64)
        barrier(ctx)


@dataclass(eq=False)
class _Grids:
    """The packed grids and counters of one run (from the method's buffer pool).

    ``flips``: the crossing marks of the current axis; ``acc``: the result
    (and for passalis-stencil the per-direction verdicts and the
    unclassifiable voxels); ``crowded``: per-column flags of Sec. 3.2;
    ``stats``: the stencil maximum read back per tile; ``count``: the set
    voxels of the result and (passalis-stencil) of the unclassifiable mask,
    counted by the last pass that writes them.
    """

    flips: Any
    acc: list
    crowded: Any
    stats: Any
    count: Any


# ---------------------------------------------------------------------------
# the methods
# ---------------------------------------------------------------------------


class _DepthLayers(Method):
    """The pipeline shared by the three implementations; ``_views`` differs."""

    #: 'karabassi', 'stencil' or 'peel'
    algorithm = ""

    def run(self, mesh, spec, *, ctx, timer, axes, tile):
        side = tile_side(ctx, tile)
        axis_ids = [_AXIS_NAMES.index(a) for a in axes]
        # the fixed point of each view's coverage test: a mesh out of its range is refused here
        fix = {axis: fixed_bits(mesh, spec, axis) for axis in axis_ids}
        grids = self._grids(ctx, spec, axis_ids)
        bufs = mesh_buffers(ctx, mesh)
        uniforms = grid_uniforms(spec, bufs.anchor)
        # one program per stencil mode, so that each declares only the buffers it touches
        record = {mode: compute_program(ctx, "depth/record.comp", {"CLASSIFIABLE_COUNT": CLASSIFIABLE_COUNT,
                                                                   "STENCIL_MODE": mode})
                  for mode in (0, 1, 2)}
        scan = compute_program(ctx, "depth/scan.comp")
        combine = compute_program(ctx, "depth/combine.comp")
        for prog in (*record.values(), scan, combine):
            set_uniforms(prog, uniforms)
        for prog in record.values():
            set_uniforms(prog, {"u_layer": 0, "u_dedupe": 1, "u_stencil": 2})
        passes, counts, tiles = {}, {}, {}
        with _Run(ctx, bufs, uniforms, record, grids) as run:
            for n_axis, axis in enumerate(axis_ids):
                name = _AXIS_NAMES[axis]
                tiles[name] = self._layers(run, spec, axis, side, timer, fix[axis])
                passes[name], counts[name] = run.passes, run.counts
                with timer.stage(f"classify_{name}"):
                    self._classify(ctx, spec, axis, n_axis, len(axis_ids), scan, combine, grids)
            if self.algorithm == "stencil":
                with timer.stage("finish"):
                    self._finish(ctx, spec, uniforms, grids)
        with timer.stage("readback", gpu=False):
            words = read_grid_words(ctx, grids.acc[0], spec)
            voxels, unclassifiable = (int(c) for c in np.frombuffer(grids.count.read(size=8), dtype="<u4"))
            extras = {}
            if self.algorithm == "stencil":
                extras["unclassifiable"] = VoxelGrid(words=read_grid_words(ctx, grids.acc[2], spec), spec=spec,
                                                     count=unclassifiable)
        timer.stats["passes"] = passes
        timer.stats["tiles"] = tiles
        if self.algorithm == "peel":
            timer.stats["max_crossings_per_class"] = counts
        if self.algorithm == "stencil":
            timer.stats["unclassifiable"] = extras["unclassifiable"].count
        return VoxelGrid(words=words, spec=spec, extras=extras, count=voxels)

    def _grids(self, ctx, spec, axis_ids) -> _Grids:
        """The run's buffers; the grids first: a grid over the SSBO limit is refused
        before any other work."""
        pool = buffer_pool(ctx, self.info.name)
        n_words = spec.n_words
        what = f"the {spec.dims} bit grid"
        flips = pool.get("flips", n_words * 4, what=what)
        acc = [pool.get("acc0", n_words * 4, what=what, clear=False)]
        if self.algorithm == "stencil":
            acc += [pool.get(f"acc{i}", n_words * 4, what=what, clear=False) for i in (1, 2)]
        # per-column flags of Sec. 3.2 (a placeholder for the others, which bind but never read it)
        most_columns = max(spec.dims[(a + 1) % 3] * spec.dims[(a + 2) % 3] for a in axis_ids)
        crowded = pool.get("crowded", most_columns * 4 if self.algorithm == "stencil" else 4,
                           what="per-column crossing flags", clear=False)
        return _Grids(flips, acc, crowded, pool.get("stats", 16), pool.get("count", 8))

    def _layers(self, run: "_Run", spec, axis: int, side: int, timer, fix_bits: int) -> int:
        """Stage ``layers_<axis>`` (step 1), tile by tile: the z-buffers of :meth:`_views`,
        each recorded into the flip grid; returns the number of tiles."""
        n_u, n_v = spec.dims[(axis + 1) % 3], spec.dims[(axis + 2) % 3]
        size, origins = tile_origins(n_u, n_v, side)
        target = depth_target(run.ctx, size)
        run.set_view(spec, axis, size, fix_bits)
        for prog in run.record.values():
            set_uniforms(prog, {"u_axis": axis, "u_view_size": (n_u, n_v)})
        with timer.stage(f"layers_{_AXIS_NAMES[axis]}"):
            run.passes, run.counts = 0, [0, 0]
            for origin in origins:
                run.set_tile(origin)
                for prog in run.record.values():
                    set_uniforms(prog, {"u_tile_origin": origin})
                self._views(run, target, size)
            barrier(run.ctx)
        return len(origins)

    def _views(self, run: "_Run", target: DepthTarget, size) -> None:
        raise NotImplementedError

    def _classify(self, ctx, spec, axis, n_axis, n_axes, scan, combine, grids: _Grids) -> None:
        """Prefix XOR along ``axis`` (segments for y and z), then AND into the accumulators;
        the ``n_axis``-th of ``n_axes`` directions (the last one's combine counts the result,
        but passalis-stencil's, which :meth:`_finish` finishes and counts)."""
        prefix_xor(ctx, spec, axis, scan, grids.flips)
        stencil = self.algorithm == "stencil"
        set_uniforms(combine, {"u_axis": axis, "u_mode": (2 if stencil else 0) + (0 if n_axis == 0 else 1),
                               "u_last": not stencil and n_axis == n_axes - 1})
        acc = grids.acc
        # Acc0..Acc2; the blocks the non-stencil modes leave unused still need a buffer bound
        accs = {f"Acc{i}": acc[i] if i < len(acc) else acc[0] for i in range(3)}
        bind(combine, Flips=grids.flips, **accs, Crowded=grids.crowded, Count=grids.count)
        dispatch_1d(ctx, combine, spec.n_words, 256)
        barrier(ctx)

    @staticmethod
    def _finish(ctx, spec, uniforms, grids: _Grids) -> None:
        """passalis-stencil: the per-direction verdicts into the result and the unclassifiable voxels."""
        prog = compute_program(ctx, "depth/finish.comp")
        set_uniforms(prog, uniforms)
        bind(prog, **{f"Acc{i}": buf for i, buf in enumerate(grids.acc)}, Count=grids.count)
        dispatch_1d(ctx, prog, spec.n_words, 256)
        barrier(ctx)


class _Run(RasterPass):
    """The raster pass with the recording of step 2 (the state every pass needs)."""

    def __init__(self, ctx, bufs, uniforms, record: dict, grids: _Grids):
        super().__init__(ctx, bufs, uniforms)
        #: depth/record.comp by stencil mode (:meth:`record_layer`)
        self.record, self.grids = record, grids
        #: the largest stencil count of each facing class (+, -) over the tiles of a view
        self.counts = [0, 0]

    def record_layer(self, target: DepthTarget, size, layer: int, *, dedupe: int | None = None,
                     stencil: int = 0) -> int | None:
        """Mark the crossings of ``target.layers[layer]`` in the flip grid.

        ``stencil`` 1 also returns the largest stencil count of the tile; 2
        marks the tile's columns holding more than CLASSIFIABLE_COUNT crossings.
        """
        ctx, grids = self.ctx, self.grids
        record = self.record[stencil]
        target.layers[layer].use(0)
        target.layers[dedupe if dedupe is not None else layer].use(1)
        target.stencil.use(2)
        set_uniforms(record, {"u_use_dedupe": dedupe is not None})
        bind(record, Flips=grids.flips, Stats=grids.stats, Crowded=grids.crowded)
        if stencil == 1:
            clear_buffer(ctx, grids.stats, 4)
        record.run((size[0] + 7) // 8, (size[1] + 7) // 8, 1)
        if stencil == 1:
            barrier(ctx)
            return int(np.frombuffer(grids.stats.read(size=4), dtype="<u4")[0])
        return None


@register
class Karabassi(_DepthLayers):
    info = MethodInfo(
        name="karabassi", kind="solid", pipeline="raster",
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
        name="passalis-stencil", kind="solid", pipeline="raster",
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
        name="passalis-peel", kind="solid", pipeline="raster",
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
            counted = run.record_layer(target, size, 0, stencil=1)
            run.counts[n_cls] = max(run.counts[n_cls], stencil_layers(counted)[0])
            peel_behind(run, target, counted, lambda layer, _: run.record_layer(target, size, layer), cls=cls)
