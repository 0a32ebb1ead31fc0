"""Schwarz & Seidel 2010 sparse solid voxelization into an octree (Sec. 5), in compute shaders.

``ss-octree`` builds the octree up front and voxelizes into it, never
holding a dense grid, so grids far beyond what fits densely work (4096^3 of
the bunny in a few hundred MiB).  The result is a :class:`glvox.results.octree.SparseOctree`.

Pipeline (``shaders/ss_octree/``; all stages on the GPU):

* ``transform``: vertices to voxel space (S&S Sec. 6, shared with ss-solid).
* ``active nodes`` (Sec. 5.1): a conservative voxelization of the triangles
  into the grid of level-1 nodes (8^3 voxels), with the paper's half-voxel
  shift in +x and node boxes enlarged by one voxel in +x, written into a bit
  array indexed by Morton code; then one invocation per 32-bit word (a
  4 x 4 x 2 block in Morton order) counts its set bits, an exclusive scan
  gives offsets and the count N1, and a second pass writes the sorted list
  ActNodes_1.  Per-triangle work is split into chunks (one invocation each,
  found by binary search in the scanned chunk counts).
* ``construct`` (Sec. 5.2): per level, FLAG (last child of a parent group),
  its exclusive scan PARENTINDEX and the compaction into ActNodes_{L+1};
  then every level is allocated and initialized top-down (Morton codes,
  parent and child pointers, x-neighbour pointers within a parent) and the
  x-neighbour pointers across parents are propagated from the top.  The
  top level, two below the root, holds all 4^3 nodes.
* ``voxelize`` (Sec. 5.3): per triangle (chunks of tiles of 4 x 4 columns),
  the covered columns of ``ss/solid.glsl`` (the arithmetic of ss-solid) flip
  SG voxels ``q_bar mod 4 .. 3`` of the level-0 node holding ``q_bar`` with
  ``atomicXor``; nodes are found by descent from the top.
* ``propagate`` (Sec. 5.4): flips along the x-linked strings of level-0
  nodes, flip flags at the strings' ends into level 1, along level-1
  strings, and so on to the top; then inside flags from the top down.
* ``coverage`` (Sec. 5.5): set-voxel counts per node, bottom-up.
* ``readback``: the node arrays.

What the CPU reads inside the pipeline: the number of active level-1 nodes
N1 (to allocate level 0) and the number of active nodes of every level above
(one uint32 each, to allocate the level below it).

Open meshes (``allow_open=True``) and walls.  On a closed mesh the parity of
crossings changes only across the surface, so a node the surface does not
meet is uniform and needs no children.  Through a hole it also changes
across the +x "shadow" of the hole's boundary (the rays from points beyond
the boundary edge cross one triangle fewer on one side).  With
``walls=True`` (default) glvox extrudes every open boundary edge (an edge
with an odd number of triangles, vertices merged by position) in +x to
beyond the grid and activates the nodes these walls meet too, so the octree
decodes to exactly ss-solid's parity result on any mesh.  With
``walls=False`` (the paper's algorithm) such nodes stay uniform and take the
state of their min-corner column: the result then differs from ss-solid in
parts of the shadows of holes.
"""

from __future__ import annotations

import weakref

import numpy as np

from ...errors import LimitError
from ...gl.shaders import compute_program, program_source
from ...gpu.buffers import buffer_pool
from ...gpu.sort import SHADERS as SORT_SHADERS, exclusive_scan
from ...gpu.dispatch import LOOP_BUDGET, barrier, bind, dispatch_1d, grid_uniforms, set_uniforms
from ...gpu.fixed_point import fixed_bits
from ...gpu.transform import SHADERS as TRANSFORM_SHADERS, transform_vertices
from ...results.octree import MAX_OCTREE_DIM, NONE, OctreeLevel, SparseOctree, top_level
from ..base import Method, MethodInfo, Option, Requirements, register

_PAPER = "Schwarz & Seidel 2010"
_LOCAL = 64   # local_size_x of the per-item passes (activate*, voxelize)
_LOCAL_NODES = 256  # local_size_x of the per-node and per-word passes

#: Work units per invocation of the activation pass: a unit is a column of
#: level-1 nodes along the triangle's dominant axis (at most a few nodes: the
#: plane's depth over one column box is below 2 * 9 voxels) or one node of a
#: box marked without tests.
ACTIVATE_CHUNK = 4096

#: Tiles (4 x 4 columns) per invocation of the voxelization pass: a tile
#: costs its test and up to 16 column tests, each with a descent of at most
#: 8 levels.
VOXELIZE_CHUNK = 128

#: Levels the shaders' offset arrays hold (common.glsl OCT_MAX_LEVELS).
MAX_LEVELS = 12

assert ACTIVATE_CHUNK * 6 < LOOP_BUDGET
assert VOXELIZE_CHUNK * (4 + 16 * (4 + 8)) < LOOP_BUDGET
assert MAX_OCTREE_DIM // 4 < LOOP_BUDGET  # string walks: at most the level-0 extent in nodes
assert top_level((MAX_OCTREE_DIM,) * 3) < MAX_LEVELS

_REQUIRES = Requirements(gl_version=430, extensions=("GL_ARB_gpu_shader_fp64",),
                         limits={"GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 20},
                         compute=(("ss_octree/*.comp", {}),) + SORT_SHADERS + TRANSFORM_SHADERS)

_BOUNDARY_EDGES: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def boundary_edges(mesh) -> np.ndarray:
    """Open boundary edges of ``mesh``: (E, 2) uint32 vertex indices.

    An edge used by an odd number of triangles, vertices merged by their
    float32 position as uploaded to the GPU (``Mesh.gpu_arrays``): the
    shaders see those, and two vertices equal there stay equal in voxel
    space, so every crack the GPU sees is found (cracks of 1e-16 that float32
    closes, as in some CAD exports, are not).  Across the +x extrusion of
    such an edge the parity of crossings changes.  Empty for a closed mesh.
    Cached per mesh.
    """
    cached = _BOUNDARY_EDGES.get(mesh)
    if cached is not None:
        return cached
    _, rep = np.unique(mesh.gpu_arrays()[0], axis=0, return_inverse=True)
    rep = rep.reshape(-1)
    first = np.zeros(rep.max() + 1 if len(rep) else 0, dtype=np.int64)
    first[rep[::-1]] = np.arange(len(rep))[::-1]  # a vertex index for each position
    f = rep[mesh.faces]
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(e, axis=0, return_counts=True)
    odd = uniq[counts % 2 == 1]
    out = first[odd].astype(np.uint32).reshape(-1, 2)
    _BOUNDARY_EDGES[mesh] = out
    return out


def _read_u32(buf, n: int = 1, offset: int = 0) -> np.ndarray:
    return np.frombuffer(buf.read(size=4 * n, offset=4 * offset), dtype="<u4").copy()


def _declared(prog, blocks: dict) -> dict:
    """The entries of ``blocks`` (by storage block name) that ``prog``'s source declares:
    every pass over the node arrays gets the whole tree and takes the arrays it uses."""
    names = program_source(prog).storage_blocks
    return {k: v for k, v in blocks.items() if k in names}


class _Build:
    """One ss-octree run: its buffers and programs, and the steps of Sec. 5 over them.

    Each step leaves what the next one needs on ``self``: the active nodes per
    level (``n_act``, ``acts``, ``pidx``), the node counts per level
    (``sizes``) with their offsets in the node arrays (``nbase``, ``ubase``),
    and the node arrays (``tree``, by storage block name).
    """

    def __init__(self, ctx, mesh, spec, walls: bool, owner: str, timer) -> None:
        self.ctx, self.spec = ctx, spec
        self.top = top_level(spec.dims)  # LimitError past MAX_OCTREE_DIM
        self.fix_bits = fixed_bits(mesh, spec, 0)  # ss/solid.glsl's fixed point; LimitError out of its range
        self.pool = buffer_pool(ctx, owner)
        self.max_groups = int(ctx.limits()["GL_MAX_COMPUTE_WORK_GROUP_COUNT"][0])
        self.n_tris = mesh.n_triangles
        self.n1 = tuple(-(-d // 8) for d in spec.dims)
        self.l1_words = max(1, 8 ** (self.top + 1) // 32)  # the Morton-indexed level-1 cube, 2^(top+1) per axis
        self.limit = int(ctx.limits()["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"])
        self.bufs, self.vox = transform_vertices(ctx, mesh, spec, timer, self.pool)
        edges = boundary_edges(mesh) if walls else np.zeros((0, 2), np.uint32)
        self.n_walls = len(edges)
        # a few KiB at most (the bunny has 223 boundary edges), written each run
        self.walls = self.alloc("walls", max(8, edges.nbytes), what="wall edges", clear=False)
        if self.n_walls:
            self.walls.write(edges.tobytes())
        self.stats = self.alloc("stats", 16)
        self.dummy = self.alloc("dummy", 16)
        self.grid_u = {**grid_uniforms(spec, self.bufs.anchor), "u_solid_fix_bits": self.fix_bits}
        self.nbase = np.zeros(MAX_LEVELS, np.uint32)
        self.ubase = np.zeros(MAX_LEVELS, np.uint32)

    def alloc(self, name, nbytes, what=None, clear=True):
        """A pooled buffer, refused with the octree's own advice past the storage-block limit."""
        what = what or name
        if nbytes > self.limit:
            raise LimitError(
                f"ss-octree needs {nbytes / 2**20:.1f} MiB in one shader storage buffer for {what}, "
                f"over this context's GL_MAX_SHADER_STORAGE_BLOCK_SIZE of {self.limit / 2**20:.1f} MiB "
                f"({self.ctx.renderer}); use a smaller grid (level-0 nodes grow about 4x per doubling "
                "of the resolution)")
        return self.pool.get(name, nbytes, what=what, clear=clear)

    def prog(self, path, defines=None, **uniforms):
        """``shaders/ss_octree/<path>`` with the run's uniforms and the level offsets."""
        p = compute_program(self.ctx, f"ss_octree/{path}", defines)
        set_uniforms(p, {**self.grid_u, "u_n1": self.n1, "u_top": self.top, "u_triangles": self.n_tris,
                         "u_walls": self.n_walls, **uniforms})
        for name, arr in (("u_nbase", self.nbase), ("u_ubase", self.ubase)):
            if name in p:
                p[name].write(arr.tobytes())
        return p

    def run_chunks(self, work, n_items, what):
        """Pass 1 (chunk counts per item), scan, indirect dispatch of one invocation per chunk."""
        ctx = self.ctx
        chunks = self.alloc("chunks", 4 * n_items, what=f"{what} chunk counts", clear=False)
        offsets = self.alloc("chunk_offsets", 4 * n_items, what=f"{what} chunk offsets", clear=False)
        total = self.alloc("chunk_total", 16)
        args = self.alloc("args", 16, clear=False)
        bind(work, **_declared(work, {"VoxVerts": self.vox, "Faces": self.bufs.faces, "Walls": self.walls,
                                      "Stats": self.stats}), Chunks=chunks)
        dispatch_1d(ctx, work, n_items, _LOCAL)
        barrier(ctx)
        exclusive_scan(ctx, chunks, offsets, n_items, total=total)
        barrier(ctx)
        targs = self.prog("chunk_args.comp", u_local_size=_LOCAL, u_max_groups=self.max_groups)
        bind(targs, ChunkTotal=total, Args=args)
        targs.run(1, 1, 1)
        barrier(ctx)
        return offsets, total, args

    def active_nodes(self) -> None:
        """Sec. 5.1: the level-1 nodes the triangles (and walls) meet, as a sorted list."""
        ctx, l1_words = self.ctx, self.l1_words
        l1 = self.alloc("l1_bits", 4 * l1_words, what="the level-1 node bit array")
        n_items = self.n_tris + 2 * self.n_walls
        defines = {"OCT_CHUNK": ACTIVATE_CHUNK}
        offsets, total, args = self.run_chunks(self.prog("activate_work.comp", defines), n_items, "activation")
        act_prog = self.prog("activate.comp", defines)
        bind(act_prog, VoxVerts=self.vox, Faces=self.bufs.faces, Walls=self.walls, ChunkOffsets=offsets,
             ChunkTotal=total, L1Bits=l1)
        act_prog.run_indirect(args)
        barrier(ctx)
        counts = self.alloc("l1_counts", 4 * l1_words, what="level-1 word counts", clear=False)
        count_prog = self.prog("extract.comp", {"EXTRACT_WRITE": 0}, u_words=l1_words)
        bind(count_prog, L1Bits=l1, Counts=counts)
        dispatch_1d(ctx, count_prog, l1_words, _LOCAL_NODES)
        barrier(ctx)
        exclusive_scan(ctx, counts, counts, l1_words, total=total)
        barrier(ctx)
        self.total = total
        self.n_act = [0, int(_read_u32(total)[0])]  # N_1: sizes level 0
        self.acts = {1: self.alloc("act1", 4 * self.n_act[1], what=f"{self.n_act[1]} active level-1 nodes",
                                   clear=False)}
        write_prog = self.prog("extract.comp", {"EXTRACT_WRITE": 1}, u_words=l1_words)
        bind(write_prog, L1Bits=l1, Offsets=counts, Act=self.acts[1])
        dispatch_1d(ctx, write_prog, l1_words, _LOCAL_NODES)
        barrier(ctx)

    def parent_levels(self) -> None:
        """Sec. 5.2, first half: per level, FLAG, its scan PARENTINDEX and the compaction
        into the active nodes of the level above."""
        ctx, n_act, acts = self.ctx, self.n_act, self.acts
        self.pidx = {}
        flag = self.alloc("flag", 4 * max(1, n_act[1]), what="FLAG", clear=False)
        for level in range(1, self.top):
            n = n_act[level]
            self.pidx[level] = self.alloc(f"pidx{level}", 4 * n, what=f"PARENTINDEX_{level}", clear=False)
            p0 = self.prog("construct.comp", {"PHASE": 0}, u_count=n)
            bind(p0, Act=acts[level], Flag=flag)
            dispatch_1d(ctx, p0, n, _LOCAL_NODES)
            barrier(ctx)
            exclusive_scan(ctx, flag, self.pidx[level], n, total=self.total)
            barrier(ctx)
            n_act.append(int(_read_u32(self.total)[0]))  # N_{level+1}: sizes level `level`
            acts[level + 1] = self.alloc(f"act{level + 1}", 4 * n_act[level + 1],
                                         what=f"active level-{level + 1} nodes", clear=False)
            p1 = self.prog("construct.comp", {"PHASE": 1}, u_count=n)
            bind(p1, Act=acts[level], Flag=flag, ActNext=acts[level + 1], ParentIndex=self.pidx[level])
            dispatch_1d(ctx, p1, n, _LOCAL_NODES)
            barrier(ctx)

    def allocate_levels(self) -> None:
        """Sec. 5.2, second half: the node arrays, every level initialized top-down
        (Morton codes, parent and child pointers, x-neighbours) and linked along x."""
        ctx, top = self.ctx, self.top
        sizes = self.sizes = [8 * self.n_act[level + 1] for level in range(top)] + [64]
        self.nbase[:top + 1] = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.uint32)
        self.ubase[1:top + 1] = self.nbase[1:top + 1] - sizes[0]
        self.n_all, self.n_upper = int(sum(sizes)), int(sum(sizes[1:]))
        n_all, n_upper = self.n_all, self.n_upper
        what = f"the octree's {n_all} nodes"
        morton = self.alloc("morton", 4 * n_all, what=f"Morton codes of {what}", clear=False)
        parent = self.alloc("parent", 4 * n_all, what=f"parent pointers of {what}", clear=False)
        x_next = self.alloc("x_next", 4 * n_all, what=f"+x pointers of {what}", clear=False)
        x_prev = self.alloc("x_prev", 4 * n_all, what=f"-x pointers of {what}", clear=False)
        count = self.alloc("count", 4 * n_all, what=f"coverage counts of {what}", clear=False)
        child = self.alloc("child", 4 * n_upper, what="child pointers", clear=False)
        flags = self.alloc("flags", 4 * n_upper, what="node flags", clear=False)
        data = self.alloc("data", 8 * sizes[0], what=f"the sub-grids of {sizes[0]} level-0 nodes", clear=False)
        self.tree = dict(Morton=morton, Parent=parent, XNext=x_next, XPrev=x_prev, Child=child, Flags=flags,
                         Data=data, Count=count)
        for level in range(top, -1, -1):
            up = self.acts.get(level + 1, self.dummy)
            p_up = self.pidx.get(level + 1, self.dummy)
            init = self.prog("init_level.comp", u_level=level, u_count=sizes[level])
            bind(init, **_declared(init, self.tree), ActUp=up, ParentIndexUp=p_up)
            dispatch_1d(ctx, init, sizes[level], _LOCAL_NODES)
            barrier(ctx)
            if level < top:
                link = self.prog("link_x.comp", u_level=level, u_count=sizes[level])
                bind(link, **_declared(link, self.tree))
                dispatch_1d(ctx, link, sizes[level], _LOCAL_NODES)
                barrier(ctx)

    def voxelize(self) -> None:
        """Sec. 5.3: the covered columns flip the sub-grid voxels of level-0 nodes."""
        defines = {"OCT_CHUNK": VOXELIZE_CHUNK}
        offsets, total, args = self.run_chunks(self.prog("voxelize.comp", {**defines, "VOX_WORK": 1}),
                                               self.n_tris, "voxelization")
        vprog = self.prog("voxelize.comp", {**defines, "VOX_WORK": 0})
        bind(vprog, **_declared(vprog, self.tree), VoxVerts=self.vox, Faces=self.bufs.faces, Stats=self.stats,
             ChunkOffsets=offsets, ChunkTotal=total)
        vprog.run_indirect(args)
        barrier(self.ctx)

    def _over_level(self, path, level, defines=None, **uniforms) -> None:
        """One pass of ``path`` over the nodes of ``level``."""
        p = self.prog(path, defines, u_level=level, u_count=self.sizes[level], **uniforms)
        bind(p, **_declared(p, self.tree))
        dispatch_1d(self.ctx, p, self.sizes[level], _LOCAL_NODES)
        barrier(self.ctx)

    def propagate(self) -> None:
        """Sec. 5.4: flips along the x strings level by level up to the top, then inside flags down."""
        top = self.top

        def phase(ph, level):
            self._over_level("propagate.comp", level, {"PHASE": ph}, u_max_steps=(16 << top) >> (level + 2))

        phase(0, 0)
        for level in range(1, top + 1):
            phase(1, level)
            phase(2, level)
        for level in range(top, 0, -1):
            phase(3, level)

    def coverage(self) -> None:
        """Sec. 5.5: set-voxel counts per node, bottom-up."""
        for level in range(self.top + 1):
            self._over_level("coverage.comp", level, u_dims=self.spec.dims)

    def read(self) -> tuple[SparseOctree, np.ndarray]:
        """The octree from the node arrays, and the voxelization's (lost, total) crossings."""
        t, n_all, n_upper, sizes = self.tree, self.n_all, self.n_upper, self.sizes

        def arr(buf, n):
            return np.frombuffer(buf.read(size=4 * n), dtype="<u4") if n else np.zeros(0, "<u4")

        all_m, all_p = arr(t["Morton"], n_all), arr(t["Parent"], n_all)
        all_n, all_x, all_c = arr(t["XNext"], n_all), arr(t["XPrev"], n_all), arr(t["Count"], n_all)
        up_child, up_flags = arr(t["Child"], n_upper), arr(t["Flags"], n_upper)
        sub = (np.frombuffer(t["Data"].read(size=8 * sizes[0]), dtype="<u8") if sizes[0]
               else np.zeros(0, "<u8"))
        vstats = _read_u32(self.stats, 2)
        levels = []
        for level in range(self.top + 1):
            a, b = int(self.nbase[level]), int(self.nbase[level]) + sizes[level]
            ch = ins = None
            if level:
                ua, ub = int(self.ubase[level]), int(self.ubase[level]) + sizes[level]
                ch = up_child[ua:ub].astype(np.uint32)
                ins = ((up_flags[ua:ub] & 1) != 0) & (ch == NONE)
            levels.append(OctreeLevel(level=level, morton=all_m[a:b].astype(np.uint32),
                                      parent=all_p[a:b].astype(np.uint32),
                                      x_next=all_n[a:b].astype(np.uint32), x_prev=all_x[a:b].astype(np.uint32),
                                      child=ch, inside=ins, count=all_c[a:b].astype(np.uint32)))
        return SparseOctree(self.spec, levels, sub.astype(np.uint64)), vstats


@register
class SSOctree(Method):
    info = MethodInfo(
        name="ss-octree", kind="sparse", pipeline="compute",
        paper=f"{_PAPER}, Sec. 5 (sparse solid voxelization into an octree; Sec. 3.2, 4.1, 6)",
        summary="sparse solid octree: active level-1 nodes, bottom-up construction, voxelization "
                "into 4^3 sub-grids with atomicXor, hierarchical propagation, coverage factors",
        reference="reference-solid",
        requires=_REQUIRES,
        options={"walls": Option(True, "also refine the +x shadows of open boundary edges, so that "
                                       "open meshes decode to ss-solid's parity result")},
    )

    def run(self, mesh, spec, *, ctx, timer, walls):
        build = _Build(ctx, mesh, spec, walls, self.info.name, timer)
        with timer.stage("active nodes"):
            build.active_nodes()
        with timer.stage("construct"):
            build.parent_levels()
            build.allocate_levels()
        with timer.stage("voxelize"):
            build.voxelize()
        with timer.stage("propagate"):
            build.propagate()
        with timer.stage("coverage"):
            build.coverage()
        with timer.stage("readback", gpu=False):
            result, vstats = build.read()
        mem = result.memory()
        timer.stats.update({
            "top_level": build.top, "active_level1_nodes": build.n_act[1], "active_nodes": build.n_act[1:],
            "nodes_per_level": build.sizes, "walls": build.n_walls, "crossings": int(vstats[1]),
            "lost_crossings": int(vstats[0]),
            "memory_bytes": mem["total"], "structure_bytes": mem["structure"], "data_bytes": mem["data"],
            "dense_bytes": mem["dense"], "level0_percent": round(mem["level0_percent"], 4),
        })
        return result
