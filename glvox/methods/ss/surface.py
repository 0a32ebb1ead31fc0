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

from ...errors import LimitError
from ...gl.shaders import compute_program
from ...gpu.buffers import MAX_SLAB_VOXELS, buffer_pool, clear_buffer, read_grid_words, slab_reader, z_slabs
from ...gpu.sort import SHADERS as SORT_SHADERS, sort_pairs
from ...gpu.dispatch import LOOP_BUDGET, barrier, bind, dispatch_1d, grid_uniforms, set_uniforms
from ...gpu.transform import SHADERS as TRANSFORM_SHADERS, transform_vertices
from ...results.voxels import VoxelGrid
from ...tolerances import SLIVER_EPS
from ..base import Method, MethodInfo, Option, Requirements, register
from . import variant_store
from .chunks import BIG_ARGS, chunked_passes

_PAPER = "Schwarz & Seidel 2010"
LOCAL_SIZE = 64  # local_size_x of ss/surface.comp and ss/classify.comp

#: Work units (voxels or columns) per invocation.  A column costs at most six
#: loop iterations (itself and up to five voxels), so an invocation stays far
#: below LOOP_BUDGET; nearly every triangle is one chunk.
CHUNK = 4096
assert 6 * CHUNK < LOOP_BUDGET
VARIANTS = {"simple": 0, "specialized": 1, "sorted": 2}

#: Bits of a triangle's work in the sorted variant's keys (``ss/classify.comp``:
#: type, axis, then the work clamped to these bits).  12 hold the work of
#: nearly every triangle (more than 4095 units is a rare big one), and the
#: 16-bit keys take two radix passes where the former 26 bits (30-bit keys)
#: took four: the sorted variant's whole run took 0.87-0.98 of the time on
#: the bunny and the armadillo at 256^3-1024^3 (``glvox bench -m
#: ss-conservative --meshes stanford_bunny_bun_zipper.ply
#: stanford_armadillo_libigl_86k.obj -r 256 512 1024 --check-max 0 --against
#: b7fd10f --repeat 15``).
WORK_BITS = 12
#: The compute shaders the surface compiles (what a method reusing
#: :func:`surface_on_gpu` adds to its requirements).
COMPUTE = tuple((f"ss/{name}.comp", {}) for name in ("classify", "dispatch_args", "ranges", "surface")) \
    + (("ss/surface.comp", {"SS_FIRST": 1}), (BIG_ARGS, {})) + SORT_SHADERS + TRANSFORM_SHADERS
_REQUIRES = Requirements(gl_version=430, limits={"GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 7}, compute=COMPUTE)


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


#: How ``auto`` chose when no calibration of the renderer is stored (run statistics).
LLVMPIPE_RULE = f"llvmpipe rule: simple where F/N^2 >= {AUTO_SIMPLE_DENSITY}, else sorted"


def auto_variant(n_triangles: int, dims, max_groups: int, renderer: str | None = None) -> tuple[str, str]:
    """The variant ``auto`` runs and the rule that chose it.

    The choice ``glvox calibrate`` stored for ``renderer`` (the GL_RENDERER
    string; :mod:`~glvox.methods.ss.variant_store`) at the nearest density,
    else :func:`default_variant`, measured on llvmpipe; either way
    :data:`AUTO_FALLBACK` where ``sorted`` cannot dispatch every triangle.
    """
    choice = variant_store.lookup(renderer, n_triangles, dims) if renderer is not None else None
    variant, rule = (choice.variant, choice.rule()) if choice else (default_variant(n_triangles, dims), LLVMPIPE_RULE)
    if variant == "sorted" and n_triangles > max_groups * LOCAL_SIZE:
        return AUTO_FALLBACK, f"{rule}; {AUTO_FALLBACK}: too many triangles for sorted"
    return variant, rule


def surface_defines(criterion: int, variant: str) -> dict:
    """The defines of ``ss/classify.comp`` and ``ss/surface.comp``: the criterion, the
    variant, the chunk and the sliver bound (:data:`~glvox.tolerances.SLIVER_EPS`)."""
    return {"SS_CRITERION": criterion, "SS_VARIANT": VARIANTS[variant], "SS_CHUNK": CHUNK,
            "SS_SLIVER_EPS": SLIVER_EPS, "SS_WORK_BITS": WORK_BITS}


def surface_on_gpu(ctx, mesh, spec, timer, pool, *, variant: str, criterion: int = 0,
                   slabs: list[tuple[int, int]] | None = None, read_slab=None):
    """The S&S surface of ``mesh`` on ``spec`` in a GPU buffer, nothing read back.

    The building block of ``ss-conservative`` and ``ss-6sep`` (stages
    ``transform``, [``classify``, ``sort``, ``ranges``], ``voxelize``), for
    methods that go on working on the surface on the GPU (``carve-solid``).
    The simple and specialized variants set each triangle up once: the first
    of the two dispatches of ``voxelize`` counts its case and does its first
    chunk (:mod:`.chunks`).  The sorted variant, and every variant in slabs,
    run ``classify`` first: the sort needs every triangle's key, and the slabs
    the case counts of whole triangles, once.

    Parameters
    ----------
    ctx : GLContext
        Current context.
    mesh : Mesh
    spec : GridSpec
    timer : StageTimer
    pool : BufferPool
        The caller's pool; the surface uses its buffers ``grid``, ``stats``,
        ``args`` and ``big`` (simple, specialized) or ``per_triangle`` (and
        ``keys``, ``ranges`` when sorted).
    criterion : {0, 1}
        0 conservative (26-separating), 1 6-separating.
    variant : {'simple', 'specialized', 'sorted'}
    slabs : list of (k0, nk), optional
        The grid in z slabs (:func:`~glvox.gpu.buffers.z_slabs`): the transform, classify and sort
        run once, then each slab's voxelization (its voxels, voxel for voxel
        those of the whole grid) into the grid buffer, which holds one slab,
        and ``read_slab(k0, nk, grid)`` takes it before the next.

    Returns
    -------
    grid : moderngl.Buffer
        The packed surface (``common/voxel_space.glsl``'s layout, uint32
        (nz, ny, words_per_row) words; with ``slabs``, the last slab's), bits past
        nx zero.
    stats : moderngl.Buffer
        uint32[8]; the first three count the 1D/2D/3D cases (criterion 0), [7]
        the voxels set (of every slab).
    """
    n = mesh.n_triangles
    max_groups = int(ctx.limits()["GL_MAX_COMPUTE_WORK_GROUP_COUNT"][0])
    if variant == "sorted" and n > max_groups * LOCAL_SIZE:
        raise LimitError(
            f"the sorted variant dispatches each bounding-box type at once, at most "
            f"{max_groups * LOCAL_SIZE} triangles (GL_MAX_COMPUTE_WORK_GROUP_COUNT {max_groups} x "
            f"{LOCAL_SIZE}); this mesh has {n}: use variant 'specialized'"
        )
    # the grid first: a grid over the SSBO limit is refused before any other work
    slices = spec.dims[2] if slabs is None else max(nk for _, nk in slabs)
    grid = pool.get("grid", slices * spec.dims[1] * spec.words_per_row * 4, what=f"the {spec.dims} bit grid")
    bufs, vox = transform_vertices(ctx, mesh, spec, timer, pool)
    stats = pool.get("stats", 8 * 4)
    args = pool.get("args", 9 * 4, clear=False)
    defines = surface_defines(criterion, variant)
    common = {**grid_uniforms(spec, bufs.anchor), "u_triangles": n, "u_tri_offset": 0,
              "u_local_size": LOCAL_SIZE, "u_max_groups": max_groups}
    if variant != "sorted" and slabs is None:
        # one pass sets every triangle up, counts its case and does its first chunk
        big = pool.get("big", (n + 2) * 4, what="the triangles with several chunks", clear=False)
        clear_buffer(ctx, big, 8)
        first, rest = (compute_program(ctx, "ss/surface.comp", {**defines, "SS_FIRST": f}) for f in (1, 0))
        for prog in (first, rest):
            set_uniforms(prog, common)
        with timer.stage("voxelize"):
            chunked_passes(ctx, (first, rest), n, max_groups,
                           {"VoxVerts": vox, "Faces": bufs.faces, "Grid": grid, "Stats": stats}, big, args,
                           LOCAL_SIZE)
        return grid, stats
    per_tri = pool.get("per_triangle", n * 4, what="per-triangle work", clear=False)
    keys = None
    if variant == "sorted":
        keys = pool.get("keys", n * 4, what="sort keys", clear=False)
    classify = compute_program(ctx, "ss/classify.comp", defines)
    set_uniforms(classify, common)
    with timer.stage("classify"):
        bind(classify, VoxVerts=vox, Faces=bufs.faces, Stats=stats, TriChunks=per_tri)
        if keys is not None:
            bind(classify, Keys=keys)
        dispatch_1d(ctx, classify, n, LOCAL_SIZE)
        barrier(ctx)
    blocks = {"VoxVerts": vox, "Faces": bufs.faces, "Grid": grid, "Stats": stats}
    if variant != "sorted":
        blocks["TriChunks"] = per_tri
    else:
        blocks.update(SortedTris=per_tri, Ranges=sort_by_case(ctx, timer, pool, n, (stats, per_tri, keys, args),
                                                               max_groups))

    def voxelize(vdefines, vcommon):
        if variant != "sorted":
            voxelize_unsorted(ctx, timer, n, vdefines, vcommon, blocks, stats, args, max_groups)
        else:
            voxelize_sorted(ctx, timer, vdefines, vcommon, blocks, args)

    if slabs is None:
        voxelize(defines, common)
        return grid, stats
    # classify saw the whole grid (its case counts and chunks are the triangles');
    # each slab's voxelization visits its slices alone
    per_slice = spec.dims[1] * spec.words_per_row * 4
    for i, (k0, nk) in enumerate(slabs):
        if k0:
            clear_buffer(ctx, grid, nk * per_slice)
        voxelize({**defines, "VOX_SLAB": 1}, {**common, "u_slab": (k0, nk)})
        read_slab(k0, nk, grid)
        timer.slab_done(i + 1, len(slabs))
    return grid, stats


def voxelize_unsorted(ctx, timer, n, defines, common, blocks, stats, args, max_groups, stage: str = "voxelize"):
    """Stage ``voxelize`` (or ``stage``) of the simple and specialized variants: indirect
    dispatches over the triangles, at most GL_MAX_COMPUTE_WORK_GROUP_COUNT groups each
    (the attribute passes run them too, with ``SS_ATTR_PASS`` defined).  ``blocks``:
    ``ss/surface.comp``'s buffers by block name; ``stats`` and ``args``: the classify
    pass's counts and the indirect arguments."""
    dargs = compute_program(ctx, "ss/dispatch_args.comp")
    prog = compute_program(ctx, "ss/surface.comp", defines)
    set_uniforms(prog, common)
    batch = max_groups * LOCAL_SIZE  # triangles per dispatch along x
    with timer.stage(stage):
        for offset in range(0, n, batch):
            count = min(batch, n - offset)
            set_uniforms(dargs, {"u_sorted": False, "u_groups_x": -(-count // LOCAL_SIZE),
                                 "u_max_groups": max_groups, "u_local_size": LOCAL_SIZE})
            bind(dargs, Stats=stats, Args=args)
            dargs.run(1, 1, 1)
            barrier(ctx)
            set_uniforms(prog, {"u_tri_offset": offset})
            bind(prog, **blocks)
            prog.run_indirect(args)
            barrier(ctx)


def sort_by_case(ctx, timer, pool, n, buffers, max_groups, prefix: str = ""):
    """Stages ``sort`` and ``ranges`` of the sorted variant (``prefix`` before the
    names): triangles sorted by case, the indirect arguments of each type.  Returns
    the ranges buffer (``ss/surface.comp``'s block ``Ranges``)."""
    stats, per_tri, keys, args = buffers
    dargs = compute_program(ctx, "ss/dispatch_args.comp")
    ranges = pool.get("ranges", 8 * 4)
    with timer.stage(f"{prefix}sort"):
        sort_pairs(ctx, keys, per_tri, n, key_bits=WORK_BITS + 4)
        barrier(ctx)
    rng = compute_program(ctx, "ss/ranges.comp", {"SS_WORK_BITS": WORK_BITS})
    set_uniforms(rng, {"u_count": n})
    set_uniforms(dargs, {"u_sorted": True, "u_local_size": LOCAL_SIZE, "u_max_groups": max_groups})
    with timer.stage(f"{prefix}ranges"):
        bind(rng, Keys=keys, Ranges=ranges)
        dispatch_1d(ctx, rng, n, 256)
        barrier(ctx)
        bind(dargs, Stats=stats, Ranges=ranges, Args=args)
        dargs.run(1, 1, 1)
        barrier(ctx)
    return ranges


def voxelize_sorted(ctx, timer, defines, common, blocks, args, stage: str = "voxelize") -> None:
    """Stage ``voxelize`` (or ``stage``) of the sorted variant, after :func:`sort_by_case`:
    one indirect dispatch per bounding-box type (the attribute passes run it too).
    ``blocks``: ``ss/surface.comp``'s buffers by block name; ``args``: the indirect
    arguments."""
    with timer.stage(stage):
        for bbox_type in range(3):
            prog = compute_program(ctx, "ss/surface.comp", {**defines, "SS_BBOX_TYPE": bbox_type})
            set_uniforms(prog, common)
            bind(prog, **blocks)
            prog.run_indirect(args, offset=12 * bbox_type)
        barrier(ctx)


class _SSSurface(Method):
    criterion = 0

    def _run(self, ctx, mesh, spec, timer, variant: str):
        pool = buffer_pool(ctx, self.info.name)
        slabs = z_slabs(ctx, spec)
        if slabs is None:
            grid, stats = surface_on_gpu(ctx, mesh, spec, timer, pool, criterion=self.criterion, variant=variant)
            if variant != "sorted":  # the triangles the first pass listed (.chunks)
                listed, most = np.frombuffer(pool.get("big", 8, clear=False).read(size=8), dtype="<u4")
                timer.stats["triangles_with_several_chunks"] = int(listed)
                timer.stats["max_chunks"] = int(most) + 1 if listed else 1
            return self._finish(ctx, spec, timer, grid, stats)
        # over the storage-block limit: slab by slab, each read into its part of the result
        words, read_slab = slab_reader(ctx, spec, timer)
        grid, stats = surface_on_gpu(ctx, mesh, spec, timer, pool, criterion=self.criterion, variant=variant,
                                     slabs=slabs, read_slab=read_slab)
        timer.stats["slabs"] = len(slabs)
        timer.merge_repeats()
        return self._finish_counts(spec, timer, words, stats)

    def _case_stats(self, timer, cases) -> None:
        if self.criterion == 0:
            total = int(cases.sum())
            timer.stats["cases_1d_2d_3d"] = [int(c) for c in cases]
            timer.stats["case_percent_1d_2d_3d"] = [round(100.0 * int(c) / total, 1) if total else 0.0
                                                    for c in cases]

    def _finish(self, ctx, spec, timer, grid, stats):
        with timer.stage("readback", gpu=False):
            words = read_grid_words(ctx, grid, spec)
        return self._finish_counts(spec, timer, words, stats)

    def _finish_counts(self, spec, timer, words, stats):
        stat_words = np.frombuffer(stats.read(size=32), dtype="<u4")
        # ss/write.glsl counts the voxels in a uint32: not where a grid has 2^32 or more
        voxels = int(stat_words[7]) if spec.n_voxels < 2**32 else None
        self._case_stats(timer, stat_words[:3])
        return VoxelGrid(words=words, spec=spec, count=voxels)  # None: popcounted on the host when asked


@register
class SSConservative(_SSSurface):
    info = MethodInfo(
        name="ss-conservative", kind="surface", pipeline="compute",
        paper=f"{_PAPER}, Sec. 3.1-3.2 and 6 (triangle-parallel conservative voxelization)",
        summary="conservative (26-separating) surface, one compute invocation per triangle, atomicOr",
        reference="reference-conservative",
        requires=_REQUIRES, max_voxels=MAX_SLAB_VOXELS,
        options={"variant": Option("auto", "Table 1's realization; auto: the fastest on this GPU where "
                                           "`glvox calibrate` measured it (stored per renderer in "
                                           "~/.cache/glvox/ss_variants.json), else simple where triangles / "
                                           f"N^2 >= {AUTO_SIMPLE_DENSITY}, else sorted (measured on llvmpipe, "
                                           "compare/ss_variants.py); run stats 'variant_rule' say which",
                                   ("auto", *VARIANTS))},
    )
    criterion = 0

    def run(self, mesh, spec, *, ctx, timer, variant):
        if variant == "auto":
            max_groups = int(ctx.limits()["GL_MAX_COMPUTE_WORK_GROUP_COUNT"][0])
            variant, timer.stats["variant_rule"] = auto_variant(mesh.n_triangles, spec.dims, max_groups,
                                                                ctx.renderer)
            timer.stats["variant"] = variant
        return self._run(ctx, mesh, spec, timer, variant)


@register
class SS6Sep(_SSSurface):
    info = MethodInfo(
        name="ss-6sep", kind="surface", pipeline="compute",
        paper=f"{_PAPER}, Sec. 3.4 (6-separating surface voxelization, dominant-axis columns)",
        summary="6-separating (thin) surface, one compute invocation per triangle, atomicOr",
        reference="reference-6sep",
        requires=_REQUIRES, max_voxels=MAX_SLAB_VOXELS,
    )
    criterion = 1

    def run(self, mesh, spec, *, ctx, timer):
        return self._run(ctx, mesh, spec, timer, "specialized")
