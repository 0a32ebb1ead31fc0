"""The attribute rule in float64: source triangles and what they carry.

A set voxel's *source triangle* is, among the triangles that overlap or
touch its box (the conservative test of :func:`conservative_pairs`), the one
whose closest point to the voxel's center is nearest; ties go to the lowest
triangle index.  Its attributes are evaluated at that closest point
(docs/design.md, "Attributes"; glvox/grid.py's convention).

The closest point is found here by projection onto the plane and, outside
the triangle, the nearest of the three edges: a different construction from
the GPU's Voronoi-region walk (``shaders/attributes/closest.glsl``), so the
two check each other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..visuals import COLOR_FACE, COLOR_TEXTURE, COLOR_VERTEX, Texture
from ..tolerances import ATTR_TIE_EPS, TIE_EPS
from ._candidates import check_dims, check_tris, lex_greater
from .surface import conservative_pairs


@dataclass
class Sources:
    """Source triangles of voxels.

    Attributes
    ----------
    triangle : (M,) int64
        Index into the triangles given, -1 for voxels no triangle overlaps.
    distance : (M,) float64
        From the voxel center to the closest point, voxels (inf where none).
    bary : (M, 3) float64
        Barycentric coordinates of the closest point (zeros where none).
    """

    triangle: np.ndarray
    distance: np.ndarray
    bary: np.ndarray


def closest_points(tris: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance and barycentrics of the closest point of ``tris[m]`` to ``points[m]``.

    Parameters
    ----------
    tris : (P, 3, 3) float64
    points : (P, 3) float64

    Returns
    -------
    distance : (P,) float64
    bary : (P, 3) float64
        Weights of the three vertices (sum 1).
    """
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    e0, e1, r = b - a, c - a, points - a
    d00 = np.einsum("ij,ij->i", e0, e0)
    d01 = np.einsum("ij,ij->i", e0, e1)
    d11 = np.einsum("ij,ij->i", e1, e1)
    d20 = np.einsum("ij,ij->i", r, e0)
    d21 = np.einsum("ij,ij->i", r, e1)
    den = d00 * d11 - d01 * d01
    with np.errstate(divide="ignore", invalid="ignore"):
        v = (d11 * d20 - d01 * d21) / den
        w = (d00 * d21 - d01 * d20) / den
    u = 1.0 - v - w
    # strictly inside: a point on an edge takes the edge path below, which
    # computes a shared edge bit for bit alike for both its triangles, so exact
    # ties stay exact (and go to the lower index)
    inside = (den > 0.0) & (u > 0.0) & (v > 0.0) & (w > 0.0)
    bary = np.where(inside[:, None], np.stack([u, v, w], axis=1), 0.0)
    q = a + v[:, None] * e0 + w[:, None] * e1
    dist = np.where(inside, np.linalg.norm(points - np.where(inside[:, None], q, 0.0), axis=1), np.inf)
    # outside (or a degenerate triangle): the nearest point of the three edges,
    # each walked from its lexicographically smaller end
    for s, t, (ks, kt) in ((a, b, (0, 1)), (b, c, (1, 2)), (c, a, (2, 0))):
        swap = lex_greater(s, t)
        s, t = np.where(swap[:, None], t, s), np.where(swap[:, None], s, t)
        st = t - s
        ll = np.einsum("ij,ij->i", st, st)
        f = np.clip(np.einsum("ij,ij->i", points - s, st) / np.where(ll > 0.0, ll, 1.0), 0.0, 1.0)
        d = np.linalg.norm(points - (s + f[:, None] * st), axis=1)
        better = ~inside & (d < dist)
        dist = np.where(better, d, dist)
        nb = np.zeros_like(bary)
        nb[:, ks] = np.where(swap, f, 1.0 - f)
        nb[:, kt] = np.where(swap, 1.0 - f, f)
        bary = np.where(better[:, None], nb, bary)
    return dist, bary


def source_triangles(tris: np.ndarray, dims, voxels: np.ndarray, half: float = 0.5) -> Sources:
    """The source triangle of each voxel of ``voxels`` by the rule of the module docstring.

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Triangles in voxel space.
    dims : (3,) int
    voxels : (M, 3) int64
        The voxels to evaluate (e.g. a result's ``indices()``), distinct.
    half : float
        Half-size of the box a triangle must overlap (0.5: the voxel; the
        tests use 0.5 +/- TIE_EPS to find overlap ties).

    Returns
    -------
    Sources, one row per voxel of ``voxels`` in its order.
    """
    tris = check_tris(tris)
    nx, ny, nz = check_dims(dims)
    vox = np.asarray(voxels, dtype=np.int64).reshape(-1, 3)
    keys = (vox[:, 0] * ny + vox[:, 1]) * nz + vox[:, 2]
    order = np.argsort(keys)
    sorted_keys = keys[order]
    m = len(vox)
    if m == 0:
        return Sources(np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 3)))
    best_d, best_t, best_b = np.full(m, np.inf), np.full(m, -1, np.int64), np.zeros((m, 3))
    for tri, ijk in conservative_pairs(tris, (nx, ny, nz), half):
        k = (ijk[:, 0] * ny + ijk[:, 1]) * nz + ijk[:, 2]
        pos = np.minimum(np.searchsorted(sorted_keys, k), m - 1)
        hit = sorted_keys[pos] == k
        if not hit.any():
            continue
        slot, tri, ijk = order[pos[hit]], tri[hit], ijk[hit]
        d, bary = closest_points(tris[tri], ijk + 0.5)
        # the best pair of each slot in this chunk: by distance, then index
        first = np.lexsort((tri, d, slot))
        slot, tri, d, bary = slot[first], tri[first], d[first], bary[first]
        lead = np.ones(len(slot), bool)
        lead[1:] = slot[1:] != slot[:-1]
        slot, tri, d, bary = slot[lead], tri[lead], d[lead], bary[lead]
        better = (d < best_d[slot]) | ((d == best_d[slot]) & (tri < best_t[slot]))
        s = slot[better]
        best_d[s], best_t[s], best_b[s] = d[better], tri[better], bary[better]
    return Sources(best_t, best_d, best_b)


def sample_texture(tex: Texture, uv: np.ndarray) -> np.ndarray:
    """``tex`` sampled at ``uv`` (N, 2) as GL samples it: (N, 4) float64 in [0, 1].

    UV (0, 0) is the image's bottom-left corner; texel centers at half
    integers; ``linear``: bilinear between the four nearest texels,
    ``nearest``: the texel holding the point; ``repeat`` wraps, ``clamp``
    clamps to the edge texels.
    """
    img = tex.image[::-1].astype(np.float64) / 255.0  # row 0 = v in [0, 1/H)
    h, w = img.shape[:2]

    def index(i, n):
        return np.mod(i, n) if tex.wrap == "repeat" else np.clip(i, 0, n - 1)

    if tex.filter == "nearest":
        x = index(np.floor(uv[:, 0] * w).astype(np.int64), w)
        y = index(np.floor(uv[:, 1] * h).astype(np.int64), h)
        return img[y, x] * tex.factor
    fx, fy = uv[:, 0] * w - 0.5, uv[:, 1] * h - 0.5
    x0, y0 = np.floor(fx), np.floor(fy)
    ax, ay = (fx - x0)[:, None], (fy - y0)[:, None]
    x0, y0 = x0.astype(np.int64), y0.astype(np.int64)
    xa, xb, ya, yb = index(x0, w), index(x0 + 1, w), index(y0, h), index(y0 + 1, h)
    top = img[ya, xa] * (1 - ax) + img[ya, xb] * ax
    bottom = img[yb, xa] * (1 - ax) + img[yb, xb] * ax
    return (top * (1 - ay) + bottom * ay) * tex.factor


def index_attribute(mesh, name: str, tri: np.ndarray) -> np.ndarray:
    """``triangle`` (the input's face index) or ``material`` (the part) of voxels whose
    source triangle (an index into ``mesh.faces``) is ``tri``, -1 where ``tri`` < 0; int32.
    The one mapping of the GPU pass (:mod:`glvox.methods.attributes.passes`) and of this reference."""
    has = tri >= 0
    ts = np.where(has, tri, 0)
    if name == "triangle":
        values = mesh.source_faces[ts] if mesh.source_faces is not None else ts
    elif name == "material":
        values = mesh.visuals.material[ts] if mesh.visuals is not None else np.zeros(len(tri), np.int32)
    else:
        raise ValueError(f"{name!r} is not an index attribute")
    return np.where(has, values, -1).astype(np.int32)


def evaluate(mesh, sources: Sources, names, normals: str = "face") -> dict[str, np.ndarray]:
    """The attributes ``names`` of voxels from their ``sources`` (triangles = ``mesh.faces``).

    Parameters
    ----------
    mesh : glvox.mesh.Mesh
        With ``visuals`` for ``color`` (and ``normals='vertex'``).
    sources : Sources
    names : iterable of {'triangle', 'color', 'normal', 'material'}
    normals : {'face', 'vertex'}
        The source triangle's normal, or the vertex normals interpolated at
        the closest point (normalized).

    Returns
    -------
    dict of name to array, the dtypes of :data:`glvox.results.voxels.ATTRIBUTE_DTYPES`.
    """
    t = sources.triangle
    has = t >= 0
    ts = np.where(has, t, 0)
    vis = mesh.visuals
    out: dict[str, np.ndarray] = {}
    for name in names:
        if name in ("triangle", "material"):
            out[name] = index_attribute(mesh, name, t)
        elif name == "normal":
            out[name] = _normals(mesh, ts, sources.bary, normals) * has[:, None]
            out[name] = out[name].astype(np.float32)
        elif name == "color":
            out[name] = _colors(vis, ts, sources.bary) * has[:, None].astype(np.uint8)
        else:
            raise ValueError(f"unknown attribute {name!r}")
    return out


def _normals(mesh, t: np.ndarray, bary: np.ndarray, mode: str) -> np.ndarray:
    if mode == "vertex":
        n = np.einsum("mc,mcd->md", bary, mesh.visuals.corner_normal[t])
    else:
        tri = mesh.vertices[mesh.faces[t]]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(length > 0.0, n / np.where(length > 0.0, length, 1.0), 0.0)


def _colors(vis, t: np.ndarray, bary: np.ndarray) -> np.ndarray:
    out = np.zeros((len(t), 4), np.uint8)
    if vis is None:
        return out
    src = vis.color_source[t]
    face = src == COLOR_FACE
    out[face] = vis.face_color[t[face]]
    vert = src == COLOR_VERTEX
    if vert.any():
        c = np.einsum("mc,mcd->md", bary[vert], vis.corner_color[t[vert]].astype(np.float64))
        out[vert] = np.clip(np.rint(c), 0, 255).astype(np.uint8)
    for k, tex in enumerate(vis.textures):
        sel = (src == COLOR_TEXTURE) & (vis.texture[t] == k)
        if sel.any():
            uv = np.einsum("mc,mcd->md", bary[sel], vis.corner_uv[t[sel]])
            out[sel] = np.clip(np.rint(sample_texture(tex, uv) * 255.0), 0, 255).astype(np.uint8)
    return out


def nearest_seeds(voxels: np.ndarray, seeded: np.ndarray) -> np.ndarray:
    """For each voxel, the row of the nearest voxel with ``seeded`` True (center
    distance, exact by a k-d tree; itself when seeded; -1 when none is).

    Parameters
    ----------
    voxels : (M, 3) int64
    seeded : (M,) bool
    """
    from scipy.spatial import cKDTree  # lazy: scipy is heavy, and only this fill needs it

    rows = np.arange(len(voxels))
    if not seeded.any():
        return np.full(len(voxels), -1, np.int64)
    seeds = np.flatnonzero(seeded)
    _, k = cKDTree(voxels[seeds]).query(voxels[~seeded])
    rows[~seeded] = seeds[k]
    return rows


def reference_attributes(mesh, tris: np.ndarray, dims, voxels: np.ndarray, names, normals: str = "face",
                         fill: str = "none") -> tuple[Sources, dict[str, np.ndarray]]:
    """:func:`source_triangles` then :func:`evaluate`: the attributes of ``voxels``;
    ``fill='nearest'``: voxels without a source triangle take the attributes of
    the nearest voxel with one (:func:`nearest_seeds`)."""
    sources = source_triangles(tris, dims, voxels)
    out = evaluate(mesh, sources, names, normals)
    if fill == "nearest":
        rows = nearest_seeds(np.asarray(voxels).reshape(-1, 3), sources.triangle >= 0)
        rows = np.where(rows < 0, np.arange(len(rows)), rows)
        out = {k: v[rows] for k, v in out.items()}
    return sources, out


def proven_ties(tris: np.ndarray, dims, voxels: np.ndarray, triangle: np.ndarray, sources: Sources,
                eps: float = ATTR_TIE_EPS) -> np.ndarray:
    """Which voxels' source triangle ``triangle`` (e.g. the GPU's, indices into
    ``tris``, -1 none) is a proven tie against the reference ``sources``.

    A voxel is a tie when the two triangles' distances to its center are
    within ``eps`` voxel, or when either one's overlap of the voxel is itself a
    tie (it overlaps the box of half-size 0.5 + TIE_EPS but not 0.5 - TIE_EPS:
    docs/design.md, "Ties").  Voxels where both agree are False.

    Returns
    -------
    (M,) bool
    """
    vox = np.asarray(voxels, dtype=np.int64).reshape(-1, 3)
    differ = np.asarray(triangle) != sources.triangle
    out = np.zeros(len(vox), bool)
    if not differ.any():
        return out
    rows = np.flatnonzero(differ)
    a, b = np.asarray(triangle)[rows], sources.triangle[rows]
    both = (a >= 0) & (b >= 0)
    da, _ = closest_points(tris[np.maximum(a, 0)], vox[rows] + 0.5)
    db, _ = closest_points(tris[np.maximum(b, 0)], vox[rows] + 0.5)
    out[rows] = both & (np.abs(da - db) <= eps)
    sel = np.unique(np.concatenate([a[a >= 0], b[b >= 0]]))  # only the triangles in question
    loose = _overlap_pairs(tris, sel, dims, vox[rows], 0.5 + TIE_EPS)
    tight = _overlap_pairs(tris, sel, dims, vox[rows], 0.5 - TIE_EPS)
    for n, (ta, tb) in enumerate(zip(a, b)):
        for t in (ta, tb):
            if t >= 0 and (n, t) in loose and (n, t) not in tight:
                out[rows[n]] = True
    return out


def _overlap_pairs(tris, sel, dims, voxels, half) -> set[tuple[int, int]]:
    """The (row of ``voxels``, triangle of ``sel``) pairs that overlap at box half-size ``half``."""
    nx, ny, nz = check_dims(dims)
    keys = (voxels[:, 0] * ny + voxels[:, 1]) * nz + voxels[:, 2]
    lookup = {int(k): n for n, k in enumerate(keys)}
    out = set()
    if len(sel) == 0:
        return out
    for tri, ijk in conservative_pairs(tris[sel], dims, half):
        for t, k in zip(sel[tri].tolist(), ((ijk[:, 0] * ny + ijk[:, 1]) * nz + ijk[:, 2]).tolist()):
            n = lookup.get(k)
            if n is not None:
                out.add((n, t))
    return out
