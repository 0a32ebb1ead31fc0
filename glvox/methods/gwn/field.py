"""``gwn-solid``: generalized winding numbers in compute shaders, for any mesh.

A voxel is set when the generalized winding number at its center (Jacobson
et al. 2013) is at least ``threshold``.  The number is ``w = C + F``
(:mod:`glvox.reference.winding` derives it and is its exact reference,
``reference-gwn``):

* ``crossings`` (``shaders/gwn/events.comp``): every triangle adds
  ``-sign(n_x)`` at the first voxel of each row its (y, z) projection covers,
  decided by ss-solid's arithmetic (``ss/solid.glsl``), counted in
  :data:`PLANES` bit planes per sign (4 bits a voxel, not an int);
* ``rows`` (``gwn/rows.comp``): prefix sums along each row give ``C``; when
  every half-edge cancels (closed meshes, also nested, overlapping or
  inside-out ones) ``F = 0`` and this pass writes the bits, word by word;
* ``bricks`` (``gwn/bricks.comp``; without ``winding``): per brick of
  :data:`BRICK`^3 voxels, ``F`` at its center from the tree, that value's
  error bound and a bound of ``|grad F|`` over the brick (the Biot-Savart
  integral over the boundary chain, valid where no boundary strip reaches the
  brick); ``rows`` then decides every voxel whose ``C + F(center)`` is
  farther from ``threshold`` than those bounds allow, and lists the row
  segments with blocks of 4 voxels left;
* ``caps`` (:mod:`.caps`; with bricks, off an integer threshold): a fan over
  every boundary loop closes the mesh, and its crossings are counted too; a
  brick where the fans' ``|w_K|`` is bounded below the threshold's distance
  to the integers is decided by ``C + C_K`` alone (``w = C + C_K - w_K``),
  and neither walks the tree nor bounds ``F``;
* ``far`` (``gwn/field.comp``): ``F``, the strips of the boundary chain,
  from its cluster tree (:mod:`.tree`): far clusters by a second-order
  expansion, near ones by exact strips.  The expansion has a proven error
  bound; where ``|C + F - threshold|`` does not exceed it (plus
  :data:`~glvox.tolerances.WINDING_TIE`), the block of 4 voxels is left
  undecided and its row segment listed with a mask of such blocks (with
  bricks, only over the segments and blocks ``rows`` left);
* ``refine`` (``gwn/refine.comp``): the listed blocks get the exact sum over
  every boundary edge.

The bound is proven, hence pessimistic (25 to 60 times the error measured on
random polygons): on meshes with a short boundary chain a few percent of the
blocks are refined, but a soup of many small open triangles (every triangle
a loop, clusters of loops with a large unsigned area) has most of its
blocks refined, at the cost of the direct sum over its boundary edges.

So the voxels equal ``reference-gwn``'s up to ties whatever the accuracy
``beta``: it trades expansion work for refinement work and sets the
accuracy of the returned field (``winding=true``), which is the expansion's
where a segment was decided.  Grids larger than a storage block run in
slabs of z slices; the tree's work is split in chunks of subtrees and the
refinement's in chunks of edges, so no invocation exceeds llvmpipe's loop
budget.
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import LimitError, MethodError
from ...gl.shaders import compute_program
from ...grid import MAX_VOXELS
from ...gpu.buffers import (MAX_SLAB_VOXELS, buffer_pool, clear_buffer, read_grid_words, slab_reader,
                             z_slabs)
from ...gpu.dispatch import LOOP_BUDGET, barrier, bind, dispatch_1d, grid_uniforms, set_uniforms
from ...gpu.fixed_point import fixed_bits
from ...gpu.transform import transform_vertices
from ...results.voxels import VoxelGrid
from ...tolerances import WINDING_TIE
from ..base import Method, MethodInfo, Option, Requirements, register
from .caps import RunCaps, cap_margin, cap_records, capped_mesh
from .plan import (BRICK, EDGE_COST, PLANES, SEGV, SUPER, carry_flags, plan_chunks, slab_slices, strip_free_share,
                   super_sizes, x_range)
from .shell import add_shell
from .tree import NODE_VEC4, boundary_loops, boundary_voxels, mesh_tree, tree_on_grid
from ..ss.chunks import chunked_passes
from ..ss.solid import COMPUTE as SOLID_COMPUTE, COLUMN_CHUNK, mesh_rows
from ..ss.surface import COMPUTE as SURFACE_COMPUTE

_LOCAL = 64  # local_size_x of the gwn shaders
_REQUIRES = Requirements(gl_version=430, extensions=("GL_ARB_gpu_shader_fp64",),
                         # the row pass with bricks and caps binds the most blocks (13, bindings
                         # 0-12), read from its source
                         compute=(("gwn/*.comp", {}),
                                  ("gwn/rows.comp", {"EDGES": 1, "BRICKS": 1, "CAPS": 1, "PLANES": 1,
                                                     "CARRY_FLAGS": 1}),
                                  ("gwn/bricks.comp", {"CAPS": 1, "GWN_GRAD": 1, "GWN_SUPER": 0}),
                                  ("gwn/bricks.comp", {"CAPS": 1, "GWN_GRAD": 0, "GWN_SUPER": SUPER,
                                                       "GWN_SUPER_AFTER": 1}))
                         + SOLID_COMPUTE + SURFACE_COMPUTE)

#: Segments one invocation of gwn/todo.comp lists (as many as a work group of
#: the field pass takes, so that the list keeps their order as a work group's
#: prefix sum did, without its barriers).
TODO_RUN = _LOCAL

#: Boundary edges per refinement dispatch.
REFINE_EDGES = (LOOP_BUDGET // 2 - 4 * SEGV) // EDGE_COST

#: The field pass's stack (``GWN_STACK`` in gwn/field.comp): trees deeper than
#: this - 1 are refused (the loop grouping is balanced by edge count, so the
#: depth grows as log2 of the boundary edges: 12 for the 1,280 of the tower).
TREE_STACK = 64

#: Bricks run only when at least this share of the brick columns the field
#: is evaluated over is free of boundary strips (:func:`strip_free_share`):
#: elsewhere nearly every segment is left to the tree walk anyway and the extra
#: passes cost 5-18% (llvmpipe, `glvox bench -m gwn-solid --against` the
#: previous head: the gyroid at 64^3 and 128^3, shares 0.25 and 0.49; the
#: wall with a hole at 64^3, 0.43; the soup, 0.0).  At 0.52-0.97 (the bunny,
#: the teapot, the tower, the wall at 128^3, the gyroid at 256^3) bricks made
#: the call 1.3-5x faster.
BRICKS_MIN_FREE = 0.5

#: Boundary edges up to which gwn/bricks.comp gives the bricks it cannot leave
#: to the caps a first-order record (the gradient of F at the brick's center
#: and a bound of its second derivative, summed over every boundary edge: one
#: loop of this many iterations per such brick, within the loop budget beside
#: the tree walk's half of it).
GRAD_EDGES = 4096

#: Nor below this many voxels in the part the field is evaluated over (the
#: mesh's rows times its x segments), where their three extra passes cost
#: what they save.  Measured with the walk alone and with bricks alternating
#: run by run in one process (llvmpipe, 2 cores, best of 6): from 2.2e5
#: voxels on they paid on the bunny, the teapot, the tower and the wall with
#: a hole (0.72-0.97 at 80^3 and 96^3; the teapot 0.65 at 128^3, the bunny
#: 0.87-0.93 at 64^3), at 1.9e5 they were level (the wall at 64^3, 0.96-1.00),
#: and below they lost (the tower 1.04, the teapot 1.10 at 64^3).
BRICKS_MIN_VOXELS = 200_000

#: Fan triangles (boundary edges) up to which the caps are used: each brick
#: near a fan sums a bound over its triangles (within the loop budget beside
#: the tree walk's half of it), and a soup, a loop per triangle, gains nothing.
CAP_MAX = 4096

#: The caps decide a voxel only where the threshold lies at least this far
#: from every integer (after the tie tolerance): near an integer threshold
#: ``|w_K|`` would have to be bounded below it almost everywhere.
CAP_MIN_MARGIN = 0.05


@register
class GwnSolid(Method):
    info = MethodInfo(
        name="gwn-solid", kind="solid", pipeline="compute",
        paper="Jacobson et al. 2013 (generalized winding number >= 1/2 at voxel centers), as signed "
              "crossings plus the boundary chain's strips, far clusters expanded to second order "
              "(after Barill et al. 2018) with a proven bound, undecided voxels refined exactly",
        summary="robust solid for any mesh (open, self-intersecting, soups): w >= threshold at centers",
        reference="reference-gwn", any_mesh=True,
        requires=_REQUIRES, max_voxels=MAX_SLAB_VOXELS,
        options={
            "threshold": Option(0.5, "inside when w >= threshold (w: 1 inside a closed shell)"),
            "accuracy": Option(2.0, "beta: a cluster is expanded from beta times its radius on (> 1); "
                                    "trades expansion for refinement work, sets the field's accuracy"),
            "shell": Option(False, "also set every voxel of the conservative surface (thin parts never vanish)"),
            "winding": Option(False, "also return w as fields['winding'] (float32, (nx, ny, nz))"),
        },
    )

    def release(self, ctx) -> None:
        buffer_pool(ctx, self.info.name).release()
        buffer_pool(ctx, self.info.name + ":shell").release()

    def run(self, mesh, spec, *, ctx, timer, threshold, accuracy, shell, winding):
        if not (math.isfinite(accuracy) and accuracy > 1.0):
            raise MethodError(f"option accuracy (beta) must be a finite number > 1, got {accuracy!r}")
        if not math.isfinite(threshold):
            raise MethodError(f"option threshold must be a finite number, got {threshold!r}")
        fix_bits = fixed_bits(mesh, spec, 0)  # refuses a mesh out of the crossings' range before any work
        pool = buffer_pool(ctx, self.info.name)
        if winding and spec.n_voxels > MAX_VOXELS:
            raise LimitError(f"winding=true returns a dense float32 field, and {spec.dims} has {spec.n_voxels} "
                             f"voxels, more than the {MAX_VOXELS} kept dense; use a smaller grid")
        # a packed grid over the storage-block limit is streamed: the bits of one slab
        # of z slices at a time, each read into its part of the result
        stream = z_slabs(ctx, spec)
        if stream is not None and (shell or winding):
            what = "shell" if shell else "winding"
            limit = ctx.limits()["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"]
            raise LimitError(f"gwn-solid streams the {spec.dims} grid in z slabs (its bit grid is over "
                             f"GL_MAX_SHADER_STORAGE_BLOCK_SIZE {limit} of this context), and {what}=true needs "
                             f"the whole grid at once; use a smaller grid or leave {what} off")
        if stream is None:
            bits = pool.get("bits", spec.n_words * 4, what=f"the {spec.dims} bit grid")
            words = read_slab = None
        else:
            bits = pool.get("bits", max(nk for _, nk in stream) * spec.dims[1] * spec.words_per_row * 4,
                            what=f"one z slab of the {spec.dims} bit grid")
            words, read_slab = slab_reader(ctx, spec, timer)
        with timer.stage("tree", gpu=False):
            loops = boundary_loops(mesh)
            # the fans over the loops (.caps), appended to the mesh the GPU reads;
            # not with winding=true, where every voxel's field is computed anyway
            capped = capped_mesh(mesh, loops) if loops.n_edges and not winding else None
            vox64 = (boundary_voxels(spec, (capped.mesh if capped else mesh).vertices, loops, len(mesh.vertices))
                     if loops.n_edges else None)
            tree = tree_on_grid(mesh_tree(mesh, loops), spec) if loops.n_edges else None
        bufs, vox = transform_vertices(ctx, capped.mesh if capped else mesh, spec, timer, pool)
        if tree is not None and tree.depth >= TREE_STACK:
            raise LimitError(f"gwn-solid walks its boundary tree with a stack of {TREE_STACK}; this mesh's tree "
                             f"({loops.n_edges} boundary edges) is {tree.depth} deep")

        def prepare(planes: bool, caps: bool = True) -> _Run:
            run = _Run(ctx, spec, pool, bufs, vox, bits, tree, timer, float(threshold), float(accuracy),
                       bool(winding), fix_bits, planes,
                       stream=None if stream is None else (max(nk for _, nk in stream), read_slab))
            if run.bricks:
                rows, segs = run.field_part()
                free = strip_free_share(tree, vox64, rows)
                run.bricks = free >= BRICKS_MIN_FREE and rows[1] * rows[3] * segs[1] * 4 * SEGV >= BRICKS_MIN_VOXELS
                run.stats["strip_free"] = round(free, 3)
            # the caps' crossings are counted in planes of their own: not with an int per voxel
            if (planes and run.bricks and capped is not None and capped.n_caps <= CAP_MAX
                    and cap_margin(threshold, WINDING_TIE) >= CAP_MIN_MARGIN):
                run.use_caps(capped, cap_records(capped, vox64), cap_margin(threshold, WINDING_TIE))
            return run

        run = prepare(planes=True)
        field = run.all_slabs(mesh.n_triangles)
        if run.overflowed():
            # 2^PLANES or more crossings of one sign in one voxel (the mesh's or the
            # caps'): again with an int per voxel
            clear_buffer(ctx, bits)
            run = prepare(planes=False)
            run.stats["event_overflow"] = True
            field = run.all_slabs(mesh.n_triangles)
        if shell:
            with timer.stage("shell", gpu=False):
                add_shell(ctx, mesh, spec, buffer_pool(ctx, self.info.name + ":shell"), bits, run.count)
        with timer.stage("readback", gpu=False):
            if stream is None:
                words = read_grid_words(ctx, bits, spec)
            voxels, _, _, left, split, _, first = (int(x) for x in np.frombuffer(run.count.read(size=28), dtype="<u4"))
        if stream is not None:
            run.stats["streamed"] = True  # its bits read slab by slab, one per z slab
            timer.merge_repeats()
        if run.bricks:
            run.stats["field_segments"] = left  # the segments the bricks left to the tree walk
            run.stats["split_blocks"] = split  # blocks of 4 voxels the -x split decided
            run.stats["first_order_blocks"] = first  # blocks the bricks' first-order records decided
        if run.caps is not None:  # bricks the caps' bound decided (counts alone), of them with their super brick
            caps = np.frombuffer(run.count.read(size=8, offset=28), dtype="<u4")
            run.stats["cap_bricks"], run.stats["super_bricks"] = int(caps[0]), int(caps[1])
        timer.stats.update(boundary_edges=loops.n_edges, loops=len(loops.loops), **run.stats)
        # the passes count in a uint32: not where a grid has 2^32 voxels or more
        return VoxelGrid(words=words, spec=spec, count=voxels if spec.n_voxels < 2**32 else None,
                         fields={"winding": field} if winding else None)


class _Run:
    """One gwn-solid run: the slabs, their passes and their statistics."""

    def __init__(self, ctx, spec, pool, bufs, vox, bits, tree, timer, threshold, beta, winding, fix_bits,
                 planes=True, stream=None):
        self.ctx, self.spec, self.pool, self.bufs, self.vox, self.bits = ctx, spec, pool, bufs, vox, bits
        # (slices the bits buffer holds, read_slab) where the grid is streamed slab by slab
        self.stream = stream
        self.tree, self.timer, self.threshold, self.beta, self.winding = tree, timer, threshold, beta, winding
        # the crossing counts in bit planes (else an int per voxel)
        self.planes = planes
        # voxels, refine list, todo list (slab), todo total, blocks of the -x split,
        # the planes' overflow flag, blocks of the first-order records, bricks the
        # caps decided, of them those their super brick decided
        self.count = pool.get("count", 36)
        # bricks need the voxels alone: the field asked for is the tree's everywhere
        self.bricks = tree is not None and not winding
        # the mirrored split's T (gwn/rows.comp, chain_winding) walks the whole tree
        # in one invocation: only within half the loop budget
        self.split = tree is not None and tree.n_nodes * 4 + len(tree.edges) <= LOOP_BUDGET // 2
        # where the caps decide bricks (use_caps)
        self.caps: RunCaps | None = None
        self.stats = {"slabs": 0, "tree_nodes": tree.n_nodes if tree else 0, "tree_chunks": 0,
                      "bricks": 0, "refined_segments": 0, "field_segments": 0}
        # F of ss/solid.glsl's fixed point (glvox.gpu.fixed_point.fixed_bits), for every pass
        self.uniforms = {**grid_uniforms(spec, bufs.anchor), "u_solid_fix_bits": fix_bits}
        self.max_groups = int(ctx.limits()["GL_MAX_COMPUTE_WORK_GROUP_COUNT"][0])
        if tree is not None:
            self.chunks = plan_chunks(tree)
            roots = np.concatenate([np.asarray(c, np.int32) for c in self.chunks])
            self.gpu_tree = {name: self._upload(name, arr) for name, arr in (
                ("edges", tree.edges), ("nodes", tree.nodes), ("links", tree.links), ("roots", roots))}
            self.stats["tree_chunks"] = len(self.chunks)

    def use_caps(self, capped, records: np.ndarray, limit: float) -> None:
        """Count the fans' crossings apart, and let the bricks the caps' bound
        (below ``limit``, turns) allows be decided from the counts (:mod:`.caps`)."""
        self.caps = RunCaps.of(self._upload("caps", records, "the boundary loops' fans"), capped, records, limit)
        self.stats["caps"] = True

    @property
    def _cap_defines(self) -> dict:
        return {"CAPS": int(self.caps is not None)}

    def _cap_uniforms(self) -> dict:
        return {} if self.caps is None else self.caps.uniforms()

    def _upload(self, name, arr, what: str | None = None):
        data = np.ascontiguousarray(arr).tobytes()
        buf = self.pool.get(name, len(data), what=what or f"the boundary tree's {name}", clear=False)
        buf.write(data)
        return buf

    def all_slabs(self, n_triangles: int):
        """Every slab's passes; the winding field (nx, ny, nz) float32 view, or None."""
        nx, ny, nz = self.spec.dims
        row = 32 * self.spec.words_per_row
        per_slab = slab_slices(self.spec, int(self.ctx.limits()["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"]),
                               planes_only=self.planes and not self.winding and self.tree is None,
                               several_chunks=self.tree is not None and len(self.chunks) > 1)
        if self.stream is not None:
            per_slab = min(per_slab, self.stream[0])
        field = np.empty((nz, ny, row), np.float32) if self.winding else None
        j0, k0, nj, nk = mesh_rows(self.spec, self.bufs)
        total = -(-nz // per_slab)
        for s0 in range(0, nz, per_slab):
            s1 = min(nz, s0 + per_slab)
            self.stats["slabs"] += 1
            if not self._slab(n_triangles, s0, s1, (j0, k0, nj, nk), field):
                break  # the planes overflowed: the caller runs the slabs again
            self.timer.slab_done(self.stats["slabs"], total)
        return None if field is None else field[:, :, :nx].transpose(2, 1, 0)

    def overflowed(self) -> bool:
        """Did a voxel get 2^PLANES or more crossings of one sign (the planes' flag)?
        Reads one word: waits for the passes so far."""
        return self.planes and bool(np.frombuffer(self.count.read(size=4, offset=20), dtype="<u4")[0])

    def _slab(self, n, s0, s1, rows, field) -> bool:
        """The passes of slices s0 .. s1 - 1; False where the planes overflowed first."""
        ctx, spec, pool = self.ctx, self.spec, self.pool
        ny = spec.dims[1]
        cells_n = (s1 - s0) * ny * 32 * spec.words_per_row
        plane_words = (s1 - s0) * ny * spec.words_per_row
        events = None
        carried = None
        if self.planes:
            events = pool.get("events", 2 * PLANES * plane_words * 4,
                              what=f"crossing counts of {s1 - s0} z slices ({2 * PLANES} bit planes)")
            # a flag per row where plane 1 holds a bit: the mesh's rows, then the caps'
            # (bound but neither written nor read without CARRY_FLAGS)
            flags = bool(self._plane_defines["CARRY_FLAGS"])
            carried = pool.get("carried", 2 * (s1 - s0) * ny * 4 if flags else 4,
                               what=f"carry flags of {s1 - s0} z slices", clear=flags)
        # an int per voxel: the counts without planes; C where a later pass reads it (the
        # field and refinement, only where the bricks left blocks: written before read
        # then, no clear), or w itself
        cells = None
        if not self.planes or self.winding or self.tree is not None:
            cleared = not self.planes or self.winding or not self.bricks
            cells = pool.get("cells", cells_n * 4, what=f"slab of {s1 - s0} z slices", clear=cleared)
        common = {**self.uniforms, "u_slab": (s0, s1), "u_threshold": self.threshold,
                  "u_bits_k0": 0 if self.stream is None else s0}
        self._crossings(n, cells, events, common, carried=carried)
        cap_events = None
        if self.caps is not None:
            cap_events = pool.get("cap_events", 2 * PLANES * plane_words * 4,
                                  what=f"the caps' crossing counts of {s1 - s0} z slices")
            self._crossings(self.caps.count, None, cap_events, common, first=self.caps.first,
                            carried=carried, carried0=(s1 - s0) * ny)
        if self.tree is not None and self.overflowed():
            # the slabs run again with an int per voxel anyway: not the tree's passes
            # first, the most of an open mesh's call (one word read, a wait per slab)
            return False
        j0, k0, nj, nk = rows
        fbox, segs = self._field_part(s0, s1, rows) if self.tree is not None else (None, None)
        if self.bricks:
            box = fbox
            bricks, cap_bits = self._bricks(common, s0, s1, fbox, segs)
        else:
            # rows outside the mesh's projection hold no crossing; all of them
            # only when C = 0 itself is inside
            full = self.threshold <= 0.0
            kk0, kk1 = (s0, s1) if full else (max(s0, k0), min(s1, k0 + nk))
            box = (0, ny, kk0, max(0, kk1 - kk0)) if full else (j0, nj, kk0, max(0, kk1 - kk0))
        with self.timer.stage("rows"):
            prog = compute_program(ctx, "gwn/rows.comp", {"EDGES": int(self.tree is not None),
                                                          "WINDING": int(self.winding),
                                                          "BRICKS": int(self.bricks), "GWN_BRICK": BRICK,
                                                          "GWN_NODE_VEC4": NODE_VEC4, "GWN_SEGV": SEGV,
                                                          "GWN_SPLIT": int(self.split), **self._plane_defines,
                                                          **self._cap_defines})
            set_uniforms(prog, {**common, "u_rows": box})
            blocks = {"Bits": self.bits, "Count": self.count}
            if cells is not None:
                blocks["Cells"] = cells
            if events is not None:
                blocks.update(Events=events, Carried=carried)
            if self.bricks:
                set_uniforms(prog, {"u_segs": segs, "u_margin": WINDING_TIE})
                t = self.gpu_tree
                blocks.update(Bricks=bricks, Masks=self._masks(box, segs), VoxVerts=self.vox, Edges=t["edges"],
                              Nodes=t["nodes"], Links=t["links"])
                if cap_events is not None:
                    blocks.update(CapEvents=cap_events, CapBits=cap_bits)
            bind(prog, **blocks)
            if box[1] * box[3]:
                dispatch_1d(ctx, prog, box[1] * box[3], _LOCAL)
            barrier(ctx)
        if self.tree is not None:
            self._field(cells, common, s0, s1, fbox, segs)
        if field is not None:
            with self.timer.stage("readback_field", gpu=False):
                cells.read_into(field[s0:s1], size=cells_n * 4)
        if self.stream is not None:
            per_slice = ny * spec.words_per_row * 4
            self.stream[1](s0, s1 - s0, self.bits)
            clear_buffer(ctx, self.bits, (s1 - s0) * per_slice)
        return True

    @property
    def _plane_defines(self) -> dict:
        return {"PLANES": int(self.planes), "CARRY_FLAGS": int(self.planes and carry_flags(self.spec))}

    def _crossings(self, n, cells, events, common, first: int = 0, carried=None, carried0: int = 0):
        ctx, pool = self.ctx, self.pool
        big = pool.get("big", (n + 2) * 4, what="the triangles with several column chunks", clear=False)
        clear_buffer(ctx, big, 8)
        args = pool.get("args", 3 * 4, clear=False)
        first_pass, rest = (compute_program(ctx, "gwn/events.comp", {"GWN_CHUNK": COLUMN_CHUNK, "FIRST": f,
                                                                      **self._plane_defines})
                            for f in (1, 0))
        for prog in (first_pass, rest):
            set_uniforms(prog, {**common, "u_triangles": n, "u_triangle0": first, "u_carried0": carried0})
        counts = ({"Events": events, "Count": self.count, "Carried": carried} if self.planes
                  else {"Counts": cells})
        with self.timer.stage("crossings"):
            chunked_passes(ctx, (first_pass, rest), n, self.max_groups,
                           {"VoxVerts": self.vox, "Faces": self.bufs.faces, **counts}, big, args, _LOCAL)

    def field_part(self):
        """Rows and slices ``(j0, nj, k0, nk)`` and segments ``(s0, ns)`` the field is
        evaluated over, in the whole grid."""
        j0, k0, nj, nk = mesh_rows(self.spec, self.bufs)
        return self._field_part(0, self.spec.dims[2], (j0, k0, nj, nk))

    def _field_part(self, s0, s1, rows):
        """The part of the slab the field is evaluated over: rows ``(j0, nj, k0, nk)``
        and segments ``(s0, ns)``."""
        spec = self.spec
        ny = spec.dims[1]
        j0, k0, nj, nk = rows
        if self.winding or self.threshold < 0.5:
            # outside the mesh's box w < 1/2 (strictly, outside its convex hull): skipped
            # only when those voxels are outside anyway and w itself is not asked for
            return (0, ny, s0, s1 - s0), (0, -(-spec.dims[0] // (4 * SEGV)))
        kk0, kk1 = max(s0, k0), min(s1, k0 + nk)
        return (j0, nj, kk0, max(0, kk1 - kk0)), x_range(self.spec, self.bufs)

    def _masks(self, box, segs):
        """The masks of blocks gwn/rows.comp leaves per segment (every segment written)."""
        return self.pool.get("masks", box[1] * box[3] * segs[1] * 4, what="blocks left by the bricks",
                             clear=False)

    def _list_todo(self, box, segs):
        """gwn/todo.comp and gwn/todo_args.comp: the segments with blocks left, listed,
        and the indirect dispatch arguments of the field pass over them (a buffer)."""
        ctx, pool = self.ctx, self.pool
        n = box[1] * box[3] * segs[1]
        todo = pool.get("todo", n * 8, what="segments left by the bricks", clear=False)
        args = pool.get("todo_args", 12, clear=False)
        clear_buffer(ctx, self.count, 4, offset=8)
        prog = compute_program(ctx, "gwn/todo.comp", {"GWN_TODO_RUN": TODO_RUN})
        set_uniforms(prog, {"u_items": n})
        bind(prog, Masks=self._masks(box, segs), Count=self.count, Todo=todo)
        dispatch_1d(ctx, prog, -(-n // TODO_RUN), _LOCAL)
        barrier(ctx)
        prog = compute_program(ctx, "gwn/todo_args.comp")
        set_uniforms(prog, {"u_local_size": _LOCAL, "u_max_groups": self.max_groups})
        bind(prog, Count=self.count, Args=args)
        prog.run(1, 1, 1)
        barrier(ctx)
        return args

    def _bricks(self, common, s0, s1, box, segs):
        """gwn/bricks.comp over the bricks of the evaluated part; the Bricks buffer."""
        ctx, spec = self.ctx, self.spec
        ny = spec.dims[1]
        per_seg = 4 * SEGV // BRICK
        nbx = -(-32 * spec.words_per_row // BRICK)
        nby = -(-ny // BRICK)
        nbz = -(-(s1 - s0) // BRICK)
        buf = self.pool.get("bricks", nbx * nby * nbz * 32, what="bricks", clear=False)
        cap_bits = None
        if self.caps is not None:
            cap_bits = self.pool.get("cap_bits", -(-nbx * nby * nbz // 32) * 4, what="bricks the caps decide")
        j0, nj, k0, nk = box
        first = (segs[0] * per_seg, j0 // BRICK, (k0 - s0) // BRICK)
        last = ((segs[0] + segs[1]) * per_seg - 1, (j0 + nj - 1) // BRICK, (k0 + nk - 1 - s0) // BRICK)
        counts = tuple(max(0, b - a + 1) for a, b in zip(first, last))
        n = counts[0] * counts[1] * counts[2]
        if not (nj and nk and segs[1]):
            return buf, cap_bits
        self.stats["bricks"] += n
        edges = len(self.tree.edges)
        grad = edges <= GRAD_EDGES
        defines = {"GWN_SEGV": SEGV, "GWN_BRICK": BRICK, "GWN_NODE_VEC4": NODE_VEC4, **self._cap_defines}
        prog = compute_program(ctx, "gwn/bricks.comp", {**defines, "GWN_GRAD": int(grad), "GWN_SUPER": 0})
        if grad:
            set_uniforms(prog, {"u_edges": edges})
        t = self.gpu_tree
        bind(prog, VoxVerts=self.vox, Bricks=buf, Edges=t["edges"], Nodes=t["nodes"], Links=t["links"],
             Roots=t["roots"], **({} if self.caps is None else {"Caps": self.caps.buf, "Count": self.count,
                                                                 "CapBits": cap_bits}))
        with self.timer.stage("bricks"):
            # the caps' bound over whole super bricks first, coarsest first, each pass
            # over those the one before left (gwn/bricks.comp's header)
            for level, size in enumerate(super_sizes(n) if self.caps is not None else ()):
                sup = compute_program(ctx, "gwn/bricks.comp", {**defines, "GWN_GRAD": 0, "GWN_SUPER": size,
                                                                "GWN_SUPER_AFTER": int(level > 0)})
                bind(sup, VoxVerts=self.vox, Caps=self.caps.buf, Count=self.count, CapBits=cap_bits)
                set_uniforms(sup, {**common, "u_brick0": first, "u_bricks": counts, **self._cap_uniforms()})
                dispatch_1d(ctx, sup, math.prod(-(-c // size) for c in counts), _LOCAL)
                barrier(ctx)
            start = 0
            for i, chunk in enumerate(self.chunks):
                set_uniforms(prog, {**common, "u_beta": self.beta, "u_roots": (start, start + len(chunk)),
                                    "u_first": i == 0, "u_last": i == len(self.chunks) - 1,
                                    "u_brick0": first, "u_bricks": counts, **self._cap_uniforms()})
                start += len(chunk)
                dispatch_1d(ctx, prog, n, _LOCAL)
                barrier(ctx)
        return buf, cap_bits

    def _field(self, cells, common, s0, s1, box, segs):
        ctx, spec, pool = self.ctx, self.spec, self.pool
        ny = spec.dims[1]
        n_inv = box[1] * box[3] * segs[1]
        if n_inv == 0:
            return
        if not self.bricks:
            self.stats["field_segments"] += n_inv
        defines = {"GWN_SEGV": SEGV, "WINDING": int(self.winding), "BRICKS": int(self.bricks),
                   "GWN_NODE_VEC4": NODE_VEC4}
        uni = {**common, "u_rows": box, "u_segs": segs, "u_beta": self.beta, "u_margin": WINDING_TIE}
        acc = None
        if len(self.chunks) > 1:
            acc = pool.get("acc", (s1 - s0) * ny * 32 * spec.words_per_row * 8, what="tree chunk sums",
                           clear=False)
        with self.timer.stage("far"):
            args = self._list_todo(box, segs) if self.bricks else None
            listed, n_list = self._tree_pass(cells, acc, uni, defines, n_inv, args)
        if n_list == 0:
            return
        self.stats["refined_segments"] += n_list
        edges = len(self.tree.edges)
        sums = pool.get("sums", n_list * SEGV * 16, what="refinement sums", clear=False) \
            if edges > REFINE_EDGES else None
        with self.timer.stage("refine"):
            prog = compute_program(ctx, "gwn/refine.comp", {"GWN_SEGV": SEGV, "WINDING": int(self.winding)})
            bind(prog, **self._blocks(cells, listed), **({"Sums": sums} if sums is not None else {}))
            for e0 in range(0, edges, REFINE_EDGES):
                e1 = min(edges, e0 + REFINE_EDGES)
                set_uniforms(prog, {**uni, "u_edges": (e0, e1), "u_first": e0 == 0, "u_last": e1 == edges,
                                    "u_items": n_list})
                dispatch_1d(ctx, prog, n_list, _LOCAL)
                barrier(ctx)

    def _tree_pass(self, cells, acc, uni, defines, n, args=None):
        """The walk of the tree (every chunk) over the ``n`` segments of the
        evaluated part, or with bricks over those listed (``args``: the indirect
        dispatch).  Returns the list of segments with undecided blocks (buffer)
        and its length: the one size read inside the pipeline, which sizes the
        refinement."""
        ctx = self.ctx
        out = self.pool.get("refine", n * 8, what="segments left undecided", clear=False)
        prog = compute_program(ctx, "gwn/field.comp", defines)
        t = self.gpu_tree
        bind(prog, **self._blocks(cells, out), Nodes=t["nodes"], Links=t["links"], Roots=t["roots"],
             **({"Acc": acc} if acc is not None else {}), **({"Todo": self.pool.get("todo", 8, clear=False)}
                                                               if self.bricks else {}))
        start = 0
        for i, chunk in enumerate(self.chunks):
            set_uniforms(prog, {**uni, "u_roots": (start, start + len(chunk)), "u_first": i == 0,
                                "u_last": i == len(self.chunks) - 1})
            start += len(chunk)
            if args is None:
                dispatch_1d(ctx, prog, n, _LOCAL)
            else:
                prog.run_indirect(args)
            barrier(ctx)
        n_out = int(np.frombuffer(self.count.read(size=8), dtype="<u4")[1])
        self.count.write(np.zeros(1, "<u4").tobytes(), offset=4)
        return out, n_out

    def _blocks(self, cells, refine) -> dict:
        """The buffers ``gwn/field.comp`` and ``gwn/refine.comp`` share, by block name."""
        return {"VoxVerts": self.vox, "Cells": cells, "Edges": self.gpu_tree["edges"], "Bits": self.bits,
                "Count": self.count, "Refine": refine}
