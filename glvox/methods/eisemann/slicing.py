"""Eisemann & Decoret single-pass voxelization with XOR / OR logic ops (raster pipeline).

``eisemann-solid`` (Eisemann & Decoret 2008, described in Leung & Wang 2013
Sec. III-A, Alg. 1 lines 1-7, and Schwarz & Seidel 2010 Sec. 2): one
orthographic render of the mesh along an axis (x by default for the solid, z
for the surface) into 8 RGBA32UI render targets, 1024 bits per pixel, one bit
per slice.  Each fragment (a
triangle crossing a voxel column) writes ones at every slice whose voxel
center lies beyond the crossing; the logic op XOR combines them, so each bit
ends as the parity of the crossings below its voxel center: the solid
voxelization (a voxel is set iff its center is inside).  Deeper grids take
one pass per 1024 slices; a pass over fewer slices uses only the targets it
needs (one for 128 slices).

``eisemann-surface`` (Eisemann & Decoret 2006): the same machinery with OR,
each fragment setting only the slice that holds its crossing point: a thin
surface voxelization that samples each triangle at the column centers only,
so it is never conservative (it misses voxels that a triangle crosses between
column centers, and all but one voxel of a steep triangle per column) and
never invents a voxel (every voxel it sets is one the triangle meets).

Pixel grid: the plane ``(u, v) = ((axis + 1) % 3, (axis + 2) % 3)`` of voxel
columns, viewport = the (tile of the) grid, orthographic projection mapping
voxel coordinate ``u`` in ``[u0, u0 + width]`` to clip ``[-1, 1]``, so pixel
centers are column centers ``(i + 0.5, j + 0.5)``.  Depth is not used: each
fragment computes its crossing ``q`` along the axis in voxel units, the
barycentric combination of the vertices with the edge functions as weights
(double precision), and the first
flipped slice ``floor(q + 1/2)`` (voxel ``k`` flips iff ``k + 1/2 > q``, the
convention of ``reference-solid``) or the crossing's slice ``floor(q)``.  No
depth test, no culling, no blending.

Coverage (``coverage`` option).  GL rasterizers snap vertices to
``2^-GL_SUBPIXEL_BITS`` of a pixel (1/256 on llvmpipe and current GPUs), so
which pixel centers a triangle covers is decided on a mesh moved by up to
2e-3 voxel, twenty times the tie tolerance of docs/design.md; measured, that
misplaces whole column segments (40 non-tie voxels on cad_featuretype.stl at
128^3).  ``"exact"`` (the default) draws each triangle grown by 1/16 pixel
(edges moved outwards, corners on the miter; a triangle around its bounding
box where a sharp corner would push the miter beyond 2 pixels), so that it
contains every column center the triangle covers whatever the snapping, and
decides coverage in the fragment shader with the reference's edge functions
and top-left fill rule, in integers on (u, v) rounded to a fixed point of
2^-F voxel (:func:`~glvox.gpu.fixed_point.fixed_bits`;
``shaders/eisemann/column.glsl`` has the precision argument, ``setup.comp``
the growth bound).  ``"raster"``
draws the triangle itself and lets GL's fill rule on the snapped vertices
decide, as the paper does; it counts a center on an edge shared by two
triangles exactly once too, but on the snapped mesh.

Pipeline: ``transform`` (vertices to voxel space, double), ``setup`` (per
triangle: the column box, the slices it can reach, the corners to draw; a
box of at most 4 column centers none of which the triangle covers, by the
fragments' own exact test, is emptied, so that the many triangles of a fine
mesh that fall between centers are never drawn), then
per tile and pass ``render`` (zero the targets, draw with the logic op) and
``pack`` (a compute pass turning the targets into glvox's packed grid: a copy
when rendering along x, 32x32 bit transposes along y and z, counting the set
bits of the words it stores), ``readback`` (the grid words and the count).
:func:`~glvox.methods.eisemann.passes.render_slice_masks` is the reusable
part (:mod:`glvox.methods.eisemann.passes`); Leung & Wang's T1 and T2 masks
reuse its shaders.

Limits.  A tile is at most :func:`~glvox.methods.eisemann.passes.tile_limit`
pixels along u and v (GL's texture, renderbuffer and viewport limits, and
``MAX_TILE`` to bound the targets' memory, 128 bytes per pixel), or the
``tile`` option's side rounded down to a multiple of 32 (at least 32);
larger grids are drawn tile by tile with identical results.  The grid itself
must fit one shader storage buffer.
"""

from __future__ import annotations

import numpy as np

from ...gpu.buffers import read_grid_words
from ...results.voxels import VoxelGrid
from ...gpu.transform import SHADERS as TRANSFORM_SHADERS
from ..base import Method, MethodInfo, Option, Requirements, register
from .passes import COVERAGES, DEFAULT_MASKS, MASKS, TARGETS, SliceRender, release_targets, render_slice_masks

_PAPER_2008 = ("Eisemann & Decoret 2008 (Leung & Wang 2013 Sec. III-A, Alg. 1 lines 1-7; "
               "Schwarz & Seidel 2010 Sec. 2)")
_PAPER_2006 = "Eisemann & Decoret 2006 (the OR variant; Schwarz & Seidel 2010 Sec. 2)"
_REQUIRES = Requirements(gl_version=450, limits={
    "GL_MAX_DRAW_BUFFERS": TARGETS, "GL_MAX_COLOR_ATTACHMENTS": TARGETS,
    "GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 4}, compute=(("eisemann/*.comp", {}),) + TRANSFORM_SHADERS,
    behaviours=("integer-logic-op",))


class _Eisemann(Method):
    op = "xor"

    def run(self, mesh, spec, *, ctx, timer, axis, masks, coverage, tile):
        render = SliceRender(self.op, axis=axis, masks=masks, coverage=coverage, tile=tile)
        grid, count = render_slice_masks(ctx, mesh, spec, render, timer=timer, owner=self.info.name)
        with timer.stage("readback", gpu=False):
            words = read_grid_words(ctx, grid, spec)
            voxels = int(np.frombuffer(count.read(size=4), dtype="<u4")[0])
        return VoxelGrid(words=words, spec=spec, count=voxels)

    def release(self, ctx) -> None:
        super().release(ctx)
        release_targets(ctx)


def _options(what: str, axis: int) -> dict[str, Option]:
    return {
        "axis": Option(axis, f"render axis: {what} along it (0=x, 1=y, 2=z)", (0, 1, 2)),
        "masks": Option(DEFAULT_MASKS, "fragment masks from bit arithmetic or a mask texture", MASKS),
        "coverage": Option("exact", "who decides the covered column centers: the double-precision "
                                    "edge test (exact) or the rasterizer on snapped vertices (raster)",
                           COVERAGES),
        "tile": Option(0, "largest render-target side in pixels; larger views are drawn in tiles "
                          "(0: the context's limits); rounded down to a multiple of 32, at least 32"),
    }


@register
class EisemannSolid(_Eisemann):
    info = MethodInfo(
        name="eisemann-solid", kind="solid", pipeline="raster",
        paper=_PAPER_2008,
        summary="solid: one orthographic render, per-fragment slice masks combined by logic op XOR "
                "into 8 RGBA32UI targets (1024 slices per pass)",
        reference="reference-solid",
        requires=_REQUIRES,
        # along x the slices are the packed grid's own words: the pack is a copy, not
        # 32 x 32 transposes with scattered stores (docs/methods/eisemann.md); the
        # solid is the same along any axis up to ties
        options=_options("parity of crossings", 0),
    )
    op = "xor"


@register
class EisemannSurface(_Eisemann):
    info = MethodInfo(
        name="eisemann-surface", kind="surface", pipeline="raster",
        paper=_PAPER_2006,
        summary="thin, non-conservative surface: the XOR machinery with OR, one slice per fragment "
                "(a subset of the conservative surface)",
        reference="reference-conservative",
        exact=False,
        requires=_REQUIRES,
        # along z as the paper draws it: which voxels it keeps depends on the axis
        options=_options("slices of the crossings", 2),
    )
    op = "or"
