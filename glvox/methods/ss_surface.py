"""Schwarz & Seidel 2010 surface voxelization in compute shaders (Sec. 3.1-3.4, 6).

``ss-conservative`` sets every voxel a triangle overlaps or touches; three
variants, as in the paper's Table 1:

* ``simple``: one invocation per triangle tests every voxel of its bounding box;
* ``specialized``: the nine 1D/2D/3D bounding-box cases, dominant-axis voxel
  columns with the range from the plane, the two remaining 2D tests only, and
  the shortcuts for one-voxel-thick ranges and boxes;
* ``sorted``: a first pass writes case and work per triangle, a GLSL radix
  sort orders them, and one indirect dispatch per bounding-box type follows.

``ss-6sep`` is the 6-separating criterion (Sec. 3.4) with the dominant-axis
columns.  All variants write the bit-packed grid of ``common/voxel_space.glsl``
with ``atomicOr`` through a small register buffer of words.

Pipeline (all on the GPU; only the grid and three case counters are read back):
``transform`` (vertices to voxel space), ``classify`` (case and work of each
triangle), [``sort``, ``ranges`` for the sorted variant], ``voxelize``
(indirect dispatches sized on the GPU), ``readback``.  A triangle's work is
split into chunks of :data:`CHUNK` voxels or columns, one invocation each, so
no invocation exceeds the loop budget of Mesa's llvmpipe (see
:data:`glvox.gpu.dispatch.LOOP_BUDGET`).
"""

from __future__ import annotations

import numpy as np

from ..errors import LimitError
from ..gl.shaders import compute_program
from ..gpu.buffers import buffer_pool, read_grid_words
from ..gpu.sort import sort_pairs
from ..gpu.dispatch import LOOP_BUDGET, barrier, dispatch_1d, grid_uniforms, set_uniforms
from ..gpu.transform import transform_vertices
from ..results.voxels import VoxelGrid
from ..tolerances import SLIVER_EPS
from .base import Method, MethodInfo, Option, Requirements, register

_PAPER = "Schwarz & Seidel 2010"
_LOCAL = 64  # local_size_x of ss/surface.comp and ss/classify.comp

#: Work units (voxels or columns) per invocation.  A column costs at most six
#: loop iterations (itself and up to five voxels), so an invocation stays far
#: below LOOP_BUDGET; nearly every triangle is one chunk.
CHUNK = 4096
assert 6 * CHUNK < LOOP_BUDGET
_VARIANTS = {"simple": 0, "specialized": 1, "sorted": 2}
_REQUIRES = Requirements(gl_version=430, limits={"GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 7,
                                                 "GL_MAX_COMPUTE_WORK_GROUP_SIZE": 256})

#: ``ss-conservative``'s variant ``auto`` (the default) runs ``simple`` where a
#: grid face has at most 1 / AUTO_SIMPLE_DENSITY voxels per triangle
#: (F / N^2 >= AUTO_SIMPLE_DENSITY, N^2 = the geometric mean of the grid's
#: face areas), ``sorted`` below.  Measured with compare/ss_variants.py on
#: five shared meshes (3.5k to 203k triangles) at 64^3-1024^3, twice: simple
#: led in 12 and 13 of the 13 cells with F / N^2 >= 0.77; below, sorted and
#: specialized traded the lead within ~25% from run to run.  The rule's
#: summed time was within 3% and 9% of always picking the fastest variant
#: (worst cell 1.31x), where specialized, the former default, was 26% and 15%
#: over (worst cell 3.8x: many voxels per triangle), simple 87% and 59%,
#: sorted 11% and 22%.  Figures in README "Methods".
AUTO_SIMPLE_DENSITY = 0.5

#: The variant ``auto`` takes when ``sorted`` cannot run (more triangles than
#: one indirect dispatch holds).
AUTO_FALLBACK = "specialized"


def default_variant(n_triangles: int, dims) -> str:
    """The variant ``auto`` picks for ``n_triangles`` on a grid of ``dims`` (see :data:`AUTO_SIMPLE_DENSITY`)."""
    # F / V^(2/3) >= d  <=>  (F / d)^3 >= V^2: exact in floats for every grid glvox takes
    volume = float(np.prod(np.asarray(dims, dtype=np.float64)))
    return "simple" if (n_triangles / AUTO_SIMPLE_DENSITY) ** 3 >= volume * volume else "sorted"


def _auto(n_triangles: int, dims, max_groups: int) -> str:
    """:func:`default_variant`, or :data:`AUTO_FALLBACK` where ``sorted`` cannot dispatch every triangle."""
    variant = default_variant(n_triangles, dims)
    return AUTO_FALLBACK if variant == "sorted" and n_triangles > max_groups * _LOCAL else variant


class _SSSurface(Method):
    criterion = 0

    def _run(self, ctx, mesh, spec, timer, variant: str):
        n = mesh.n_triangles
        max_groups = int(ctx.limits()["GL_MAX_COMPUTE_WORK_GROUP_COUNT"][0])
        if variant == "sorted" and n > max_groups * _LOCAL:
            raise LimitError(
                f"the sorted variant dispatches each bounding-box type at once, at most "
                f"{max_groups * _LOCAL} triangles (GL_MAX_COMPUTE_WORK_GROUP_COUNT {max_groups} x "
                f"{_LOCAL}); this mesh has {n}: use variant 'specialized'"
            )
        pool = buffer_pool(ctx, self.info.name)
        # the grid first: a grid over the SSBO limit is refused before any other work
        grid = pool.get("grid", spec.n_words * 4, what=f"the {spec.dims} bit grid")
        bufs, vox = transform_vertices(ctx, mesh, spec, timer, pool)
        stats = pool.get("stats", 8 * 4)
        per_tri = pool.get("per_triangle", n * 4, what="per-triangle work", clear=False)
        args = pool.get("args", 9 * 4, clear=False)
        defines = {"SS_CRITERION": self.criterion, "SS_VARIANT": _VARIANTS[variant], "SS_CHUNK": CHUNK,
                   "SS_SLIVER_EPS": SLIVER_EPS}
        common = {**grid_uniforms(spec, bufs.anchor), "u_triangles": n, "u_tri_offset": 0,
                  "u_local_size": _LOCAL, "u_max_groups": max_groups}
        vox.bind_to_storage_buffer(1)
        bufs.faces.bind_to_storage_buffer(2)
        grid.bind_to_storage_buffer(3)
        stats.bind_to_storage_buffer(4)
        per_tri.bind_to_storage_buffer(5)
        args.bind_to_storage_buffer(8)
        keys = None
        if variant == "sorted":
            keys = pool.get("keys", n * 4, what="sort keys", clear=False)
            keys.bind_to_storage_buffer(7)
        classify = compute_program(ctx, "ss/classify.comp", defines)
        set_uniforms(classify, common)
        with timer.stage("classify"):
            dispatch_1d(ctx, classify, n, _LOCAL)
            barrier(ctx)
        dargs = compute_program(ctx, "ss/dispatch_args.comp")
        if variant != "sorted":
            prog = compute_program(ctx, "ss/surface.comp", defines)
            set_uniforms(prog, common)
            batch = max_groups * _LOCAL  # triangles per dispatch along x
            with timer.stage("voxelize"):
                for offset in range(0, n, batch):
                    count = min(batch, n - offset)
                    set_uniforms(dargs, {"u_sorted": False, "u_groups_x": -(-count // _LOCAL),
                                         "u_max_groups": max_groups, "u_local_size": _LOCAL})
                    dargs.run(1, 1, 1)
                    barrier(ctx)
                    set_uniforms(prog, {"u_tri_offset": offset})
                    prog.run_indirect(args)
                    barrier(ctx)
            return self._finish(spec, timer, grid, stats)
        ranges = pool.get("ranges", 8 * 4)
        ranges.bind_to_storage_buffer(6)
        with timer.stage("sort"):
            sort_pairs(ctx, keys, per_tri, n, key_bits=30)
            barrier(ctx)
        rng = compute_program(ctx, "ss/ranges.comp")
        set_uniforms(rng, {"u_count": n})
        set_uniforms(dargs, {"u_sorted": True, "u_local_size": _LOCAL, "u_max_groups": max_groups})
        with timer.stage("ranges"):
            # the sort may have bound its own buffers: bind ours again
            keys.bind_to_storage_buffer(7)
            ranges.bind_to_storage_buffer(6)
            stats.bind_to_storage_buffer(4)
            args.bind_to_storage_buffer(8)
            dispatch_1d(ctx, rng, n, 256)
            barrier(ctx)
            dargs.run(1, 1, 1)
            barrier(ctx)
        with timer.stage("voxelize"):
            vox.bind_to_storage_buffer(1)
            bufs.faces.bind_to_storage_buffer(2)
            grid.bind_to_storage_buffer(3)
            per_tri.bind_to_storage_buffer(5)
            for bbox_type in range(3):
                prog = compute_program(ctx, "ss/surface.comp", {**defines, "SS_BBOX_TYPE": bbox_type})
                set_uniforms(prog, common)
                prog.run_indirect(args, offset=12 * bbox_type)
            barrier(ctx)
        return self._finish(spec, timer, grid, stats)

    def _finish(self, spec, timer, grid, stats):
        with timer.stage("readback", gpu=False):
            words = read_grid_words(grid, spec)
            stat_words = np.frombuffer(stats.read(size=32), dtype="<u4")
        cases, voxels = stat_words[:3], int(stat_words[7])  # ss/write.glsl counts the voxels
        if self.criterion == 0:
            total = int(cases.sum())
            timer.stats["cases_1d_2d_3d"] = [int(c) for c in cases]
            timer.stats["case_percent_1d_2d_3d"] = [round(100.0 * int(c) / total, 1) if total else 0.0
                                                    for c in cases]
        return VoxelGrid(words=words, spec=spec, count=voxels)


@register
class SSConservative(_SSSurface):
    info = MethodInfo(
        name="ss-conservative", kind="surface", family="compute",
        paper=f"{_PAPER}, Sec. 3.1-3.2 and 6 (triangle-parallel conservative voxelization)",
        summary="conservative (26-separating) surface, one compute invocation per triangle, atomicOr",
        reference="reference-conservative",
        requires=_REQUIRES,
        options={"variant": Option("auto", "Table 1's realization; auto: simple where triangles / N^2 >= "
                                           f"{AUTO_SIMPLE_DENSITY}, else sorted (measured, "
                                           "compare/ss_variants.py)", ("auto", *_VARIANTS))},
    )
    criterion = 0

    def run(self, mesh, spec, *, ctx, timer, variant):
        if variant == "auto":
            max_groups = int(ctx.limits()["GL_MAX_COMPUTE_WORK_GROUP_COUNT"][0])
            variant = timer.stats["variant"] = _auto(mesh.n_triangles, spec.dims, max_groups)
        return self._run(ctx, mesh, spec, timer, variant)


@register
class SS6Sep(_SSSurface):
    info = MethodInfo(
        name="ss-6sep", kind="surface", family="compute",
        paper=f"{_PAPER}, Sec. 3.4 (6-separating surface voxelization, dominant-axis columns)",
        summary="6-separating (thin) surface, one compute invocation per triangle, atomicOr",
        reference="reference-6sep",
        requires=_REQUIRES,
    )
    criterion = 1

    def run(self, mesh, spec, *, ctx, timer):
        return self._run(ctx, mesh, spec, timer, "specialized")
