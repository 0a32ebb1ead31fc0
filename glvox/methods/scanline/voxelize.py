"""Zhang et al. 2018 projected optimal scanline voxelization in a compute shader.

``scanline-rlv``, ``scanline-slv`` and ``scanline-ilv`` run
``shaders/scanline/voxelize.comp``: one invocation per triangle voxelizes its
edges, slices it along the dominant axis and scans each slice with the
optimal scanline interval (Sec. 4, Alg. 1), writing the bit-packed grid of
``common/voxel_space.glsl`` with ``atomicOr``.  The three methods differ in
the line voxelization (Sec. 4.1): float RLV, float super cover SLV, integer
ILV (with the integer end selection of Eq. 8-9).  ``tunnel`` (26, 18, 6)
selects the paper's cover or the thinner variants of Sec. 5.  The algorithm
and its conventions are documented in :mod:`glvox.reference.scanline`, the
CPU implementation the shader mirrors step for step.

Agreement with the CPU implementation (tests/test_scanline.py):

* ILV is integer after the vertices' voxel indices; with the vertices
  transformed exactly as the shader does (:func:`gpu_voxel_coords`) the CPU
  result is the GPU result, voxel for voxel.
* RLV and SLV are float; both lie, in exact arithmetic, between the
  conservative voxelizations with box half-sizes 0.5 - eps and 0.5 (SLV is
  the conservative set itself), so float32 and float64 runs may differ only on
  the conservative tie set of :func:`glvox.reference.surface_ties`.  The thin
  variants (tunnel 18, 6) are bracketed by nothing; their ties are those of
  the algorithm, :func:`glvox.reference.scanline.float_variant_ties`.  The
  shader computes each triangle's normal in double (from the float32
  vertices): in float32 its error, ulp * |edge|^2, tilts a thin triangle's
  slicing enough to draw scanlines in the wrong layer.

Pipeline: ``setup`` (grid and scratch buffers from the pool, the mesh uploaded
once per context; ILV's table of small triangles built on its first call in a
context, :meth:`_Scanline.small_table`), ``voxelize`` (one dispatch over the
triangles; for ILV the table pass, which draws the triangles the table holds
and lists the others, then the scan over that list by an indirect dispatch),
``overflow`` (only where needed, see below), ``readback`` (the grid words;
besides them only a few counters are read: triangles listed for the overflow
stage, ILV triangles refused for :data:`~glvox.reference.scanline.ILV_COORD_LIMIT`,
which raise :class:`~glvox.errors.LimitError` after the dispatch, and ILV's
scanned triangles, ``run.stats["scanned_triangles"]``).

Mesa's llvmpipe ends all loops of a SIMD batch after 65535 iterations in
total (:data:`glvox.gpu.dispatch.LOOP_BUDGET`), silently.  Each invocation
charges itself for its loop iterations (``shaders/scanline/budget.glsl``)
against its share of that budget and, before running out, stops drawing and
lists its triangle.  Listed triangles are then measured (one invocation each,
alone in its batch) and redrawn in parts: each part repeats the triangle's
scanline selection and draws its share of the lines.  On hardware GPUs there
is no such limit and the overflow stage never runs.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ...errors import LimitError
from ...gl.shaders import compute_program
from ...gpu.buffers import (buffer_pool, clear_buffer, mesh_buffers, object_cache, read_grid_words,
                            release_object_cache)
from ...gpu.dispatch import LOOP_BUDGET, barrier, bind, dispatch_1d, grid_uniforms, set_uniforms
from ...gpu.transform import SHADERS as TRANSFORM_SHADERS, SNAP_DEFINES, gpu_triangles_voxel
from ...reference.scanline import (ILV_BOUNDARY_SNAP, ILV_COORD_LIMIT, RLV_BOUNDARY_SNAP, SCANLINE_SLACK,
                                  TUNNELS)
from ...results.voxels import VoxelGrid
from ..base import Method, MethodInfo, Option, Requirements, register

_PAPER = "Zhang et al. 2018"
_LOCAL = 64
_MODES = {"rlv": 0, "slv": 1, "ilv": 2}
_REQUIRES = Requirements(gl_version=450,
                         compute=tuple(("scanline/voxelize.comp", {"LOCAL_SIZE": _LOCAL, "PASS": pass_,
                                                                   "SMALL_TABLE": table, "FROM_LIST": listed})
                                       for pass_, table, listed in ((0, 1, 0), (0, 0, 1), (3, 0, 0)))
                         + (("scanline/scan_args.comp", {}),) + TRANSFORM_SHADERS)

#: ILV's small-triangle table: a triangle whose lattice points fit in a block of
#: SMALL_BLOCK^3 voxels reads its voxels from it (shaders/scanline/voxelize.comp).
SMALL_BLOCK = 4
#: Its entries: one per set of three of the block's corners (repeats allowed).
SMALL_SLOTS = math.comb(SMALL_BLOCK**3 + 2, 3)
_TABLES = "scanline-ilv-small"


def small_triples() -> np.ndarray:
    """The triangles ILV's small-triangle table holds, as (n, 4) uint32 ``(c0, c1,
    c2, 0)``: corners ``x + 4 y + 16 z`` of the 4 x 4 x 4 block, ``c0 <= c1 <= c2``
    (the scan does not depend on the vertices' order), whose lowest x, y and z
    are all 0 (a triangle is looked up relative to the low corner of its lattice
    box): 8,614 of the C(66, 3) = 45,760 sets of three corners."""
    c = np.arange(SMALL_BLOCK**3)
    c0, c1, c2 = (a.ravel() for a in np.meshgrid(c, c, c, indexing="ij"))
    keep = (c0 <= c1) & (c1 <= c2)
    xyz = [np.stack([k % SMALL_BLOCK, k // SMALL_BLOCK % SMALL_BLOCK, k // SMALL_BLOCK**2], axis=1)
           for k in (c0, c1, c2)]
    keep &= (np.minimum(np.minimum(xyz[0], xyz[1]), xyz[2]) == 0).all(axis=1)
    out = np.zeros((int(keep.sum()), 4), dtype=np.uint32)
    out[:, 0], out[:, 1], out[:, 2] = c0[keep], c1[keep], c2[keep]
    return out


#: Loop iterations kept back from LOOP_BUDGET per SIMD batch: the shader
#: charges the entries of its outermost loops and its final partial loop
#: iteration only approximately, and this margin covers them many times over.
BUDGET_MARGIN = 1024

_TUNNEL_OPTION = Option(26, "26: the paper's 26-tunnel-free cover; 18, 6: thinner variants that "
                            "drop (part of) the second voxelization of each base edge (Sec. 5, Fig. 9)",
                        TUNNELS)


def gpu_voxel_coords(mesh, spec) -> np.ndarray:
    """The triangles in voxel space exactly as the shader computes them, (T, 3, 3).

    The one world -> voxel transform of every GPU method with its plane snap
    (:func:`glvox.gpu.transform.gpu_vertices_voxel`), returned as float64
    holding the float32 values.  Feeding them to
    :func:`glvox.reference.scanline.scanline_surface` reproduces the GPU's ILV
    result exactly.
    """
    return gpu_triangles_voxel(mesh, spec)


def simd_lanes(ctx) -> int:
    """Invocations llvmpipe runs as one SIMD batch (from "... 256 bits)" in the renderer string)."""
    m = re.search(r"(\d+)\s*bits", ctx.renderer)
    return max(1, int(m.group(1)) // 32) if m else 8


def loop_budgets(ctx) -> tuple[int, int]:
    """Loop iterations one invocation may charge: in the main pass (shared by
    a SIMD batch) and in the overflow passes (one invocation per batch).
    Without a driver limit (hardware GPUs), effectively unlimited."""
    if not ctx.is_software:
        return 2**31 - 1, 2**31 - 1
    return (LOOP_BUDGET - BUDGET_MARGIN) // simd_lanes(ctx), LOOP_BUDGET - BUDGET_MARGIN


class _Scanline(Method):
    mode = "ilv"

    def _program(self, ctx, tunnel: int, pass_: int, from_list: bool = False):
        """voxelize.comp for ``pass_``; ILV's PASS 0 is two programs: the table pass, which
        lists the triangles it cannot draw, and the scan over that list (``from_list``)."""
        table = self.mode == "ilv" and pass_ == 0 and not from_list
        defines = {"LINE_MODE": _MODES[self.mode], "TUNNEL": int(tunnel), "PASS": pass_,
                   "SMALL_TABLE": int(table), "FROM_LIST": int(from_list),
                   "LOCAL_SIZE": _LOCAL if pass_ in (0, 3) else 1, "SCANLINE_SLACK": float(SCANLINE_SLACK),
                   "ILV_COORD_LIMIT": int(ILV_COORD_LIMIT), "ILV_BOUNDARY_SNAP": float(ILV_BOUNDARY_SNAP),
                   "RLV_BOUNDARY_SNAP": float(RLV_BOUNDARY_SNAP), **SNAP_DEFINES}
        return compute_program(ctx, "scanline/voxelize.comp", defines)

    def release(self, ctx) -> None:
        buffer_pool(ctx, "scanline").release()  # the three line modes share one pool
        release_object_cache(ctx, _TABLES)

    def small_table(self, ctx, tunnel: int):
        """ILV's small-triangle table for ``tunnel``, built on first use in ``ctx``.

        One entry (a uvec2) per set of three corners of a 4 x 4 x 4 block, at
        their rank among all such sets (``small_index`` in the shader): bit
        ``x + 4 y + 16 z`` is set where the scan draws voxel ``(x, y, z)`` of
        the block for that lattice triangle.  Built by one dispatch of the scan
        itself over :func:`small_triples` (``PASS 3``), which counts any triple
        that ran out of loop budget or drew outside its block (neither can
        happen); the entries no lookup reaches stay 0.
        """
        cache = object_cache(ctx, _TABLES, lambda c: [c.pop(k).release() for k in list(c)])
        table = cache.get(tunnel)
        if table is None:
            triples = small_triples()
            items = ctx.mgl.buffer(triples.tobytes())
            bad = ctx.mgl.buffer(bytes(4))
            table = ctx.mgl.buffer(bytes(8 * SMALL_SLOTS))
            try:
                prog = self._program(ctx, tunnel, 3)
                set_uniforms(prog, {"u_dims": (16, 16, 16), "u_count": len(triples),
                                    "u_budget": loop_budgets(ctx)[0]})
                bind(prog, Items=items, Table=table, Out=bad)
                dispatch_1d(ctx, prog, len(triples), _LOCAL)
                barrier(ctx)
                n_bad = int(np.frombuffer(bad.read(), dtype="<u4")[0])
            finally:
                items.release()
                bad.release()
            if n_bad:
                table.release()
                raise RuntimeError(f"scanline-ilv: {n_bad} entries of the small-triangle table "
                                   f"failed to build on {ctx.renderer}")
            cache[tunnel] = table
        return table

    def run(self, mesh, spec, *, ctx, timer, tunnel):
        n = mesh.n_triangles
        pool = buffer_pool(ctx, "scanline")
        main_budget, split_budget = loop_budgets(ctx)
        with timer.stage("setup", gpu=False):
            grid = pool.get("grid", spec.n_words * 4, what=f"the {spec.dims} bit grid")
            bufs = mesh_buffers(ctx, mesh)
            out = pool.get("overflow", 4 * (n + 2), what="the overflow list")
            prog = self._program(ctx, tunnel, 0)
            uniforms = {**grid_uniforms(spec, bufs.anchor), "u_count": n, "u_budget": main_budget}
            set_uniforms(prog, uniforms)
            ilv = self.mode == "ilv"
            if ilv:
                # built on first use by a pass of its own, so before this pass's bindings
                table = self.small_table(ctx, tunnel)
                scan = pool.get("scan", 16 + 4 * n, what="the list of triangles to scan", clear=False)
                clear_buffer(ctx, scan, 16)
                scan_prog = self._program(ctx, tunnel, 0, from_list=True)
                set_uniforms(scan_prog, uniforms)
                args_prog = compute_program(ctx, "scanline/scan_args.comp")
                set_uniforms(args_prog, {"u_local_size": _LOCAL,
                                         "u_max_groups": int(ctx.limits()["GL_MAX_COMPUTE_WORK_GROUP_COUNT"][0])})
        with timer.stage("voxelize"):
            # Items is never read in this pass, but a block the shader declares gets a buffer
            common = {"Vertices": bufs.vertices, "Faces": bufs.faces, "Grid": grid, "Out": out, "Items": out}
            bind(prog, **common, **({"Table": table, "Scan": scan} if ilv else {}))
            dispatch_1d(ctx, prog, n, _LOCAL)
            barrier(ctx)
            if ilv:  # the triangles the table does not hold, scanned in batches of their own
                bind(args_prog, Scan=scan)
                args_prog.run(1)
                barrier(ctx)
                bind(scan_prog, **common, Scan=scan)
                scan_prog.run_indirect(scan, offset=4)
                barrier(ctx)
        n_over, refused = (int(x) for x in np.frombuffer(out.read(size=8), dtype="<u4"))
        if refused:
            raise LimitError(
                f"scanline-ilv needs every vertex of a triangle that meets the grid within "
                f"{ILV_COORD_LIMIT} voxel indices of voxel 0 (int32 arithmetic); {refused} triangles "
                "are beyond it: use scanline-rlv / scanline-slv, or a grid closer to the mesh's extent"
            )
        parts = 0
        if n_over:
            ids = np.frombuffer(out.read(size=4 * (n_over + 2)), dtype="<u4")[2:].copy()
            with timer.stage("overflow"):
                parts = self._overflow(ctx, pool, spec, bufs, grid, tunnel, ids, split_budget)
        with timer.stage("readback", gpu=False):
            words = read_grid_words(ctx, grid, spec)
        timer.stats["overflow_triangles"] = n_over
        timer.stats["overflow_parts"] = parts
        if ilv:
            timer.stats["scanned_triangles"] = int(np.frombuffer(scan.read(size=4), dtype="<u4")[0])
        return VoxelGrid(words=words, spec=spec)

    def _overflow(self, ctx, pool, spec, bufs, grid, tunnel, ids, budget) -> int:
        """Measure the listed triangles, then redraw each in parts within the budget."""
        m = len(ids)
        items = np.zeros((m, 4), dtype=np.uint32)
        items[:, 0] = ids
        item_buf = pool.get("items", items.nbytes, what="the overflow items", clear=False)
        item_buf.write(items.tobytes())
        meas = pool.get("measure", 12 * m, what="the overflow measures")
        prog = self._program(ctx, tunnel, 1)
        base = {**grid_uniforms(spec, bufs.anchor), "u_budget": budget}
        set_uniforms(prog, {**base, "u_count": m})
        bind(prog, Vertices=bufs.vertices, Faces=bufs.faces, Grid=grid, Out=meas, Items=item_buf)
        dispatch_1d(ctx, prog, m, 1)
        barrier(ctx)
        res = np.frombuffer(meas.read(size=12 * m), dtype="<u4").reshape(m, 3).astype(np.int64)
        select, total, largest = res[:, 0], res[:, 1], res[:, 2]
        share = budget - select - largest
        bad = (select == 0xFFFFFFFF) | (share <= 0)
        if bad.any():
            t = int(ids[np.argmax(bad)])
            raise LimitError(
                f"triangle {t} needs more loop iterations than one invocation of this renderer may run "
                f"({LOOP_BUDGET}, {ctx.renderer}) even when its lines are split over several "
                f"invocations; use a smaller grid or a GPU"
            )
        nparts = np.maximum(1, -(-total // share))
        tri = np.repeat(ids, nparts)
        k = np.arange(int(nparts.sum())) - np.repeat(np.cumsum(nparts) - nparts, nparts)
        sh = np.repeat(share, nparts)
        items = np.zeros((len(tri), 4), dtype=np.uint32)
        items[:, 0] = tri
        items[:, 1] = k * sh
        items[:, 2] = np.minimum((k + 1) * sh, 0xFFFFFFFF)
        item_buf = pool.get("items", items.nbytes, what="the overflow items", clear=False)
        item_buf.write(items.tobytes())
        flag = pool.get("abort", 4, what="the abort counter")
        prog = self._program(ctx, tunnel, 2)
        set_uniforms(prog, {**base, "u_count": len(items)})
        bind(prog, Vertices=bufs.vertices, Faces=bufs.faces, Grid=grid, Out=flag, Items=item_buf)
        dispatch_1d(ctx, prog, len(items), 1)
        barrier(ctx)
        if int(np.frombuffer(flag.read(size=4), dtype="<u4")[0]):
            raise LimitError(f"an overflow part ran out of loop budget ({ctx.renderer}); "
                             "use a smaller grid or a GPU")
        return len(items)


def _info(mode: str, summary: str) -> MethodInfo:
    return MethodInfo(
        name=f"scanline-{mode}", kind="surface", pipeline="compute",
        paper=f"{_PAPER}, Sec. 4-5, Alg. 1 ({mode.upper()} line voxelization, Sec. 4.1)",
        summary=summary, reference="reference-conservative", exact=False,
        requires=_REQUIRES, options={"tunnel": _TUNNEL_OPTION},
    )


@register
class ScanlineRLV(_Scanline):
    mode = "rlv"
    info = _info("rlv", "projected optimal scanlines, Amanatides-Woo lines: 26-tunnel-free cover "
                        "(the conservative set up to voxels touched only at singular points)")


@register
class ScanlineSLV(_Scanline):
    mode = "slv"
    info = _info("slv", "projected optimal scanlines, super-cover lines: the conservative set")


@register
class ScanlineILV(_Scanline):
    mode = "ilv"
    info = _info("ilv", "projected optimal scanlines, integer-only lines and end selection (Eq. 8-9): "
                        "approximate cover, within a few percent of the conservative count")
