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
``transform`` (vertices to voxel space), then ``voxelize`` (or ``classify``,
``sort``, ``ranges``, ``voxelize``), then ``readback``.
"""

from __future__ import annotations

import numpy as np

from ..grid import VoxelGrid
from ..shaders import compute_program
from ._base import Method, MethodInfo, Option, Requirements, register
from ._gpu import (barrier, buffer_pool, dispatch_1d, grid_uniforms, mesh_buffers, read_grid_words,
                   set_uniforms)

_PAPER = "Schwarz & Seidel 2010"
_LOCAL = 64  # local_size_x of ss/surface.comp and ss/classify.comp
_VARIANTS = {"simple": 0, "specialized": 1, "sorted": 2}
_REQUIRES = Requirements(gl_version=430, limits={"GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 7,
                                                 "GL_MAX_COMPUTE_WORK_GROUP_SIZE": 256})

#: The default conservative variant: the fastest measured here (see README, "Methods").
DEFAULT_VARIANT = "specialized"


class _SSSurface(Method):
    criterion = 0

    def _transform(self, ctx, mesh, spec, timer, pool):
        bufs = mesh_buffers(ctx, mesh)
        vox = pool.get("vox_vertices", bufs.n_vertices * 12, what="voxel-space vertices", clear=False)
        prog = compute_program(ctx, "ss/transform.comp")
        set_uniforms(prog, {**grid_uniforms(spec, bufs.anchor), "u_vertices": bufs.n_vertices})
        with timer.stage("transform"):
            bufs.vertices.bind_to_storage_buffer(0)
            vox.bind_to_storage_buffer(1)
            dispatch_1d(ctx, prog, bufs.n_vertices, 256)
            barrier(ctx)
        return bufs, vox

    def _finish(self, ctx, spec, timer, grid, stats):
        with timer.stage("readback", gpu=False):
            words = read_grid_words(grid, spec)
            cases = np.frombuffer(stats.read(size=12), dtype="<u4")
        if self.criterion == 0:
            total = int(cases.sum())
            timer.stats["cases_1d_2d_3d"] = [int(c) for c in cases]
            timer.stats["case_percent_1d_2d_3d"] = [round(100.0 * int(c) / total, 1) if total else 0.0
                                                    for c in cases]
        return VoxelGrid(words=words, spec=spec)

    def _run(self, ctx, mesh, spec, timer, variant: str):
        pool = buffer_pool(ctx, self.info.name)
        # the grid first: a grid over the SSBO limit is refused before any other work
        grid = pool.get("grid", spec.n_words * 4, what=f"the {spec.dims} bit grid")
        bufs, vox = self._transform(ctx, mesh, spec, timer, pool)
        stats = pool.get("stats", 16)
        n = bufs.n_triangles
        common = {**grid_uniforms(spec, bufs.anchor), "u_triangles": n}
        defines = {"SS_CRITERION": self.criterion, "SS_VARIANT": _VARIANTS[variant]}
        if variant != "sorted":
            prog = compute_program(ctx, "ss/surface.comp", defines)
            set_uniforms(prog, common)
            with timer.stage("voxelize"):
                vox.bind_to_storage_buffer(1)
                bufs.faces.bind_to_storage_buffer(2)
                grid.bind_to_storage_buffer(3)
                stats.bind_to_storage_buffer(4)
                dispatch_1d(ctx, prog, n, _LOCAL)
                barrier(ctx)
            return self._finish(ctx, spec, timer, grid, stats)
        return self._run_sorted(ctx, spec, timer, pool, bufs, vox, grid, stats, common)

    def _run_sorted(self, ctx, spec, timer, pool, bufs, vox, grid, stats, common):
        from ..gpu_sort import sort_pairs

        n = bufs.n_triangles
        keys = pool.get("keys", n * 4, what="sort keys", clear=False)
        values = pool.get("values", n * 4, what="sort values", clear=False)
        ranges = pool.get("ranges", 8 * 4)
        args = pool.get("args", 9 * 4, clear=False)
        classify = compute_program(ctx, "ss/classify.comp")
        set_uniforms(classify, common)
        with timer.stage("classify"):
            vox.bind_to_storage_buffer(1)
            bufs.faces.bind_to_storage_buffer(2)
            keys.bind_to_storage_buffer(3)
            stats.bind_to_storage_buffer(4)
            values.bind_to_storage_buffer(5)
            dispatch_1d(ctx, classify, n, _LOCAL)
            barrier(ctx)
        with timer.stage("sort"):
            sort_pairs(ctx, keys, values, n, key_bits=30)
            barrier(ctx)
        rng = compute_program(ctx, "ss/ranges.comp")
        set_uniforms(rng, {"u_count": n})
        dargs = compute_program(ctx, "ss/dispatch_args.comp")
        set_uniforms(dargs, {"u_local_size": _LOCAL,
                             "u_max_groups": int(ctx.limits()["GL_MAX_COMPUTE_WORK_GROUP_COUNT"][0])})
        with timer.stage("ranges"):
            keys.bind_to_storage_buffer(0)
            ranges.bind_to_storage_buffer(1)
            dispatch_1d(ctx, rng, n, 256)
            barrier(ctx)
            args.bind_to_storage_buffer(2)
            dargs.run(1, 1, 1)
            barrier(ctx)
        with timer.stage("voxelize"):
            vox.bind_to_storage_buffer(1)
            bufs.faces.bind_to_storage_buffer(2)
            grid.bind_to_storage_buffer(3)
            values.bind_to_storage_buffer(5)
            ranges.bind_to_storage_buffer(6)
            for bbox_type in range(3):
                prog = compute_program(ctx, "ss/surface.comp",
                                       {"SS_CRITERION": 0, "SS_VARIANT": 2, "SS_BBOX_TYPE": bbox_type})
                set_uniforms(prog, common)
                prog.run_indirect(args, offset=12 * bbox_type)
            barrier(ctx)
        return self._finish(ctx, spec, timer, grid, stats)

    def release(self, ctx) -> None:
        buffer_pool(ctx, self.info.name).release()


@register
class SSConservative(_SSSurface):
    info = MethodInfo(
        name="ss-conservative", kind="surface", family="compute",
        paper=f"{_PAPER}, Sec. 3.1-3.2 and 6 (triangle-parallel conservative voxelization)",
        summary="conservative (26-separating) surface, one compute invocation per triangle, atomicOr",
        reference="reference-conservative",
        requires=_REQUIRES,
        options={"variant": Option(DEFAULT_VARIANT, "Table 1's realization", tuple(_VARIANTS))},
    )
    criterion = 0

    def run(self, mesh, spec, *, ctx, timer, variant):
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
