"""Mesh traits that decide what a solid method makes of a mesh.

Dataset meshes (ShapeNet and its kin) often hold every face twice with
opposite winding, orient their parts inconsistently or inside out, or are
open.  Winding numbers and signed crossings then cancel, parities turn even,
exterior carving leaks through holes, and a solid method returns an empty or
wrong grid without failing.  :func:`mesh_traits` measures these properties
once per :class:`~glvox.mesh.Mesh`, in numpy (sorts over the faces and
edges, ~0.1 s for 100k triangles), and :func:`solid_outlook` turns them into a
verdict per solid method, for ``glvox inspect``, for the warnings after a
solid run, and for the ``solid`` alias's choice.

>>> import numpy as np
>>> from glvox.mesh import load_mesh
>>> from glvox.traits import mesh_traits, solid_outlook
>>> v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
>>> f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
>>> t = mesh_traits(load_mesh((v, np.vstack([f, f[:, ::-1]]))))  # every face twice, reversed
>>> t.opposite_pairs, t.opposite_share, t.signed_volume_ratio
(4, 1.0, 0.0)
>>> solid_outlook(t)["ss-solid"]
'empty (double-sided faces cancel)'
"""

from __future__ import annotations

import weakref
from dataclasses import asdict, dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .mesh import Mesh, _row_labels
from .tolerances import WELD_RTOL

__all__ = ["MeshTraits", "mesh_traits", "solid_outlook", "solid_warning", "SOLID_MECHANISMS", "MECHANISM_WORDS",
           "ALL_SHARE", "ROBUST"]


@dataclass(frozen=True)
class MeshTraits:
    """What a mesh is made of, as far as solid methods care (:func:`mesh_traits`).

    Faces are compared after welding vertices by position
    (:data:`~glvox.tolerances.WELD_RTOL` of the longest bounding-box side).

    Attributes
    ----------
    triangles : int
        Faces of the mesh (degenerate ones already dropped by :func:`~glvox.mesh.load_mesh`).
    opposite_pairs : int
        Pairs of coincident faces with opposite winding (same three positions,
        reverse cyclic order); a face pairs at most once.
    opposite_share : float
        Share of the faces in such pairs, 0..1 (1: every face doubled, reversed).
    duplicate_share : float
        Share of the faces coincident with another face of the same winding, 0..1.
    parts : int
        Connected components of faces sharing an edge (after welding).
    inconsistent_parts : int
        Parts where the two faces of an edge traverse it in the same direction
        (orientation not consistent; edges of three or more faces are not judged).
        Judged on the faces left after setting coincident faces aside: the
        two faces of an opposite pair are dropped, same-winding copies kept once.
    inverted_parts : int
        Closed, consistently oriented parts whose signed volume is negative
        (inside out), beyond 1e-6 of the bounding box's volume.
    open_edges : int
        Boundary edges: edges of exactly one face once coincident faces count
        once (so a doubled open sheet's rim counts, a doubled closed shell has none).
    signed_volume_ratio : float
        Signed volume (divergence theorem) / bounding-box volume; about 1 for
        a box, 0 when double-sided faces or inside-out parts cancel, negative
        when the mesh is inside out; 0 for a flat mesh (no box volume).
    part_volume_ratio : float
        Sum over parts of their absolute signed volumes / bounding-box volume:
        what ``signed_volume_ratio`` would be with every part turned outward.
    watertight : bool
        As :attr:`glvox.mesh.Mesh.watertight` (every edge of exactly two faces).
    """

    triangles: int
    opposite_pairs: int
    opposite_share: float
    duplicate_share: float
    parts: int
    inconsistent_parts: int
    inverted_parts: int
    open_edges: int
    signed_volume_ratio: float
    part_volume_ratio: float
    watertight: bool

    def to_dict(self) -> dict:
        return asdict(self)


_CACHE: "weakref.WeakKeyDictionary[Mesh, MeshTraits]" = weakref.WeakKeyDictionary()


def mesh_traits(mesh: Mesh) -> MeshTraits:
    """The :class:`MeshTraits` of ``mesh``, computed once per Mesh object (cached weakly).

    Parameters
    ----------
    mesh : Mesh
        From :func:`glvox.mesh.load_mesh`.
    """
    traits = _CACHE.get(mesh)
    if traits is None:
        traits = _compute(mesh)
        _CACHE[mesh] = traits
    return traits


def _weld(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F, 3) int64 faces over welded vertex labels (positions equal to WELD_RTOL)."""
    used = np.zeros(len(vertices), dtype=bool)
    used[faces] = True
    idx = np.flatnonzero(used)
    v = vertices[idx]
    lo = v.min(axis=0)
    extent = float((v.max(axis=0) - lo).max())
    keys = np.round((v - lo) / (extent * WELD_RTOL if extent > 0 else 1.0)).astype(np.int64)
    remap = np.zeros(len(vertices), dtype=np.int64)
    remap[idx] = _row_labels(keys)
    return remap[faces]


def _runs(sorted_keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start index and length of each run of equal values in a sorted array."""
    if not len(sorted_keys):
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    starts = np.flatnonzero(np.r_[True, sorted_keys[1:] != sorted_keys[:-1]])
    return starts, np.diff(np.r_[starts, len(sorted_keys)])


def _one_per_label(labels: np.ndarray, n_labels: int) -> np.ndarray:
    """(len(labels),) bool: one element of each label set, any one (no sort)."""
    rep = np.full(n_labels, -1, dtype=np.int64)
    rep[labels] = np.arange(len(labels))  # whichever write wins, it holds that label
    out = np.zeros(len(labels), dtype=bool)
    out[rep[rep >= 0]] = True
    return out


def _compute(mesh: Mesh) -> MeshTraits:
    faces = mesh.faces
    n_faces = len(faces)
    f = _weld(mesh.vertices, faces)
    n = int(f.max()) + 1
    # faces whose corners weld together have no orientation or edges to share
    proper = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    fi = np.flatnonzero(proper)
    fp = f[fi]

    # coincident faces: the sorted corners name the face, the rotation that
    # starts at the smallest corner tells the winding (+1: it then goes up)
    x, y, z = (np.ascontiguousarray(c) for c in fp.T)
    lo3, hi3 = np.minimum(np.minimum(x, y), z), np.maximum(np.maximum(x, y), z)
    srt = np.stack([lo3, x + y + z - lo3 - hi3, hi3], axis=1)
    # a rotation of ascending order has two ascending steps of three, cyclically
    sign = np.where((x < y).astype(np.int8) + (y < z) + (z < x) == 2, 1, -1)
    group = _row_labels(srt) if len(fp) else np.zeros(0, np.int64)
    n_groups = int(group.max()) + 1 if len(group) else 0
    pos = np.bincount(group, weights=sign > 0, minlength=n_groups).astype(np.int64)
    neg = np.bincount(group, weights=sign < 0, minlength=n_groups).astype(np.int64)
    pairs = np.minimum(pos, neg)
    opposite_pairs = int(pairs.sum())
    dup = int(pos[pos >= 2].sum() + neg[neg >= 2].sum())

    # every face edge once, sorted by (undirected edge, direction): one sort
    # serves the parts, the orientation clashes and the boundary
    a = fp.ravel()
    b = fp[:, [1, 2, 0]].ravel()
    m = len(fp)
    key2 = (np.minimum(a, b) * n + np.maximum(a, b)) * 2 + (a < b)
    order = np.argsort(key2)
    ks, so = key2[order], order // 3
    und = ks >> 1

    # parts: faces linked through shared undirected edges (every face of an
    # edge linked to the next one in the sort order)
    same = und[1:] == und[:-1]
    graph = coo_matrix((np.ones(int(same.sum())), (so[:-1][same], so[1:][same])), shape=(m, m))
    n_parts, part = connected_components(graph, directed=False) if m else (0, np.zeros(0, np.int64))

    # orientation: among the faces that remain once opposite pairs are set aside
    # and same-winding copies kept once, an edge of two faces (a manifold
    # edge: at three or more, as where closed parts touch, there is no
    # orientation to agree on) traversed twice in one direction is a clash
    single = _one_per_label(group * 2 + (sign > 0), 2 * n_groups) & (pairs[group] == 0)
    keep = single[so]
    kd, ko = ks[keep], so[keep]
    s2, len2 = _runs(kd >> 1)
    s2 = s2[len2 == 2]
    clash = s2[kd[s2] == kd[s2 + 1]]
    bad_parts = np.unique(part[ko[clash]]) if m else np.zeros(0, np.int64)

    # boundary: undirected edges of one face once coincident faces count once
    once = _one_per_label(group, n_groups)[so]
    ue, uo = und[once], so[once]
    s1, len1 = _runs(ue)
    open_edges = int((len1 == 1).sum())
    closed = np.ones(n_parts, dtype=bool)
    closed[part[uo[s1[len1 == 1]]]] = False

    # volumes, relative to the box center (less cancellation far from the origin)
    lo, hi = mesh.bounds
    c = [np.ascontiguousarray(col) - m0 for col, m0 in zip(mesh.vertices.T, 0.5 * (lo + hi))]
    p0, p1, p2 = (np.ascontiguousarray(k) for k in faces[fi].T)
    vol = (c[0][p0] * (c[1][p1] * c[2][p2] - c[2][p1] * c[1][p2])
           + c[1][p0] * (c[2][p1] * c[0][p2] - c[0][p1] * c[2][p2])
           + c[2][p0] * (c[0][p1] * c[1][p2] - c[1][p1] * c[0][p2])) / 6.0
    box = float(np.prod(hi - lo))
    per_part = np.bincount(part, weights=vol, minlength=n_parts) if m else np.zeros(0)
    if box > 0:
        ratio = float(vol.sum() / box)
        part_ratio = float(np.abs(per_part).sum() / box)
        judged = closed.copy()  # an open or inconsistent part has no inside to be inverted
        judged[bad_parts] = False
        inverted = int(((per_part / box) < -1e-6)[judged].sum())
    else:
        ratio = part_ratio = 0.0
        inverted = 0
    # a cancelled volume is 0, not float64 dust such as 1e-17
    ratio = 0.0 if abs(ratio) < 1e-12 else ratio
    part_ratio = 0.0 if part_ratio < 1e-12 else part_ratio
    return MeshTraits(
        triangles=n_faces,
        opposite_pairs=opposite_pairs,
        opposite_share=2 * opposite_pairs / n_faces,
        duplicate_share=dup / n_faces,
        parts=int(n_parts),
        inconsistent_parts=int(len(bad_parts)),
        inverted_parts=inverted,
        open_edges=open_edges,
        signed_volume_ratio=ratio,
        part_volume_ratio=part_ratio,
        watertight=bool(mesh.watertight),
    )


# -- what each solid method makes of the traits -----------------------------------

#: How each solid method decides inside, by name (checked against the
#: registry by tests/test_traits.py, so a new solid method must be placed):
#:
#: * ``parity``: the parity of surface crossings along rays (one axis, or a
#:   vote of three): winding is ignored, but coincident faces cross twice,
#:   so doubled faces (either winding) cancel;
#: * ``winding``: the generalized winding number: opposite faces cancel,
#:   reversed faces subtract, parts inside out count -1;
#: * ``hull``: Karabassi's six z-buffers (nearest surface from each side):
#:   winding and doubling do not matter, a hole lets a view see through;
#: * ``carve``: exterior flood fill around the conservative surface:
#:   winding and doubling do not matter, a hole lets the exterior in;
#: * ``binvox``: binvox's carving (six depth views) OR its parity vote.
SOLID_MECHANISMS = {
    "ss-solid": "parity", "ss-solid-tiled": "parity", "reference-solid": "parity",
    "eisemann-solid": "parity", "passalis-peel": "parity", "passalis-stencil": "parity",
    "vote-solid": "parity", "reference-vote": "parity",
    "gwn-solid": "winding", "reference-gwn": "winding",
    "karabassi": "hull",
    "carve-solid": "carve", "reference-carve": "carve",
    "binvox-solid": "binvox", "reference-binvox": "binvox",
}

#: One line per mechanism, for ``glvox inspect``.
MECHANISM_WORDS = {
    "parity": "parity of crossings: ignores winding; coincident faces cancel",
    "winding": "winding number: opposite faces cancel, reversed faces subtract",
    "hull": "six depth views: ignores winding and doubling; holes let views through",
    "carve": "exterior carving: ignores winding and doubling; holes let the outside in",
    "binvox": "carving or parity vote: ignores winding and doubling; holes let the outside in",
}

#: Shares at or above this count as "every face" (a few stray single faces
#: in an otherwise double-sided model change nothing a user sees).
ALL_SHARE = 0.999

#: From this share of cancelling faces up, a method that they defeat is
#: called unreliable (and always warned about); below it the doubled patches
#: act as holes (warned about when the result comes out nearly empty): scans
#: such as the Stanford dragon hold ~1% of doubled faces and voxelize fine.
MOST_SHARE = 0.5

#: Methods to name instead of one that the traits rule out.
ROBUST = "-m binvox-solid or -m carve-solid"


def _pct(x: float) -> str:
    return f"{100 * x:.3g}%"


def solid_outlook(traits: MeshTraits) -> dict[str, str]:
    """A short verdict per solid method on a mesh with these traits.

    Parameters
    ----------
    traits : MeshTraits

    Returns
    -------
    dict
        Method name (every key of :data:`SOLID_MECHANISMS`) -> ``'ok'`` or
        a verdict whose first words are the consequence (``empty``, ``partly
        empty``, ``unreliable``: the method gets this mesh wrong; ``may leak``,
        ``may streak``, ``may dent``: it may, where the defect is; ``surface
        only``) and whose parenthesis is the cause, e.g. ``'empty
        (double-sided faces cancel)'``.  Causes are tried in this order:
        coincident faces, zero volume, inside-out parts, inconsistent
        orientation, open boundary; the first that applies to the method wins.
    """
    return {name: _verdict(mech, traits) for name, mech in SOLID_MECHANISMS.items()}


def _verdict(mech: str, t: MeshTraits) -> str:
    coincident = t.opposite_share + t.duplicate_share  # faces crossed twice at one point
    cancelling = coincident if mech == "parity" else t.opposite_share if mech == "winding" else 0.0
    if cancelling >= ALL_SHARE:
        return "empty (double-sided faces cancel)"
    if t.part_volume_ratio == 0.0 and t.opposite_share < ALL_SHARE:
        return "surface only (zero volume)" if mech in ("carve", "binvox") else "empty (zero volume)"
    if cancelling >= MOST_SHARE:
        return f"unreliable ({_pct(cancelling)} of faces double-sided: they cancel)"
    if cancelling > 0:  # patches that cancel act as holes in the surface
        return f"{'may dent' if mech == 'winding' else 'may streak'} ({_pct(cancelling)} of faces double-sided)"
    if mech == "winding":
        if t.inverted_parts and t.inverted_parts >= t.parts - t.inconsistent_parts:
            return "empty (inside out)"
        if t.inverted_parts:
            return f"partly empty ({t.inverted_parts} of {t.parts} parts inside out)"
        if t.inconsistent_parts:
            return "unreliable (inconsistent orientation)"
    if t.open_edges:
        if mech in ("carve", "binvox", "hull"):
            return "may leak (open boundary)"
        if mech == "parity":
            return "may streak (open boundary)"
    return "ok"


def solid_warning(traits: MeshTraits, method: str, count: int, bbox_voxels: int) -> str | None:
    """The one-line warning a solid result deserves, or None when it looks right.

    Cheap: it compares the result's voxel count with what the traits lead to
    expect, and runs nothing.

    Parameters
    ----------
    traits : MeshTraits
        Of the mesh voxelized.
    method : str
        The solid method that ran (a name of :data:`SOLID_MECHANISMS`; others
        are judged by the count alone).
    count : int
        Voxels of the result.
    bbox_voxels : int
        Voxels of the grid inside the mesh's bounding box, the scale of "far
        smaller": a result under 1% of it counts as empty-ish.

    Returns
    -------
    str or None
        ``"<verdict>: <what to do>"``, the cause named, e.g. ``"0 voxels:
        double-sided faces cancel (every face is doubled with opposite winding);
        use -m binvox-solid or -m carve-solid"``.
    """
    mech = SOLID_MECHANISMS.get(method)
    verdict = _verdict(mech, traits) if mech else "ok"
    small = count < 0.01 * bbox_voxels
    got = f"{count} voxels" + (" (empty)" if count == 0 else " (far fewer than the mesh's box holds)" if small else "")
    if verdict.startswith(("empty", "partly empty", "unreliable")):
        cause = verdict[verdict.index("(") + 1:-1]
        if "double-sided" in verdict:
            shares = [f"{_pct(x)} of faces doubled with {w} winding" for x, w in
                      ((traits.opposite_share, "opposite"), (traits.duplicate_share, "the same")) if x > 0]
            cause += f" ({', '.join(shares)})"
        return f"{got} from {method}: {cause}; use {ROBUST}"
    if verdict.startswith(("may dent", "may streak")) and small and "double-sided" in verdict:
        return f"{got} from {method}: {verdict[verdict.index('(') + 1:-1]}, which cancel; use {ROBUST}"
    if verdict.startswith(("may leak", "may streak")) and small:
        return (f"{got} from {method}: open boundary ({traits.open_edges} boundary edges) let the outside in; "
                f"repair the mesh, or use -m gwn-solid (robust to holes) or -m carve-solid close=K")
    if count == 0:
        if traits.part_volume_ratio == 0.0:
            return f"{got} from {method}: the mesh encloses zero volume; use a surface method"
        return (f"{got} from {method}: no voxel center lies inside the mesh at this grid; "
                f"use a finer grid or a surface method")
    return None
