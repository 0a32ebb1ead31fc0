"""Leung & Wang 2013 conservative LDI sampling and its intersecting-volume application.

``leung-wang-ldi`` (Leung & Wang 2013, Sec. III; Alg. 1-2, Eq. 1-6).  Rays run
along ``axis`` through the pixel centers of the grid's other two axes
(:mod:`glvox.results.ldi`); along the rays the range of the grid is cut into
``lod_c`` cells (the paper's r_z, "Level of Details in Conservation").

* Phase 1 (Alg. 1): T1, the XOR solid voxelization of Eisemann & Decoret on
  the cells (bit k: inside at the top of cell k), and T2, an OR pass marking
  the cells that hold crossings while T1 is 0 on both sides (parts thinner
  than a cell).  Both render the mesh orthographically into
  :data:`TARGETS` RGBA32UI targets, 128 cells each (1024 per pass; more
  passes for a larger LOD-C), with the logic op; a compute pass copies each
  pass into a mask buffer holding each ray's words consecutively.  The render
  reuses the Eisemann & Decoret machinery (:mod:`glvox.methods.eisemann.passes`'
  shaders: per-triangle setup, the exact-coverage vertex stage, the column
  tests and mask writers); only the transform (per-axis scale to cells) and
  the two fragment shaders are this method's.
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
* Views larger than the render-target limit (or the ``tile`` option's side)
  are drawn tile by tile, with identical results.

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

:func:`intersecting_ldi` is the application of Sec. V-A: T1 and T2 of two
meshes on one grid, their AND (with a T2 for thin overlaps, see
``shaders/ldi/intersect.comp``), and Phase 2 drawing both meshes: the LDI of
the overlap, whose :attr:`~glvox.results.ldi.LDI.volume` is the intersecting volume.

The GPU passes (render targets, the frame of rays and cells, Phase 1, the
n_max pass, Phase 2) are in :mod:`glvox.methods.ldi.leung_wang_passes`; the
other LDI methods are ``peel-ldi`` (:mod:`glvox.methods.ldi.peel`, the exact
LDI by depth peeling, the paper's Table II baseline) and ``reference-ldi``
(:mod:`glvox.methods.reference.registered`).
"""

from __future__ import annotations

from typing import Any

import moderngl
import numpy as np

from ...errors import GridError, MethodError
from ...gl.shaders import compute_program
from ...gpu.buffers import buffer_pool
from ...gpu.fixed_point import fixed_bits
from ...gpu.dispatch import LOOP_BUDGET, barrier, bind, dispatch_1d, set_uniforms
from ...grid import GridSpec, fit_grid
from ...results.ldi import LDI
from ...gpu.transform import SHADERS as TRANSFORM_SHADERS
from ..base import Method, MethodInfo, Option, Requirements, register
from ..envelope import run_in_envelope
from .common import AXIS_OPTION, warn_open
from .leung_wang_passes import (TARGETS, Frame, OnGrid, check_fragment_storage, count_samples, phase2, prepare,
                                read_result, release_targets, render_mask, tile_limit)

_PAPER = "Leung & Wang 2013"

#: The paper's LOD-C of Table II ("in most cases ... accurate enough").
DEFAULT_LOD_C = 1024

#: Largest LOD-C: a ray's masks are LOD-C / 32 words, and the fast bit
#: checking of one fragment and the n_max pass loop over them (2048
#: iterations here, far below the loop budget).
MAX_LOD_C = 1 << 16
assert MAX_LOD_C // 32 < LOOP_BUDGET // 4

_LOCAL = 64  # local_size_x of ldi/intersect.comp
_REQUIRES = Requirements(gl_version=450, limits={
    "GL_MAX_DRAW_BUFFERS": TARGETS, "GL_MAX_COLOR_ATTACHMENTS": TARGETS,
    "GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 12},
    compute=tuple((f"ldi/{name}.comp", {}) for name in ("intersect", "count", "masks_store", "store"))
    + (("eisemann/setup.comp", {}),) + TRANSFORM_SHADERS, behaviours=("integer-logic-op",))
_TILE = Option(0, "largest render-target side in pixels; larger views are drawn in tiles (0: the context's "
                  "limits); any side >= 1 (the passes store whole rays)")


# ---------------------------------------------------------------------------
# the pipelines
# ---------------------------------------------------------------------------


def _frame(ctx, spec, axis: int, lod_c: int, targets: int, tile: int) -> Frame:
    """The run's frame from the options, checked, and the context's fragment storage."""
    if axis not in (0, 1, 2):
        raise MethodError(f"option axis must be 0, 1 or 2, got {axis!r}")
    if not 1 <= int(lod_c) <= MAX_LOD_C:
        raise MethodError(f"option lod_c (cells along the rays) must be in 1..{MAX_LOD_C}, got {lod_c!r}")
    if not 1 <= int(targets) <= TARGETS:
        raise MethodError(f"option targets must be in 1..{TARGETS}, got {targets!r}")
    side = tile_limit(ctx, int(tile))
    check_fragment_storage(ctx)
    return Frame(spec, int(axis), int(lod_c), int(targets), side)


def _buffers(frame: Frame, pool, masks) -> dict[str, Any]:
    """The bit masks named ``masks`` (one word per 32 cells of each ray), ``counts``
    (samples per ray) and ``stats`` (n_max and the total) from ``pool``.  The big buffers
    come first, so that one over the storage-block limit is refused before any work."""
    mask_bytes = frame.n_rays * frame.words * 4
    what = f"a bit mask of {frame.n_rays} rays x {frame.cells} cells"
    bufs = {n: pool.get(n, mask_bytes, what=what, clear=False) for n in masks}
    bufs["counts"] = pool.get("counts", frame.n_rays * 4, what="samples per ray", clear=False)
    bufs["stats"] = pool.get("stats", 8)
    return bufs


def _phase1(ctx, frame: Frame, on_grid: OnGrid, t1, t2, timer, stats, suffix: str = "") -> None:
    """Alg. 1: T1 (XOR) then T2 (OR, reading T1) of one mesh, stages ``t1`` and ``t2``
    (with ``suffix``)."""
    render_mask(ctx, frame, on_grid, "xor", t1, None, timer, f"t1{suffix}", stats)
    render_mask(ctx, frame, on_grid, "or", t2, t1, timer, f"t2{suffix}", stats)


def _depths(ctx, frame: Frame, meshes: list[OnGrid], bufs: dict, pool, timer, stats) -> LDI:
    """The n_max pass, Alg. 2 over ``meshes`` and the readback: the LDI of the masks
    ``bufs['t1']`` and ``bufs['t2']``."""
    t1, t2, counts = bufs["t1"], bufs["t2"], bufs["counts"]
    n_max, samples = count_samples(ctx, frame, t1, t2, counts, bufs["stats"], timer)
    chunks = phase2(ctx, frame, meshes, t1, t2, counts, n_max, pool, timer, stats)
    depths, cnt = read_result(frame, chunks, counts, n_max, timer)
    stats.update({"lod_c": frame.cells, "axis": frame.axis, "n_max": n_max, "samples": samples})
    timer.stats.update(stats)
    return LDI(depths, cnt, frame.spec, frame.axis, lod_c=frame.cells)


def _new_stats() -> dict[str, Any]:
    return {"draws": 0, "render_targets": [0, 0]}


def conservative_ldi(ctx, mesh, spec, *, timer, axis: int = 2, lod_c: int = DEFAULT_LOD_C,
                     targets: int = TARGETS, tile: int = 0, owner: str = "leung-wang-ldi") -> LDI:
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
    tile : int
        Largest render-target side in pixels, any side >= 1; 0: the
        context's limits (:func:`~glvox.methods.ldi.leung_wang_passes.tile_limit`).
    owner : str
        Name of the buffer pool.

    Returns
    -------
    LDI
    """
    frame = _frame(ctx, spec, axis, lod_c, targets, tile)
    fixed_bits(mesh, spec, frame.axis, warn=False)  # a mesh out of the coverage test's range: refused before any work
    pool = buffer_pool(ctx, owner)
    m = _buffers(frame, pool, ("t1", "t2"))
    stats = _new_stats()
    on_grid = prepare(ctx, mesh, frame, pool, "a", timer)
    ctx.mgl.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
    _phase1(ctx, frame, on_grid, m["t1"], m["t2"], timer, stats)
    return _depths(ctx, frame, [on_grid], m, pool, timer, stats)


def _combine(ctx, frame: Frame, m: dict, timer) -> None:
    """Stage ``combine``: T1 = T1_A AND T1_B, and T2 as ``shaders/ldi/intersect.comp`` says."""
    prog = compute_program(ctx, "ldi/intersect.comp")
    n_words = frame.n_rays * frame.words
    set_uniforms(prog, {"u_words": frame.words, "u_cells": frame.cells, "u_invocations": n_words})
    with timer.stage("combine"):
        bind(prog, OutT1=m["t1"], OutT2=m["t2"], A1=m["t1_a"], A2=m["t2_a"], B1=m["t1_b"], B2=m["t2_b"])
        dispatch_1d(ctx, prog, n_words, _LOCAL)
        barrier(ctx)


def intersecting_ldi(ctx, mesh_a, mesh_b, spec, *, timer, axis: int = 2, lod_c: int = DEFAULT_LOD_C,
                     targets: int = TARGETS, tile: int = 0, owner: str = "leung-wang-intersection") -> LDI:
    """The conservative LDI of the overlap of two closed meshes (Leung & Wang 2013 Sec. V-A).

    T1 and T2 of each mesh on the same rays and cells (Phase 1 twice), their
    combination (``combine``: T1 = T1_A AND T1_B, T2 as in
    ``shaders/ldi/intersect.comp``), then the n_max pass and Phase 2 drawing
    the triangles of both meshes.  Parameters as :func:`conservative_ldi`;
    stages get ``_a`` / ``_b`` suffixes for the per-mesh ones.

    Returns
    -------
    LDI
        Its :attr:`~glvox.results.ldi.LDI.volume` is the intersecting volume (world
        units cubed), an upper bound of the overlap sampled on the rays.
    """
    frame = _frame(ctx, spec, axis, lod_c, targets, tile)
    for mesh in (mesh_a, mesh_b):  # a mesh out of the coverage test's range: refused before any work
        fixed_bits(mesh, spec, frame.axis, warn=False)
    pool = buffer_pool(ctx, owner)
    m = _buffers(frame, pool, ("t1", "t2", "t1_a", "t2_a", "t1_b", "t2_b"))
    stats = _new_stats()
    grids = {"a": prepare(ctx, mesh_a, frame, pool, "a", timer, "_a"),
             "b": prepare(ctx, mesh_b, frame, pool, "b", timer, "_b")}
    ctx.mgl.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
    for tag, g in grids.items():
        _phase1(ctx, frame, g, m[f"t1_{tag}"], m[f"t2_{tag}"], timer, stats, f"_{tag}")
    _combine(ctx, frame, m, timer)
    return _depths(ctx, frame, list(grids.values()), m, pool, timer, stats)


# ---------------------------------------------------------------------------
# the registered method
# ---------------------------------------------------------------------------


@register
class LeungWangLDI(Method):
    info = MethodInfo(
        name="leung-wang-ldi", kind="ldi", pipeline="raster",
        paper=f"{_PAPER}, Sec. III (Alg. 1-2, Eq. 1-6): XOR/OR bit masks, fast bit checking, MAX blending",
        summary="conservative LDI: T1 (XOR) and T2 (OR) masks on LOD-C cells, n_max pass, 32 sorted "
                "layers per pass by bitCount and MAX blending; encloses every exact interior segment",
        reference="reference-solid", exact=False, requires=_REQUIRES,
        options={
            "lod_c": Option(DEFAULT_LOD_C, f"cells along the rays (the paper's LOD-C, r_z), 1..{MAX_LOD_C}; "
                                           "1024 per Phase-1 pass"),
            "axis": AXIS_OPTION,
            "targets": Option(TARGETS, "render targets per pass (8 as in the paper: 1024 cells, 32 layers); "
                                       "fewer means more passes", tuple(range(1, TARGETS + 1))),
            "tile": _TILE,
        },
    )

    def run(self, mesh, spec, *, ctx, timer, lod_c, axis, targets, tile):
        warn_open(mesh, self.info.name)
        return conservative_ldi(ctx, mesh, spec, timer=timer, axis=axis, lod_c=lod_c, targets=targets,
                                tile=tile, owner=self.info.name)

    def release(self, ctx) -> None:
        super().release(ctx)
        buffer_pool(ctx, INTERSECTION.name).release()
        release_targets(ctx)


# ---------------------------------------------------------------------------
# the intersecting-volume application (Sec. V-A), run like a method
# ---------------------------------------------------------------------------

#: The application's entry for the run envelope (two meshes, so not in the registry).
INTERSECTION = MethodInfo(
    name="leung-wang-intersection", kind="ldi", pipeline="raster",
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
                     targets: int = TARGETS, tile: int = 0) -> LDI:
    """:func:`intersecting_ldi` with what :func:`glvox.methods.run_method` does around a method:
    the watertight check, the context and its capabilities, stage timings and ``result.run``.

    Parameters
    ----------
    mesh_a, mesh_b : glvox.mesh.Mesh
    spec : GridSpec
        One grid for both (e.g. fitted to :func:`overlap_bounds`).
    ctx, backend, allow_open, debug
        As :func:`glvox.methods.run_method`.
    lod_c, axis, targets, tile
        As ``leung-wang-ldi``.

    Returns
    -------
    LDI
        The overlap; ``.volume`` is the intersecting volume in world units cubed.
    """
    opts = {"lod_c": int(lod_c), "axis": int(axis), "targets": int(targets), "tile": int(tile)}

    def work(ctx, timer):
        result = intersecting_ldi(ctx, mesh_a, mesh_b, spec, timer=timer, owner=INTERSECTION.name, **opts)
        timer.stats.update({"triangles": [mesh_a.n_triangles, mesh_b.n_triangles], "volume": result.volume})
        return result

    return run_in_envelope(INTERSECTION, (mesh_a, mesh_b), spec, work, options=opts, ctx=ctx,
                           backend=backend, allow_open=allow_open, debug=debug)
