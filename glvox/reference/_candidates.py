"""Input checks and candidate enumeration shared by the CPU references.

Everything here works in voxel space: voxel ``(i, j, k)`` is the closed box
``[i, i+1] x [j, j+1] x [k, k+1]`` with center ``(i+.5, j+.5, k+.5)``.

The references never loop per triangle or per voxel.  They enumerate
(triangle, voxel) candidate pairs as flat integer arrays, a bounded number at
a time, so peak memory stays near ``PAIRS_PER_CHUNK`` times a few dozen bytes
whatever the mesh and grid.
"""

from __future__ import annotations

from typing import Iterator, Sequence

import numpy as np

#: Candidate pairs evaluated at once.  Each pair costs a few hundred bytes of
#: temporaries in the overlap tests, so 2**21 pairs keep a chunk well under 1 GiB
#: while leaving the Python overhead per chunk negligible.
PAIRS_PER_CHUNK = 1 << 21

#: Margin, in voxels, added on both sides of the dominant-axis range that the
#: triangle's plane can reach in a column (see :func:`pruned_candidates`).  The
#: range is only a pre-filter: a whole voxel of slack makes it a superset of
#: every voxel the exact tests can accept, however the floating-point rounding
#: of the range and of the tests themselves fall.
PRUNE_MARGIN = 1


def check_tris(tris: np.ndarray) -> np.ndarray:
    """Return ``tris`` as a C-contiguous (T, 3, 3) float64 array, or raise.

    Parameters
    ----------
    tris : array_like, (T, 3, 3)
        Triangle vertices in voxel space.

    Returns
    -------
    (T, 3, 3) float64
    """
    arr = np.ascontiguousarray(tris, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[1:] != (3, 3):
        raise ValueError(f"tris must have shape (T, 3, 3), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError("tris must be finite, got NaN or infinite coordinates")
    return arr


def check_eps(eps: float, below_half: bool = True) -> float:
    """A tie tolerance in voxels: 0 < eps < 0.5 (any eps > 0 without ``below_half``), else ValueError."""
    if below_half and not 0.0 < eps < 0.5:
        raise ValueError(f"eps must be in (0, 0.5) voxel, got {eps!r}")
    if not eps > 0.0:
        raise ValueError(f"eps must be a positive length in voxels, got {eps!r}")
    return float(eps)


def segment_distance(c: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(M,) distances from the 2D points ``c`` to the segments ``a b``, all (M, 2)."""
    ab = b - a
    ll = np.einsum("ij,ij->i", ab, ab)
    w = np.clip(np.einsum("ij,ij->i", c - a, ab) / np.where(ll > 0.0, ll, 1.0), 0.0, 1.0)
    return np.linalg.norm(c - (a + w[:, None] * ab), axis=1)


def lex_greater(s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(P,) bool: row s[m] comes after row t[m] in lexicographic order (rows of 3)."""
    out = np.zeros(len(s), bool)
    undecided = np.ones(len(s), bool)
    for k in range(3):
        out |= undecided & (s[:, k] > t[:, k])
        undecided &= s[:, k] == t[:, k]
    return out


def check_dims(dims: Sequence[int]) -> tuple[int, int, int]:
    """Return ``dims`` as a tuple of three positive Python ints, or raise."""
    try:
        vals = tuple(int(d) for d in dims)
        ok = len(vals) == 3 and all(v > 0 and v == d for v, d in zip(vals, dims))
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"dims must be three positive integers, got {dims!r}")
    return vals


def check_half(half: float) -> float:
    """Return the box half-size as a float, or raise if it is not positive."""
    h = float(half)
    if not (np.isfinite(h) and h > 0.0):
        raise ValueError(f"half must be a positive finite box half-size, got {half!r}")
    return h


def check_axis(axis: int) -> int:
    """Return the ray axis as an int in {0, 1, 2}, or raise."""
    if axis not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2, got {axis!r}")
    return int(axis)


def normals(tris: np.ndarray) -> np.ndarray:
    """Unnormalized triangle normals ``(v1 - v0) x (v2 - v1)``, (T, 3) float64."""
    return np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 1])


def index_range(lo: np.ndarray, hi: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Integer index range ``[first, last]`` of ``ceil(lo) .. floor(hi)`` clipped to ``[0, n-1]``.

    Parameters
    ----------
    lo, hi : (...) float64
        Real bounds of the wanted indices (inclusive).
    n : int
        Number of cells along the axis.

    Returns
    -------
    first, last : (...) int64
        ``last < first`` means empty.  Bounds are clipped in floating point
        first, so coordinates far outside the grid cannot overflow int64.
    """
    first = np.clip(np.ceil(lo), 0, n).astype(np.int64)
    last = np.clip(np.floor(hi), -1, n - 1).astype(np.int64)
    return first, last


def box_ranges(tris: np.ndarray, dims: tuple[int, int, int], pad: float):
    """Per-axis index ranges of the voxels whose box of half-size ``pad`` meets each bounding box.

    A voxel ``i`` (center ``i + 0.5``) is a candidate along an axis when the
    closed interval ``[i + .5 - pad, i + .5 + pad]`` meets the triangle's
    closed extent ``[lo, hi]``, i.e. ``lo - .5 - pad <= i <= hi - .5 + pad``.
    With ``pad = 0.5`` these are the voxels that overlap or merely touch the
    bounding box (S&S Sec. 3.2, Fig. 5a).

    Returns
    -------
    first, last : (T, 3) int64
        Inclusive index ranges per triangle and axis, clipped to the grid.
    """
    lo = tris.min(axis=1)
    hi = tris.max(axis=1)
    n = np.asarray(dims, dtype=np.int64)
    first = np.empty(lo.shape, dtype=np.int64)
    last = np.empty(lo.shape, dtype=np.int64)
    for a in range(3):
        first[:, a], last[:, a] = index_range(lo[:, a] - 0.5 - pad, hi[:, a] - 0.5 + pad, int(n[a]))
    return first, last


def expand(counts: np.ndarray, chunk: int = PAIRS_PER_CHUNK) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Enumerate ``(owner, local)`` for ``local in range(counts[owner])``, ``chunk`` items at a time.

    One owner's items may be split across chunks, so a single triangle with
    a huge bounding box cannot exceed the chunk size.

    Parameters
    ----------
    counts : (N,) int64
        Non-negative item count per owner.
    chunk : int
        Most items per yielded pair of arrays.

    Yields
    ------
    owner, local : (M,) int64
    """
    offsets = np.zeros(len(counts) + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    total = int(offsets[-1])
    for start in range(0, total, chunk):
        g = np.arange(start, min(start + chunk, total), dtype=np.int64)
        # side='right' skips owners with zero items (repeated offsets).
        owner = np.searchsorted(offsets, g, side="right") - 1
        yield owner, g - offsets[owner]


def repeat_expand(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unchunked :func:`expand` for counts already known to be small in total."""
    owner = np.repeat(np.arange(len(counts), dtype=np.int64), counts)
    starts = np.cumsum(counts) - counts
    return owner, np.arange(len(owner), dtype=np.int64) - starts[owner]


def bbox_candidates(tris: np.ndarray, dims: tuple[int, int, int], pad: float,
                    chunk: int = PAIRS_PER_CHUNK) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Every voxel whose box of half-size ``pad`` meets a triangle's bounding box.

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Triangles in voxel space.
    dims : (3,) int
        Grid size; voxels outside it are never produced.
    pad : float
        Half-size of the box around each voxel center, in voxels.

    Yields
    ------
    tri : (M,) int64
        Triangle index of each candidate pair.
    ijk : (M, 3) int64
        Voxel index of each candidate pair.
    """
    first, last = box_ranges(tris, dims, pad)
    ext = np.maximum(last - first + 1, 0)
    counts = ext[:, 0] * ext[:, 1] * ext[:, 2]
    for tri, local in expand(counts, chunk):
        e = ext[tri]
        ijk = np.empty((len(tri), 3), dtype=np.int64)
        ijk[:, 2] = local % e[:, 2]
        rest = local // e[:, 2]
        ijk[:, 1] = rest % e[:, 1]
        ijk[:, 0] = rest // e[:, 1]
        ijk += first[tri]
        yield tri, ijk


def pruned_candidates(tris: np.ndarray, dims: tuple[int, int, int], pad: float,
                      chunk: int = PAIRS_PER_CHUNK) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The :func:`bbox_candidates` that can also meet the triangle's plane.

    Following S&S Sec. 3.2 ("test specialization"), each triangle is walked
    column by column along its normal's dominant axis ``d``.  In a column the
    plane reaches ``d`` values within ``spread = pad * (|n_u| + |n_v|) / |n_d|``
    of its value at the column center; only voxels whose box of half-size
    ``pad`` meets that range (widened by :data:`PRUNE_MARGIN`) are produced.
    Every voxel whose box meets the triangle is among them, so the result of
    an exact test evaluated on these candidates equals its result on all
    bounding-box candidates, at a cost proportional to the triangle's area
    instead of its bounding-box volume.  Zero-area triangles (no dominant
    axis) keep their whole bounding box.

    Parameters and yields are those of :func:`bbox_candidates`.
    """
    first, last = box_ranges(tris, dims, pad)
    ext = np.maximum(last - first + 1, 0)
    n = normals(tris)
    d = np.argmax(np.abs(n), axis=1)
    u = (d + 1) % 3
    v = (d + 2) % 3
    rows = np.arange(len(tris))
    nd = n[rows, d]
    # Without a usable dominant component (zero area, or a normal that
    # overflowed for absurdly large coordinates) keep the whole bounding box.
    flat = (nd == 0.0) | ~np.isfinite(n).all(axis=1)
    nd_safe = np.where(flat, 1.0, nd)
    ratio_u = np.where(flat, 0.0, n[rows, u] / nd_safe)
    ratio_v = np.where(flat, 0.0, n[rows, v] / nd_safe)
    spread = pad * (np.abs(ratio_u) + np.abs(ratio_v))
    v0 = tris[:, 0]
    ext_u, ext_v = ext[rows, u], ext[rows, v]
    ncols = ext_u * ext_v * (ext[rows, d] > 0)
    # Columns per chunk: a column holds at most ~2*spread + 2*pad + 2*margin + 1
    # (<= 6 for pad = 0.5) candidates, so this keeps pairs near `chunk`.
    for tri, local in expand(ncols, max(chunk // 8, 1)):
        iu = first[tri, u[tri]] + local // ext_v[tri]
        iv = first[tri, v[tri]] + local % ext_v[tri]
        cu = iu + 0.5 - v0[tri, u[tri]]
        cv = iv + 0.5 - v0[tri, v[tri]]
        # Plane: n . (x - v0) = 0  =>  x_d = v0_d - (n_u/n_d) (x_u - v0_u) - (n_v/n_d) (x_v - v0_v).
        center = v0[tri, d[tri]] - ratio_u[tri] * cu - ratio_v[tri] * cv
        fd = first[tri, d[tri]]
        ld = last[tri, d[tri]]
        # Clipped in floating point to the bounding-box range, so far-away
        # planes cannot overflow int64.
        a = np.clip(np.ceil(center - spread[tri] - 0.5 - pad - PRUNE_MARGIN), fd, ld + 1).astype(np.int64)
        b = np.clip(np.floor(center + spread[tri] - 0.5 + pad + PRUNE_MARGIN), fd - 1, ld).astype(np.int64)
        a = np.where(flat[tri], fd, a)
        b = np.where(flat[tri], ld, b)
        cnt = np.maximum(b - a + 1, 0)
        col, k = repeat_expand(cnt)
        t = tri[col]
        ijk = np.empty((len(col), 3), dtype=np.int64)
        r = np.arange(len(col))
        ijk[r, d[t]] = a[col] + k
        ijk[r, u[t]] = iu[col]
        ijk[r, v[t]] = iv[col]
        yield t, ijk


def column_candidates(tris: np.ndarray, dims: tuple[int, int, int], axis: int,
                      chunk: int = PAIRS_PER_CHUNK, pad: float = 0.0
                      ) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Voxel columns along ``axis`` whose center line meets each triangle's projected bounding box.

    With ``u = (axis + 1) % 3`` and ``v = (axis + 2) % 3``, column ``(ju, jv)``
    is a candidate when ``(ju + .5, jv + .5)`` lies in the triangle's closed
    bounding box in the (u, v) plane (S&S Sec. 4.1), grown by ``pad`` voxels.

    Yields
    ------
    tri : (M,) int64
        Triangle index per pair.
    ju, jv : (M,) int64
        Column indices along ``u`` and ``v``.
    """
    u = (axis + 1) % 3
    v = (axis + 2) % 3
    lo = tris.min(axis=1)
    hi = tris.max(axis=1)
    fu, lu = index_range(lo[:, u] - 0.5 - pad, hi[:, u] - 0.5 + pad, dims[u])
    fv, lv = index_range(lo[:, v] - 0.5 - pad, hi[:, v] - 0.5 + pad, dims[v])
    eu = np.maximum(lu - fu + 1, 0)
    ev = np.maximum(lv - fv + 1, 0)
    for tri, local in expand(eu * ev, chunk):
        yield tri, fu[tri] + local // ev[tri], fv[tri] + local % ev[tri]


def scatter(out: np.ndarray, ijk: np.ndarray) -> None:
    """Set ``out[i, j, k] = True`` for each row of ``ijk`` ((M, 3) int64, inside the grid)."""
    if len(ijk):
        flat = np.ravel_multi_index((ijk[:, 0], ijk[:, 1], ijk[:, 2]), out.shape)
        out.reshape(-1)[flat] = True
