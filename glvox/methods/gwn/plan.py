"""How ``gwn-solid`` (:mod:`.field`) divides its work: the grid in slabs of z
slices (:func:`slab_slices`) and its crossing counts in bit planes
(:data:`PLANES`, :func:`carry_flags`), the boundary tree in chunks of
subtrees per field dispatch (:func:`plan_chunks`, within the loop budget),
the share of brick columns where bricks can decide at all
(:func:`strip_free_share`), and the row segments along x the mesh can reach
(:func:`x_range`)."""

from __future__ import annotations

import math
import weakref

import numpy as np

from ...gpu.dispatch import LOOP_BUDGET
from .tree import ClusterTree

#: vec4 per row segment: a segment is 4 * SEGV voxels, a whole 32-bit word,
#: so each invocation of the field pass writes its word alone.
SEGV = 8

#: Loop iterations charged per tree node and per boundary edge in one field
#: invocation, should the compiler keep every loop (a node: the walk, its
#: record, the far test, expansion and chord strip over the segment's blocks;
#: an edge: its strip over them).  Chunks keep their sum under half of
#: LOOP_BUDGET.
NODE_COST = 8 + 4 * SEGV
EDGE_COST = 1 + SEGV

#: Edge of a brick (voxels): gwn/bricks.comp bounds F over cubes of BRICK^3
#: voxels.  A brick of 8 needs one tree walk per 512 voxels, and leaves
#: 2-6% of the voxels of the bunny and the teapot at 256^3 to the per-voxel
#: walk (4 walks 4 times as many bricks for a few percent fewer voxels;
#: 16 leaves twice as many).  It divides 4 * SEGV: a block of 4 voxels lies in
#: one brick.
BRICK = 8

#: Bricks per edge of a super brick: where the caps are used, gwn/bricks.comp
#: first tries their bound over the ball around each super brick's voxel
#: centers, and the bricks of a super brick it decides skip their own test
#: (which loops over every fan triangle whose ball the brick is in).  From
#: SUPER_MIN_BRICKS bricks in the part evaluated: below, the pass's fixed cost
#: is what it saves.  Measured on llvmpipe (2 cores), `glvox bench -m gwn-solid
#: --meshes stanford_bunny_bun_zipper.ply messy_teapot_newell.obj
#: messy_tower_holes.obj messy_wallhole.obj depth_gyroid_tpms_sheet.stl -r 128
#: 256 512 --against REV --repeat 3`, two runs (best ratios): 0.88-0.96 at
#: 512^3 (the bunny 0.97), 0.95-1.01 at 256^3, 1.00-1.05 at 128^3.  Then
#: again over super bricks of half the edge, down to 2, inside the super
#: bricks the pass before left (docs/methods/gwn.md has the measurements).
SUPER = 4
SUPER_MIN_BRICKS = 1 << 14


def super_sizes(n_bricks: int) -> tuple[int, ...]:
    """Bricks per edge of the super bricks of each pass, coarsest first
    (:data:`SUPER`, then halved down to 2), where ``n_bricks`` bricks are in the
    part evaluated; () below :data:`SUPER_MIN_BRICKS`: no super bricks' pass."""
    if SUPER < 2 or n_bricks < SUPER_MIN_BRICKS:
        return ()
    return tuple(SUPER >> i for i in range(SUPER.bit_length() - 1))


#: Cells (voxels of padded rows) per slab, at most: the slab buffer takes 4
#: bytes a cell and, with several tree chunks, the chunk sums' buffer 8; each
#: must fit the storage-block limit, which binds first where it is lower
#: (llvmpipe's 128 MiB: 2^25 cells; NVIDIA's 2 GiB: this cap, 256 MiB of
#: cells, 16 slabs at 1024^3).  Eight times as many where only the crossings'
#: bit planes are kept (closed meshes, no field).  Every slab repeats the crossing pass over
#: all triangles and each pass's fixed cost: on llvmpipe the bunny at 512^3
#: took 949 / 1,082 / 1,934 ms in 8 / 32 / 128 slabs (same process, best of 3).
SLAB_CELLS = 1 << 26

#: Bit planes per sign of the crossing counts (gwn/events.comp, which fixes
#: it at 2; gwn/layout.glsl has their layout): a voxel's count of +1 (and of
#: -1) crossings is held modulo 2^PLANES.  The crossings
#: of one sign in one voxel and row are one or none but where sheets of the
#: mesh nearly coincide; 4 or more set a flag, and the slabs run again with an
#: int per voxel (``run.stats['event_overflow']``).  Against that int per
#: voxel, the planes cut the memory cleared and read by the row pass eightfold
#: (closed meshes, llvmpipe: see docs/methods/gwn.md).
PLANES = 2

#: Grids (voxels) from which the crossings flag the rows whose second bit planes
#: hold a bit (gwn/layout.glsl), so that the row pass reads those planes there
#: only.  The flag's store costs the crossing pass at every size (llvmpipe runs it
#: in every batch); below this the row pass saves no more than that: the armadillo
#: (closed) took 1.04-1.12x the time with flags at 64^3, 1.01 at 128^3, 0.89-0.91
#: at 256^3 and 0.85 at 512^3 (`glvox bench -m gwn-solid --against REV`, 2 cores,
#: llvmpipe).
CARRY_FLAGS_MIN_VOXELS = 1 << 24


def slab_slices(spec, limit: int, *, planes_only: bool, several_chunks: bool) -> int:
    """z slices per slab of ``spec``'s grid: :data:`SLAB_CELLS` cells at most, and
    each slab buffer within the storage-block ``limit`` (bytes).  ``planes_only``:
    only the crossings' bit planes are kept (2 * PLANES bits a cell, eight times
    the cells); else a cell takes 4 bytes, and 8 with ``several_chunks`` (the
    tree's chunk sums)."""
    row = 32 * spec.words_per_row
    if planes_only:
        cells = min(8 * SLAB_CELLS, limit * 8 // (2 * PLANES))
    else:
        cells = min(SLAB_CELLS, limit // (8 if several_chunks else 4))
    return max(1, cells // (row * spec.dims[1]))


def carry_flags(spec) -> bool:
    """Whether the crossings flag the rows that carry into the second bit planes
    (:data:`CARRY_FLAGS_MIN_VOXELS`)."""
    return spec.n_voxels >= CARRY_FLAGS_MIN_VOXELS


_CHUNKS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def plan_chunks(tree: ClusterTree) -> list[list[int]]:
    """Subtree roots per field dispatch, so that one invocation's loops stay
    within half of LOOP_BUDGET even if every node and edge of its chunk is
    visited: the root is split into its children until each subtree fits,
    and the subtrees are packed in order.  They depend on the tree's links
    alone (and the budget): cached per topology (a mesh's trees on every grid
    share one)."""
    limit = LOOP_BUDGET // 2 - 4 * SEGV
    per_limit = _CHUNKS.setdefault(tree.topology, {})
    if limit not in per_limit:
        per_limit[limit] = _plan_chunks(tree.links, limit)
    return [list(c) for c in per_limit[limit]]


def _plan_chunks(links: np.ndarray, limit: int) -> list[list[int]]:
    size: dict[int, tuple[int, int]] = {}

    def measure(n: int) -> tuple[int, int]:
        first, count, left, right = (int(x) for x in links[n, 0])
        if left < 0:
            size[n] = (1, count)
        else:
            a, b = measure(left), measure(right)
            size[n] = (1 + a[0] + b[0], count)
        return size[n]

    measure(0)
    cost = {n: m * NODE_COST + e * EDGE_COST + 1 for n, (m, e) in size.items()}
    cut, todo = [], [0]
    while todo:
        n = todo.pop(0)
        left, right = int(links[n, 0, 2]), int(links[n, 0, 3])
        if cost[n] <= limit or left < 0:
            cut.append(n)
        else:
            todo[:0] = [left, right]
    chunks, cur, used = [], [], 0
    for n in cut:
        if cur and used + cost[n] > limit:
            chunks.append(cur)
            cur, used = [], 0
        cur.append(n)
        used += cost[n]
    chunks.append(cur)
    return chunks


def strip_free_share(tree: ClusterTree | None, vox: np.ndarray, rows: tuple[int, int, int, int]) -> float:
    """The share of the (y, z) columns of bricks over ``rows`` = (j0, nj, k0, nk)
    (voxel rows and slices) that no boundary edge's strip can enter, judged by
    the edges' (y, z) bounding boxes: bricks decide voxels only there.
    ``vox``: the mesh's vertices in voxel space.  1.0 without boundary edges."""
    j0, nj, k0, nk = rows
    if tree is None or not len(tree.edges) or nj <= 0 or nk <= 0:
        return 1.0
    lo = np.array([j0 // BRICK, k0 // BRICK])
    n = np.array([(j0 + nj - 1) // BRICK, (k0 + nk - 1) // BRICK]) - lo + 1
    ends = vox[:, 1:][tree.edges.astype(np.int64)]  # (E, 2 ends, (y, z))
    a = np.clip(np.floor(ends.min(axis=1) / BRICK).astype(np.int64) - lo, 0, n)
    b = np.clip(np.floor(ends.max(axis=1) / BRICK).astype(np.int64) - lo + 1, 0, n)
    marks = np.zeros((n[0] + 1, n[1] + 1), np.int64)  # a 2D difference array of the rectangles
    np.add.at(marks, (a[:, 0], a[:, 1]), 1)
    np.add.at(marks, (b[:, 0], a[:, 1]), -1)
    np.add.at(marks, (a[:, 0], b[:, 1]), -1)
    np.add.at(marks, (b[:, 0], b[:, 1]), 1)
    covered = marks.cumsum(axis=0).cumsum(axis=1)[:-1, :-1] > 0
    return float(1.0 - covered.mean())


def x_range(spec, bufs) -> tuple[int, int]:
    """Segments (s0, ns) of SEG voxels that can hold a voxel within a voxel of the mesh's x extent."""
    seg = 4 * SEGV
    o = float(spec.origin[0] - bufs.anchor[0])
    lo = (bufs.bounds[0, 0] - o) / spec.voxel_size - 1.5
    hi = (bufs.bounds[1, 0] - o) / spec.voxel_size + 1.5
    n_segs = -(-spec.dims[0] // seg)
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return 0, 0
    s0 = int(np.clip(math.floor(lo / seg), 0, n_segs))
    s1 = int(np.clip(math.floor(hi / seg), -1, n_segs - 1))
    return s0, max(0, s1 - s0 + 1)
