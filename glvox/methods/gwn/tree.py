"""The boundary chain of a mesh and its cluster tree, for ``gwn-solid``.

``gwn-solid`` evaluates ``w = C + F`` (:mod:`glvox.reference.winding`): ``C``
counts signed crossings, ``F`` sums the strips of the half-edges that do not
cancel, the mesh's boundary chain.  ``F`` is the costly part (voxels x
boundary edges), so the chain is clustered here, on the CPU, and the GPU
evaluates far clusters by a multipole expansion (``shaders/gwn/field.comp``).

Closing the clusters.  The chain is a cycle (every vertex has as many edges
in as out; the boundary of a sum of triangles has no boundary), so it splits
into closed loops (:func:`boundary_loops`).  A tree node holds either whole
loops, or a piece of one loop, a path ``w_a -> ... -> w_b``, closed by its
*chord* ``w_b -> w_a``.  Its edges plus its chord form closed polygons ``Q``,
spanned by the fan patch ``P`` of triangles ``(c, u, v)``, one per polygon
edge ``u -> v``, around the node's center ``c``; ``P`` lies in the ball of
radius ``r`` around ``c`` that holds the node's vertices.  The identity of
the reference applied to ``P`` gives ``F_Q = w_P - C_P``; at a point p from
whose ray towards -x the ball is out of reach (``C_P = 0``: behind the ball,
``p_x < c_x - r``, or beside it, (y, z) distance > r) and at distance
``>= beta r`` from ``c``, ``w_P`` is smooth and is expanded to second order
about ``c`` (the moments below; Barill et al. 2018 expand each triangle
cluster the same way).  So a far node contributes its multipole minus the
exact strip of its chord; a near leaf, its edges' exact strips; a near inner
node, its children.  Every jump of ``F`` (4 pi across a strip, where ``C``
jumps) comes from an exact strip, decided by the same edge function as the
crossings of ``C``; the expansion only touches the continuous part.

The expansion.  With ``y = c - p``, ``rho = |y|`` and the fan's moments
about ``c`` (``s = x - c``): ``D = sum a n`` (vector area),
``Q_ji = int s_j n_i``, ``T_jki = int s_j s_k n_i``,

    Omega ~ D.y / rho^3 + tr Q / rho^3 - 3 y.Q.y / rho^5
            - 3/2 (2 a + b).y / rho^5 + 15/2 T(y, y, y) / rho^7,

``a_k = T_iki``, ``b_i = T_jji`` (sums over repeated indices), from the
Taylor expansion of the kernel ``(x - p) / |x - p|^3`` about ``c``.  Only
the symmetric parts of ``Q`` and ``T`` meet ``y``; the node record keeps
those (:data:`NODE_VEC4`).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

#: Boundary edges per leaf: a near leaf costs its edges' strips at every
#: voxel of a segment, a far node one multipole and one chord strip.
LEAF_EDGES = 8

#: vec4 records per node: (c, r), (D, tr Q), symmetric Q (6), g = 2a + b (3),
#: symmetric T (10), the fan's unsigned area; then (L, 0, 0, 0), L the total
#: length of the node's boundary edges (its chord excluded), which bounds the
#: gradient of their strips (``shaders/gwn/bricks.comp``).
NODE_VEC4 = 8

#: (voxels) Added to every node radius: the GPU's float32 vertices differ from
#: the float64 ones used here by far less (2^-24 of coordinates below 2^16).
RADIUS_MARGIN = 1e-2


@dataclass
class BoundaryLoops:
    """The boundary chain of a mesh as closed loops of vertex indices.

    Attributes
    ----------
    loops : list of (n_i,) int64
        Each loop's vertices ``w_0 .. w_{n-1}`` (indices into the mesh's
        vertices), its edges ``w_i -> w_{i+1 mod n}``; a half-edge that
        appears m times (multiplicity m) is m edges.
    n_edges : int
        Total edges.
    """

    loops: list
    n_edges: int


_LOOPS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def boundary_loops(mesh) -> BoundaryLoops:
    """The half-edges of ``mesh`` that do not cancel, walked into closed loops.

    Positions are keyed by the float32 vertices the GPU holds
    (:meth:`glvox.mesh.Mesh.gpu_arrays`): two triangles whose shared edge has
    the same float32 end points see bit-identical edges on the GPU, so their
    strips cancel exactly and need not be evaluated.  Cached per mesh.
    """
    hit = _LOOPS.get(mesh)
    if hit is not None:
        return hit
    v32, faces = mesh.gpu_arrays()
    # + 0.0 turns -0.0 into 0.0: the same point, but other bytes in the key
    v32 = np.ascontiguousarray(v32 + np.float32(0.0))
    _, first, ids = np.unique(v32.view(np.dtype((np.void, 12))).ravel(),
                              return_index=True, return_inverse=True)
    f = ids.ravel()[faces.astype(np.int64)]
    start, end = f.ravel(), np.roll(f, -1, axis=1).ravel()
    lo, hi = np.minimum(start, end), np.maximum(start, end)
    n = np.int64(len(first))
    keys, inv = np.unique(lo * n + hi, return_inverse=True)
    net = np.rint(np.bincount(inv.ravel(), weights=np.where(start < end, 1.0, -1.0),
                              minlength=len(keys))).astype(np.int64)
    keep = net != 0
    a, b, m = keys[keep] // n, keys[keep] % n, net[keep]
    src = np.repeat(np.where(m > 0, a, b), np.abs(m))
    dst = np.repeat(np.where(m > 0, b, a), np.abs(m))
    loops = [first[loop] for loop in _walk(src, dst)]
    out = BoundaryLoops(loops, int(len(src)))
    _LOOPS[mesh] = out
    return out


def _walk(src: np.ndarray, dst: np.ndarray) -> list[np.ndarray]:
    """Split the edges ``src[i] -> dst[i]`` of a cycle (in-degree = out-degree
    at every vertex) into closed walks; each walk as its start vertices."""
    order = np.argsort(src, kind="stable")
    starts = np.searchsorted(src[order], np.arange(int(src.max()) + 2 if len(src) else 1))
    nxt = starts[:-1].copy()  # next unused out-edge slot of each vertex
    used = np.zeros(len(src), dtype=bool)
    loops = []
    for e0 in range(len(src)):
        if used[e0]:
            continue
        walk, e, home = [], e0, src[e0]
        while True:
            used[e] = True
            walk.append(src[e])
            x = dst[e]
            if x == home:
                break
            while used[order[nxt[x]]]:
                nxt[x] += 1
            e = order[nxt[x]]
            nxt[x] += 1
        loops.append(np.asarray(walk, dtype=np.int64))
    return loops


def boundary_voxels(spec, vertices: np.ndarray, loops: BoundaryLoops, extra_from: int) -> np.ndarray:
    """``vertices`` in ``spec``'s voxel space (float64), but only the rows the
    boundary ``loops`` use and those from ``extra_from`` on (a capped mesh's
    apexes, :func:`.caps.capped_mesh`); the rest NaN.  The tree and the caps'
    records read no other, and a whole mesh's would cost more than both."""
    out = np.full((len(vertices), 3), np.nan)
    idx = np.concatenate(loops.loops + [np.arange(extra_from, len(vertices))]).astype(np.int64)
    out[idx] = spec.world_to_voxel(np.asarray(vertices)[idx])
    return out


@dataclass
class ClusterTree:
    """The boundary chain as GPU buffers.

    Attributes
    ----------
    edges : (E, 2) uint32
        Vertex indices (into the mesh's vertices, so the GPU reads the same
        float32 voxel-space positions as its triangles) of each boundary
        edge, in tree order: every node's edges are a contiguous range.
    nodes : (M, NODE_VEC4, 4) float32
        Per node: center c and radius r (voxels), then the fan's moments,
        then the length of its boundary edges.
    links : (M, 2, 4) int32
        Per node: (first edge, edge count, left child, right child) with
        children -1 for a leaf; (chord start, chord end, 0, 0) vertex indices,
        -1 without a chord.  Node 0 is the root.
    depth : int
        Nodes on the longest root-to-leaf path.
    topology : TreeTopology
        What of the tree does not depend on the grid (shared by the trees of
        one mesh on every grid: :func:`mesh_tree`).
    """

    edges: np.ndarray
    nodes: np.ndarray
    links: np.ndarray
    depth: int
    topology: "TreeTopology"

    @property
    def n_nodes(self) -> int:
        return int(len(self.links))


@dataclass(eq=False)
class TreeTopology:
    """A cluster tree without its node records: which edges each node holds.

    Attributes
    ----------
    edges : (E, 2) uint32
        :attr:`ClusterTree.edges`.
    edge_loop : (E,) int64
        The loop of each edge.
    links : (M, 2, 4) int32
        :attr:`ClusterTree.links`.
    polys : (M, 5) int64
        Per node: first edge, edge count, chord start and end (-1 without),
        1 for a node of whole loops.
    depth : int
    """

    edges: np.ndarray
    edge_loop: np.ndarray
    links: np.ndarray
    polys: np.ndarray
    depth: int


def loop_centroids(loops: BoundaryLoops, points: np.ndarray) -> np.ndarray:
    """(L, 3) float64: the mean of each loop's vertices at ``points``."""
    if not loops.n_edges:
        return np.zeros((0, 3))
    sizes = np.array([len(lp) for lp in loops.loops], dtype=np.int64)
    return np.add.reduceat(points[np.concatenate(loops.loops)], np.cumsum(sizes) - sizes) / sizes[:, None]


def tree_topology(loops: BoundaryLoops, points: np.ndarray, leaf: int = LEAF_EDGES) -> TreeTopology:
    """The nodes of the cluster tree of ``loops``, their vertices at ``points``.

    Whole loops are grouped by a median split of their centroids along the
    widest axis (balanced by edge count) until a group is a single loop;
    a loop with more than ``leaf`` edges is halved into pieces closed by
    chords.  Nodes with at most ``leaf`` edges are leaves.  Only the order
    of the centroids along an axis and the axis of widest spread matter, so
    any translation and uniform scaling of ``points`` gives the same tree
    (ties apart).
    """
    edges: list[tuple[int, int]] = []
    edge_loop: list[int] = []
    links: list[list[int]] = []
    polys: list[tuple[int, int, int, int, int]] = []  # per node: edge range, chord, whole loops?
    sizes = np.array([len(lp) for lp in loops.loops], dtype=np.int64)
    cent = loop_centroids(loops, points)
    depth = 0

    def node(first: int, count: int, chord: tuple[int, int], whole: bool) -> int:
        links.append([first, count, -1, -1, chord[0], chord[1], 0, 0])
        polys.append((first, count, chord[0], chord[1], int(whole)))
        return len(links) - 1

    def emit(i: int, a: int, b: int) -> None:
        loop = loops.loops[i]
        edges.extend((int(loop[k]), int(loop[(k + 1) % len(loop)])) for k in range(a, b))
        edge_loop.extend([i] * (b - a))

    def piece(i: int, a: int, b: int, level: int) -> int:
        nonlocal depth
        depth = max(depth, level)
        loop = loops.loops[i]
        wa, wb = int(loop[a]), int(loop[b % len(loop)])
        chord = (wb, wa) if b - a < len(loop) else (-1, -1)
        first = len(edges)
        if b - a <= leaf:
            emit(i, a, b)
            return node(first, b - a, chord, False)
        me = node(first, b - a, chord, False)
        m = (a + b) // 2
        links[me][2] = piece(i, a, m, level + 1)
        links[me][3] = piece(i, m, b, level + 1)
        return me

    def group(members: np.ndarray, level: int) -> int:
        nonlocal depth
        depth = max(depth, level)
        total = int(sizes[members].sum())
        if len(members) == 1 and total > leaf:
            return piece(int(members[0]), 0, total, level)
        first = len(edges)
        if total <= leaf:
            for i in members:
                emit(int(i), 0, int(sizes[i]))
            return node(first, total, (-1, -1), True)
        me = node(first, total, (-1, -1), True)
        cen = cent[members]
        order = members[np.argsort(cen[:, int(np.argmax(np.ptp(cen, axis=0)))], kind="stable")]
        csum = np.cumsum(sizes[order])
        cut = int(np.clip(np.searchsorted(csum, total / 2.0), 0, len(order) - 2)) + 1
        links[me][2] = group(order[:cut], level + 1)
        links[me][3] = group(order[cut:], level + 1)
        return me

    if loops.n_edges:
        group(np.arange(len(loops.loops)), 1)
    return TreeTopology(np.asarray(edges, dtype=np.uint32).reshape(-1, 2), np.asarray(edge_loop, np.int64),
                        np.asarray(links, np.int32).reshape(-1, 2, 4), np.asarray(polys, np.int64).reshape(-1, 5),
                        depth)


#: The power of the length unit each of a node record's 32 entries scales
#: with (:func:`pack_moments`' order; the center also moves with the origin):
#: center, radius, D (area), tr Q and Q, g and T, the fan's area, the edges'
#: length.
_SCALE_POWER = np.array([0, 0, 0, 1, 2, 2, 2, 3, 3, 3, 3, 3, 3, 3, 4, 4,
                         4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 2, 1, 0, 0, 0], np.float64).reshape(NODE_VEC4, 4)


@dataclass(eq=False)
class MeshTree:
    """A mesh's cluster tree in its own (world) units: what :func:`tree_on_grid`
    maps onto any grid.

    Attributes
    ----------
    topology : TreeTopology
    records : (M, NODE_VEC4, 4) float64
        The node records at the mesh's vertices, radii without
        :data:`RADIUS_MARGIN` (a voxel-space margin).
    """

    topology: TreeTopology
    records: np.ndarray


_MESH_TREES: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def mesh_tree(mesh, loops: BoundaryLoops, leaf: int = LEAF_EDGES) -> MeshTree:
    """The tree of ``mesh``'s boundary ``loops`` at its own vertices, cached per
    mesh.  A grid maps world to voxel space by a translation and a uniform
    scaling, which keeps the tree's nodes (:func:`tree_topology`) and scales
    each record entry by a power of the voxel size, so one tree serves every
    grid (:func:`tree_on_grid`)."""
    per_mesh = _MESH_TREES.setdefault(mesh, {})
    if leaf not in per_mesh:
        points = np.asarray(mesh.vertices, np.float64)
        top = tree_topology(loops, points, leaf)
        per_mesh[leaf] = MeshTree(top, _node_records(top, loop_centroids(loops, points), points))
    return per_mesh[leaf]


def tree_on_grid(tree: MeshTree, spec) -> ClusterTree:
    """``tree`` in ``spec``'s voxel space: its records moved and scaled, rounded
    to float32, :data:`RADIUS_MARGIN` added to the radii."""
    return _on_grid(tree.topology, tree.records, np.asarray(spec.origin, np.float64), 1.0 / spec.voxel_size)


def build_tree(loops: BoundaryLoops, vox: np.ndarray, leaf: int = LEAF_EDGES,
               topology: TreeTopology | None = None) -> ClusterTree:
    """The cluster tree of ``loops`` for vertices at ``vox`` ((V, 3) float64, voxel space).

    Its nodes are ``topology``'s (default :func:`tree_topology` at ``vox``);
    their records (center, radius, moments, edge length) are computed at
    ``vox``, all nodes at once.  Only the rows of ``vox`` that the loops use
    are read.  (``gwn-solid`` maps its mesh's :func:`mesh_tree` instead: the
    same records up to float64 rounding.)
    """
    top = tree_topology(loops, vox, leaf) if topology is None else topology
    return _on_grid(top, _node_records(top, loop_centroids(loops, vox), vox), np.zeros(3), 1.0)


def _on_grid(top: TreeTopology, records: np.ndarray, origin: np.ndarray, scale: float) -> ClusterTree:
    rec = records * scale ** _SCALE_POWER
    rec[:, 0, :3] = (records[:, 0, :3] - origin) * scale
    rec[:, 0, 3] += RADIUS_MARGIN
    return ClusterTree(top.edges, rec.astype(np.float32), top.links, top.depth, top)


def _node_records(top: TreeTopology, loop_cent: np.ndarray, vox: np.ndarray) -> np.ndarray:
    """Center, radius and moments of every node (:data:`NODE_VEC4` vec4 each, float64,
    radii without :data:`RADIUS_MARGIN`), for all nodes at once: one row per (node,
    polygon edge), reduced per node.  ``vox``: the vertices in any units (voxel
    space, or the mesh's own for :func:`mesh_tree`), ``loop_cent`` the loops'
    centroids in the same.

    The patch spanning a node's polygons is a fan around the node's center for
    a piece of a loop (its path and chord), and around each loop's own
    centroid for a node of whole loops: the expansion does not depend on the
    patch (two patches differ by a closed surface, whose solid angle is 0
    outside the ball), but the error bound grows with the patch's area, and
    fans of far-apart loops around one center are long slivers.
    """
    polys, edges, edge_loop = top.polys, top.edges, top.edge_loop
    out = np.zeros((len(polys), NODE_VEC4, 4), dtype=np.float64)
    if not len(polys):
        return out
    first, count, cu, cv, whole = polys.T
    has = cu >= 0
    sizes = count + has
    owner = np.repeat(np.arange(len(polys)), sizes)
    start = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    local = np.arange(int(sizes.sum())) - start[owner]
    chord = local == count[owner]  # the last row of a node with a chord
    eidx = np.where(chord, 0, first[owner] + local)
    src = np.where(chord, cu[owner], edges[eidx, 0] if len(edges) else 0)
    dst = np.where(chord, cv[owner], edges[eidx, 1] if len(edges) else 0)
    u, v = vox[src], vox[dst]
    lo = np.minimum.reduceat(np.minimum(u, v), start)
    hi = np.maximum.reduceat(np.maximum(u, v), start)
    c = 0.5 * (lo + hi)
    co = c[owner]
    apex = np.where((whole[owner] == 1)[:, None], loop_cent[edge_loop[eidx]] if len(edges) else co, co) - co
    a, b = u - co, v - co
    r2 = np.maximum((a * a).sum(axis=1), (b * b).sum(axis=1))
    r = np.sqrt(np.maximum.reduceat(r2, start)) * (1 + 1e-6)
    D, Q, T, area = fan_moments(a, b, apex, start)
    length = np.add.reduceat(np.where(chord, 0.0, np.linalg.norm(v - u, axis=1)), start)
    out[:, :7] = pack_moments(c, r, D, Q, T, area)
    out[:, 7, 0] = length * (1 + 1e-6)  # rounded up: a bound's input
    return out


def fan_moments(a: np.ndarray, b: np.ndarray, apex: np.ndarray | None = None,
                start: np.ndarray | None = None):
    """Exact moments of the triangles (apex_i, a_i, b_i), relative to a center.

    Parameters
    ----------
    a, b : (K, 3) float64
        Polygon edges' start and end points minus the center.
    apex : (K, 3) float64, optional
        Each triangle's apex minus the center (default: the center, 0).
    start : (M,) int, optional
        Sum the rows in groups beginning at these indices (``np.add.reduceat``);
        default one group.

    Returns
    -------
    D : (3,) or (M, 3)
        ``sum int n dA`` (vector area).
    Q : (3, 3) or (M, 3, 3)
        ``Q[j, i] = sum int s_j n_i dA``.
    T : (3, 3, 3) or (M, 3, 3, 3)
        ``T[j, k, i] = sum int s_j s_k n_i dA``.
    area : float or (M,)
        ``sum int |n| dA``, the patch's unsigned area (for the error bound).
    """
    p0 = np.zeros_like(a) if apex is None else apex
    n = 0.5 * np.cross(a - p0, b - p0)  # area vector of each triangle
    tot = p0 + a + b
    second = (np.einsum("tj,tk->tjk", p0, p0) + np.einsum("tj,tk->tjk", a, a) + np.einsum("tj,tk->tjk", b, b)
              + np.einsum("tj,tk->tjk", tot, tot)) / 12.0  # int s s^T dA / area
    parts = (n, np.einsum("tj,ti->tji", tot / 3.0, n), np.einsum("tjk,ti->tjki", second, n),
             np.linalg.norm(n, axis=1))
    if start is None:
        return tuple(x.sum(axis=0) for x in parts)
    return tuple(np.add.reduceat(x, start) for x in parts)


def pack_moments(c, r, D, Q, T, area) -> np.ndarray:
    """Node records' first 7 vec4: what the GPU's expansion needs,
    symmetrized, and the fan's unsigned area last (:func:`far_bound`).

    One node (``c`` (3,), ``r`` scalar, ...: a (7, 4) record) or many at once
    (a leading axis M on every argument: (M, 7, 4) records, each the same
    float64 arithmetic as the node alone).
    """
    c, r, D, Q, T, area = (np.asarray(x, np.float64) for x in (c, r, D, Q, T, area))
    one = c.ndim == 1
    if one:
        c, r, D, Q, T, area = c[None], r[None], D[None], Q[None], T[None], area[None]
    Qs = 0.5 * (Q + Q.transpose(0, 2, 1))
    # g_k = 2 sum_i T[i, k, i] + sum_j T[j, j, k]
    g = (2.0 * (T[:, 0, :, 0] + T[:, 1, :, 1] + T[:, 2, :, 2])
         + (T[:, 0, 0, :] + T[:, 1, 1, :] + T[:, 2, 2, :]))
    S = (T + T.transpose(0, 1, 3, 2) + T.transpose(0, 2, 1, 3) + T.transpose(0, 2, 3, 1)
         + T.transpose(0, 3, 1, 2) + T.transpose(0, 3, 2, 1)) / 6.0
    trace = Q[:, 0, 0] + Q[:, 1, 1] + Q[:, 2, 2]
    rec = np.stack([c[:, 0], c[:, 1], c[:, 2], r, D[:, 0], D[:, 1], D[:, 2], trace,
                    Qs[:, 0, 0], Qs[:, 1, 1], Qs[:, 2, 2], Qs[:, 0, 1], Qs[:, 0, 2], Qs[:, 1, 2], g[:, 0], g[:, 1],
                    g[:, 2], S[:, 0, 0, 0], S[:, 1, 1, 1], S[:, 2, 2, 2], S[:, 0, 0, 1], S[:, 0, 0, 2],
                    S[:, 0, 1, 1], S[:, 0, 2, 2], S[:, 1, 1, 2], S[:, 1, 2, 2], S[:, 0, 1, 2], area],
                   axis=1).reshape(-1, 7, 4)
    return rec[0] if one else rec


def far_field(rec: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The expansion of one node record at points ``p`` ((P, 3) voxel space), in turns.

    The float64 model of ``shaders/gwn/field.comp``'s far field.
    """
    f = np.asarray(rec, np.float64).ravel()
    c, D, trq = f[0:3], f[4:7], f[7]
    qxx, qyy, qzz, qxy, qxz, qyz = f[8:14]
    g = f[14:17]
    sxxx, syyy, szzz, sxxy, sxxz, sxyy, sxzz, syyz, syzz, sxyz = f[17:27]
    y = c - np.asarray(p, np.float64)
    x1, y1, z1 = y[:, 0], y[:, 1], y[:, 2]
    r2 = (y * y).sum(axis=1)
    yqy = qxx * x1 * x1 + qyy * y1 * y1 + qzz * z1 * z1 + 2 * (qxy * x1 * y1 + qxz * x1 * z1 + qyz * y1 * z1)
    syyy_ = (sxxx * x1 ** 3 + syyy * y1 ** 3 + szzz * z1 ** 3 + 3 * (sxxy * x1 * x1 * y1 + sxxz * x1 * x1 * z1
             + sxyy * x1 * y1 * y1 + sxzz * x1 * z1 * z1 + syyz * y1 * y1 * z1 + syzz * y1 * z1 * z1)
             + 6 * sxyz * x1 * y1 * z1)
    num = r2 * r2 * (y @ D + trq) - r2 * (3 * yqy + 1.5 * (y @ g)) + 7.5 * syyy_
    return num / (r2 ** 3 * np.sqrt(r2)) / (4 * np.pi)


def far_bound(rec: np.ndarray, p: np.ndarray) -> np.ndarray:
    """A bound of :func:`far_field`'s error at points ``p`` (turns); needs ``|p - c| > r``.

    The expansion keeps the terms l = 1, 2, 3 of ``1 / |x - p| = sum_l
    h_l(x - c)``, the solid harmonics ``h_l(s) = |s|^l P_l(cos g) / rho^(l+1)``;
    the kernel's remainder is ``sum_{l > 3} grad h_l``, and
    ``|grad h_l| <= l |s|^(l-1) / rho^(l+1)`` (``l^2 P_l^2 + (1 - t^2) P_l'^2
    <= l^2`` on [-1, 1]).  With ``|s| <= r`` over the fan, ``q = r / rho``:

        |Omega - expansion| <= area / rho^2 * sum_{l > 3} l q^(l-1)
                             = area / rho^2 * q^3 (4 - 3 q) / (1 - q)^2.
    """
    f = np.asarray(rec, np.float64).ravel()
    rho2 = ((np.asarray(p, np.float64) - f[0:3]) ** 2).sum(axis=1)
    q = f[3] / np.sqrt(rho2)
    return f[27] / (4 * np.pi) * q ** 3 * (4 - 3 * q) / ((1 - q) ** 2 * rho2)
