"""What is wrong with a mesh, before voxelizing it: ``glvox inspect``.

:func:`inspect_mesh` reports the counts that decide which solid is
meaningful: triangles, connected components, boundary and non-manifold
edges, duplicate and degenerate faces, winding consistency, orientation
(signed volume), an estimate of self-intersections, and, on a grid, the
share of the solid whose generalized winding number lies within
:data:`UNCERTAIN_BAND` of the threshold.

Vertices are merged by position first, as trimesh's default processing
does (which also decides :attr:`glvox.mesh.Mesh.watertight`), so a mesh
stored as a soup of separate triangles still has its edges shared.  Edges
are undirected pairs of merged vertices; a face's edges are its three sides.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from .datasets import resolve_mesh
from .errors import SuspiciousResultWarning
from .grid import grid_for
from .mesh import Mesh, load_mesh
from .methods import run_method
from .traits import ALL_SHARE, MeshTraits, mesh_traits, solid_outlook

#: ``uncertain_share`` counts voxels whose winding number lies within this of
#: the threshold: the issue's definition of an ambiguous solid.
UNCERTAIN_BAND = 0.1

#: Edges :func:`inspect_mesh` tests for self-intersections, at most: a
#: larger mesh gets an estimate from a random sample of them.
SELF_INTERSECTION_SAMPLE = 50_000

#: (edge, triangle) candidate pairs tested, at most (about a second of numpy
#: here per 5 million): when the broad phase finds more, a smaller random
#: sample of the edges is tested, so a soup of huge triangles stays bounded too.
PAIR_BUDGET = 5_000_000

#: Pairs tested per numpy batch (bounded temporaries: a few hundred bytes a pair).
PAIR_BATCH = 1 << 20


@dataclass
class MeshReport:
    """:func:`inspect_mesh`'s answer (also the extra columns of a batch manifest).

    Attributes
    ----------
    name : str
    triangles : int
        Triangles kept (non-degenerate).
    vertices : int
        Distinct vertex positions the triangles use.
    degenerate_faces : int
        Zero-area triangles dropped on load.
    duplicate_faces : int
        Triangles on the same three positions as an earlier one (any order).
    components : int
        Parts connected through manifold edges (edges of exactly two triangles).
    boundary_edges, nonmanifold_edges : int
        Edges of one triangle; of three or more.
    inconsistent_edges : int
        Edges of exactly two triangles that run them the same way (one of
        the two is flipped against the other).
    winding_consistent : bool
        No inconsistent edge.
    watertight : bool
        Every edge shared by exactly two triangles (as :class:`glvox.mesh.Mesh`).
    signed_volume : float
        World units cubed: the volume the faces enclose, positive when they
        face outward; on an open mesh, the volume of the surface closed by
        cones to its bounding-box center, only indicative.
    orientation : {'outward', 'inward', 'double-sided', 'mixed', 'flat'}
        ``'double-sided'`` when every face has a coincident reversed twin (the
        volume cancels: neither way round), ``'mixed'`` when some closed parts
        face outward and some inward, ``'flat'`` when the faces enclose no
        volume, else the sign of ``signed_volume``.
    opposite_face_pairs : int
        Coincident faces with opposite winding, in pairs (:class:`glvox.traits.MeshTraits`).
    opposite_share, same_winding_duplicate_share : float
        Share of the faces in such pairs; coincident with a same-winding copy.
    inconsistent_parts, inverted_parts : int
        Parts whose faces disagree on orientation; closed parts inside out.
    signed_volume_ratio : float
        ``signed_volume`` / the bounding box's volume: about 1 for a box, 0
        when doubled faces or inside-out parts cancel.
    solid_methods : dict of str to str
        What each solid method makes of this mesh (:func:`glvox.traits.solid_outlook`):
        ``'ok'`` or the consequence and its cause.
    self_intersections : int
        Edges that cross a triangle they do not share a vertex with (a screen
        of float64 segment/triangle tests; coplanar overlaps are not counted),
        estimated from a random sample of edges on large meshes.
    self_intersection_edges_tested : int
        The edges tested: all of them, or the sample
        (:data:`SELF_INTERSECTION_SAMPLE`).
    resolution : int or None
        The grid of ``uncertain_share``, when asked for.
    uncertain_share : float or None
        With a grid: voxels whose winding number w lies within
        :data:`UNCERTAIN_BAND` of the threshold, as a share of the voxels
        with ``w >= threshold - UNCERTAIN_BAND`` (the solid and its band): 0
        for a closed, consistently oriented mesh, 1 when nothing is sure
        (also when no voxel comes near the threshold: the winding solid is
        empty, as for a double-sided mesh).
    uncertain_voxels : int or None
    """

    name: str
    triangles: int
    vertices: int
    degenerate_faces: int
    duplicate_faces: int
    components: int
    boundary_edges: int
    nonmanifold_edges: int
    inconsistent_edges: int
    winding_consistent: bool
    watertight: bool
    signed_volume: float
    orientation: str
    self_intersections: int
    self_intersection_edges_tested: int
    opposite_face_pairs: int = 0
    opposite_share: float = 0.0
    same_winding_duplicate_share: float = 0.0
    inconsistent_parts: int = 0
    inverted_parts: int = 0
    signed_volume_ratio: float = 0.0
    solid_methods: dict[str, str] | None = None
    resolution: int | None = None
    uncertain_share: float | None = None
    uncertain_voxels: int | None = None

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def format(self) -> str:
        """The lines ``glvox inspect`` prints."""
        rows = [(k, v) for k, v in self.to_dict().items() if v is not None]
        w = max(len(k) for k, _ in rows)
        out = []
        for k, v in rows:
            if isinstance(v, dict):  # one indented line per entry, problems first
                out.append(f"{k}:")
                for name, verdict in sorted(v.items(), key=lambda kv: (kv[1] == "ok", kv[0])):
                    out.append(f"  {name + ':':<{w - 1}} {verdict}")
                continue
            if isinstance(v, float):
                v = f"{v:.6g}"
            elif isinstance(v, bool):
                v = "yes" if v else "no"
            out.append(f"{k + ':':<{w + 1}} {v}")
        return "\n".join(out)


def merged_faces(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Faces on vertices merged by position, as trimesh merges them (coordinates
    equal once rounded to ``trimesh.tol.merge``), so that the report agrees with
    :attr:`glvox.mesh.Mesh.watertight`, which trimesh decides.

    Returns
    -------
    positions : (P, 3) float64
        The distinct positions the faces use (each a first occurrence).
    faces : (F, 3) int64
        Indices into ``positions``.
    """
    from trimesh.grouping import float_to_int  # lazy, as in glvox.mesh: trimesh is slow to import

    used = np.unique(mesh.faces)
    _, first, inverse = np.unique(float_to_int(mesh.vertices[used]), axis=0, return_index=True,
                                  return_inverse=True)
    remap = np.zeros(len(mesh.vertices), dtype=np.int64)
    remap[used] = inverse.reshape(-1)
    return mesh.vertices[used][first], remap[mesh.faces]


def edge_table(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The undirected edges of ``faces``.

    Returns
    -------
    edges : (E, 2) int64
        Distinct undirected edges (smaller index first).
    uses : (E,) int64
        Triangles having each edge.
    balance : (E,) int64
        Sum over those triangles of +1 where the triangle runs the edge from
        its smaller index, -1 otherwise: 0 for two consistently oriented
        neighbours, +-2 for an inconsistent pair.
    face_edge : (F, 3) int64
        Each face's edges, as indices into ``edges``.
    """
    a = faces
    b = np.roll(faces, -1, axis=1)
    lo, hi = np.minimum(a, b).ravel(), np.maximum(a, b).ravel()
    base = int(faces.max()) + 1 if faces.size else 1
    keys, inverse, uses = np.unique(lo * base + hi, return_inverse=True, return_counts=True)
    edges = np.stack([keys // base, keys % base], axis=1)
    inverse = inverse.reshape(-1)
    sign = np.where(a.ravel() < b.ravel(), 1, -1)
    balance = np.bincount(inverse, weights=sign, minlength=len(edges)).astype(np.int64)
    return edges, uses, balance, inverse.reshape(faces.shape)


def count_components(face_edge: np.ndarray, uses: np.ndarray) -> int:
    """Parts of the mesh connected through manifold edges (edges of exactly two faces),
    as trimesh splits a mesh: bodies that only touch along a non-manifold edge, and
    copies of a face, are parts of their own."""
    # lazy: scipy.sparse takes a few tenths of a second to import, which `import glvox` should not pay
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n_faces, n_edges = len(face_edge), len(uses)
    # a bipartite graph faces <-> manifold edges: two faces are joined iff they share one
    manifold = uses[face_edge.ravel()] == 2
    rows = np.repeat(np.arange(n_faces), 3)[manifold]
    cols = n_faces + face_edge.ravel()[manifold]
    g = coo_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(n_faces + n_edges,) * 2)
    _, labels = connected_components(g, directed=False)
    return int(len(np.unique(labels[:n_faces])))


def signed_volume(positions: np.ndarray, faces: np.ndarray) -> float:
    """Sum of the signed volumes of the tetrahedra (center, face), world units cubed;
    relative to the bounding-box center, which keeps float64 precise far from the origin."""
    c = 0.5 * (positions.min(axis=0) + positions.max(axis=0))
    t = positions[faces] - c
    return float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6.0)


def _cells(lo: np.ndarray, hi: np.ndarray, cell: float, origin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cells of a uniform grid that boxes ``[lo, hi]`` (M, 3) overlap: (keys, owner),
    one entry per (box, cell); keys pack the cell's three indices into 21 bits each."""
    a = np.floor((lo - origin) / cell).astype(np.int64)
    n = np.floor((hi - origin) / cell).astype(np.int64) - a + 1
    count = n.prod(axis=1)
    owner = np.repeat(np.arange(len(lo)), count)
    k = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)  # the k-th cell of its box
    nn, aa = n[owner], a[owner]
    ix = aa[:, 0] + k % nn[:, 0]
    iy = aa[:, 1] + (k // nn[:, 0]) % nn[:, 1]
    iz = aa[:, 2] + k // (nn[:, 0] * nn[:, 1])
    return (ix << 42) | (iy << 21) | iz, owner


class _Grid:
    """The broad phase on one cell size: triangle cells sorted, each edge's candidate count."""

    def __init__(self, tris: np.ndarray, p: np.ndarray, q: np.ndarray, origin: np.ndarray, cell: float):
        tc, tri = _cells(tris.min(axis=1), tris.max(axis=1), cell, origin)
        order = np.argsort(tc, kind="stable")
        self.tc, self.tri = tc[order], tri[order]
        ec, self.edge = _cells(np.minimum(p, q), np.maximum(p, q), cell, origin)
        self.start = np.searchsorted(self.tc, ec, side="left")
        self.stop = np.searchsorted(self.tc, ec, side="right")
        self.per_edge = np.bincount(self.edge, weights=self.stop - self.start, minlength=len(p))

    def pairs(self, tested: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(edge, triangle) pairs of the ``tested`` edges (repeats possible)."""
        keep = tested[self.edge]
        edge, start, stop = self.edge[keep], self.start[keep], self.stop[keep]
        n = stop - start
        first = np.repeat(np.cumsum(n) - n, n)
        return np.repeat(edge, n), self.tri[np.repeat(start, n) + np.arange(int(n.sum())) - first]


def _broad_phase(tris: np.ndarray, p: np.ndarray, q: np.ndarray, origin: np.ndarray, length: float,
                 smallest: float, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(edge, triangle) pairs whose boxes share a cell, at most :data:`PAIR_BUDGET`.

    The cell is ``length * (4, 2, 1)`` (at least ``smallest``), tried in that
    order until the pairs stop decreasing (long triangles favour large cells,
    fine meshes small ones); a size whose entries alone exceed the budget is
    not built.  When the pairs still exceed the budget, a random subset of
    the edges is kept.

    Returns
    -------
    e, t : (M,) int64
        Pairs (repeats of a pair sharing several cells possible).
    tested : (E,) bool
        The edges whose pairs are in.
    """
    def entries(cell):
        return sum(float((np.floor(hi / cell) - np.floor(lo / cell) + 1).prod(axis=1).sum())
                   for lo, hi in ((tris.min(axis=1), tris.max(axis=1)), (np.minimum(p, q), np.maximum(p, q))))

    grid = None
    for f in (4.0, 2.0, 1.0):
        cell = max(length * f, smallest)
        if grid is not None and entries(cell) > PAIR_BUDGET:
            break
        finer = _Grid(tris, p, q, origin, cell)
        if grid is not None and finer.per_edge.sum() >= grid.per_edge.sum():
            break
        grid = finer
    tested = np.ones(len(p), dtype=bool)
    if grid.per_edge.sum() > PAIR_BUDGET:
        order = rng.permutation(len(p))
        tested[order[np.cumsum(grid.per_edge[order]) > PAIR_BUDGET]] = False
    e, t = grid.pairs(tested)
    return e, t, tested


def _crossing(p, q, a, b, c) -> np.ndarray:
    """(M,) bool: segment p-q crosses triangle abc, its ends strictly on opposite sides
    of the plane and the crossing strictly inside the triangle (float64)."""
    n = np.cross(b - a, c - a)
    dp = np.einsum("ij,ij->i", p - a, n)
    dq = np.einsum("ij,ij->i", q - a, n)
    cross = dp * dq < 0
    x = p + (q - p) * (dp / np.where(cross, dp - dq, 1.0))[:, None]
    for u, v in ((a, b), (b, c), (c, a)):
        cross &= np.einsum("ij,ij->i", np.cross(v - u, x - u), n) > 0
    return cross


def self_intersecting_edges(positions: np.ndarray, faces: np.ndarray, edges: np.ndarray,
                            sample: int | None = None) -> tuple[int, int]:
    """Edges that cross the interior of a triangle they do not share a vertex with.

    A broad phase on a uniform grid (:func:`_broad_phase`) and a float64
    segment/triangle test
    (:func:`_crossing`).  Touching and coplanar contacts are not counted: it
    is a screen, not a predicate.

    Parameters
    ----------
    positions : (P, 3) float64
    faces : (F, 3) int64
    edges : (E, 2) int64
    sample : int, optional
        Test at most this many edges, drawn at random (seeded: the same mesh
        gives the same answer); fewer when they have more than
        :data:`PAIR_BUDGET` candidate pairs.  The answer is then the count
        among the tested edges scaled to all edges, an estimate.

    Returns
    -------
    count : int
        Self-intersecting edges (an estimate when not all were tested).
    tested : int
        Edges tested.
    """
    n_edges = len(edges)
    if len(faces) < 2 or n_edges == 0:
        return 0, n_edges
    rng = np.random.default_rng(0)
    if sample is not None and n_edges > sample:
        edges = edges[np.sort(rng.choice(n_edges, sample, replace=False))]
    tris = positions[faces]
    p, q = positions[edges[:, 0]], positions[edges[:, 1]]
    origin = positions.min(axis=0)
    # cells of at least 2^-20 of the extent keep every cell index within 21 bits
    extent = float((positions.max(axis=0) - origin).max())
    smallest = max(extent * 2.0**-20, 1e-300)
    length = max(float(np.median(np.linalg.norm(q - p, axis=1))), smallest)
    e, t, tested = _broad_phase(tris, p, q, origin, length, smallest, rng)
    own = (faces[t] == edges[e, :1]).any(axis=1) | (faces[t] == edges[e, 1:]).any(axis=1)
    e, t = e[~own], t[~own]
    hit = np.zeros(len(edges), dtype=bool)
    for s in range(0, len(e), PAIR_BATCH):
        ee, tt = e[s:s + PAIR_BATCH], t[s:s + PAIR_BATCH]
        hit[ee[_crossing(p[ee], q[ee], tris[tt, 0], tris[tt, 1], tris[tt, 2])]] = True
    n_tested = int(tested.sum())
    return int(round(hit.sum() * n_edges / max(n_tested, 1))), n_tested


def inspect_mesh(mesh: Any, resolution: int | None = None, *, backend: str | None = None) -> MeshReport:
    """Report a mesh's defects (see :class:`MeshReport`).

    Parameters
    ----------
    mesh : path, "gen:NAME", mesh name, trimesh.Trimesh, (vertices, faces) or Mesh
        As :func:`glvox.load_mesh` takes it (a name of ``glvox data list`` too).
    resolution : int, optional
        N: also compute ``uncertain_share`` on the N^3 grid glvox fits to the
        mesh (from ``gwn-solid``'s winding numbers, on the GPU).
    backend : str, optional
        GL backend for the winding numbers.

    Returns
    -------
    MeshReport
    """
    m = load_mesh(resolve_mesh(mesh) if isinstance(mesh, (str, os.PathLike)) else mesh)
    positions, faces = merged_faces(m)
    edges, uses, balance, face_edge = edge_table(faces)
    two = uses == 2
    vol = signed_volume(positions, faces)
    traits = mesh_traits(m)
    key = np.sort(faces, axis=1)
    crossing, tested = self_intersecting_edges(positions, faces, edges, SELF_INTERSECTION_SAMPLE)
    report = MeshReport(
        name=m.name, triangles=m.n_triangles, vertices=len(positions), degenerate_faces=m.n_degenerate,
        duplicate_faces=int(len(key) - len(np.unique(key, axis=0))),
        components=count_components(face_edge, uses),
        boundary_edges=int((uses == 1).sum()), nonmanifold_edges=int((uses > 2).sum()),
        inconsistent_edges=int((two & (balance != 0)).sum()),
        winding_consistent=bool(not (two & (balance != 0)).any()), watertight=m.watertight,
        signed_volume=vol if traits.signed_volume_ratio != 0.0 else 0.0, orientation=orientation(traits),
        self_intersections=crossing, self_intersection_edges_tested=tested,
        opposite_face_pairs=traits.opposite_pairs, opposite_share=traits.opposite_share,
        same_winding_duplicate_share=traits.duplicate_share, inconsistent_parts=traits.inconsistent_parts,
        inverted_parts=traits.inverted_parts, signed_volume_ratio=traits.signed_volume_ratio,
        solid_methods=solid_outlook(traits))
    if resolution is not None:
        report.resolution = int(resolution)
        report.uncertain_voxels, report.uncertain_share = uncertain(m, resolution, backend=backend)
    return report


def orientation(traits: MeshTraits) -> str:
    """Which way the faces point, for :class:`MeshReport` (see ``orientation`` there)."""
    if traits.opposite_share >= ALL_SHARE:
        return "double-sided"
    if traits.part_volume_ratio == 0.0:
        return "flat"
    if traits.inverted_parts and traits.signed_volume_ratio > 0 or (traits.inverted_parts
                                                                     and traits.signed_volume_ratio == 0.0):
        return "mixed"
    return "outward" if traits.signed_volume_ratio > 0 else "inward" if traits.signed_volume_ratio < 0 else "flat"


def uncertain_share(winding: np.ndarray, threshold: float = 0.5) -> tuple[int, float]:
    """``(uncertain_voxels, uncertain_share)`` of a winding-number field (:class:`MeshReport`).

    Parameters
    ----------
    winding : (nx, ny, nz) float
        w at the voxel centers.
    threshold : float
        The solid's threshold.

    Returns
    -------
    uncertain : int
        Voxels with ``|w - threshold| < UNCERTAIN_BAND``.
    share : float
        ``uncertain`` over the voxels with ``w > threshold - UNCERTAIN_BAND``
        (the solid and its band); 1.0 when there are none (no voxel is surely inside).
    """
    w = np.asarray(winding)
    band = np.abs(w - threshold) < UNCERTAIN_BAND
    n = int(np.count_nonzero(band))
    region = int(np.count_nonzero(w > threshold - UNCERTAIN_BAND))
    return n, (n / region if region else 1.0)  # no voxel near inside: nothing is sure


def uncertain(mesh: Mesh, resolution: int, *, backend: str | None = None) -> tuple[int, float]:
    """``(uncertain_voxels, uncertain_share)`` on the N^3 grid glvox fits to ``mesh``, from
    ``gwn-solid``'s winding numbers (on the GPU; within its expansion's error, a few 1e-3
    at the default accuracy, of the exact ones: only voxels that close to the band's edges
    can be counted differently)."""
    with warnings.catch_warnings():  # the report says what the traits mean for gwn-solid itself
        warnings.simplefilter("ignore", SuspiciousResultWarning)
        g = run_method("gwn-solid", mesh, grid_for(mesh, resolution), backend=backend, winding=True)
    return uncertain_share(g.fields["winding"])
