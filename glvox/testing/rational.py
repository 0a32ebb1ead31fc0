"""Second, independently formulated surface references in exact rational arithmetic.

:mod:`glvox.reference.surface` evaluates Schwarz & Seidel's criteria with
precomputed offsets (the critical point of Eq. 1, the corner terms of Eq. 2,
the dominant-axis terms of Sec. 3.4) in float64.  Here the same definitions
are written as support functions evaluated by enumerating vertices, in
:class:`fractions.Fraction` (every float is a dyadic rational, so the input
is taken exactly and no comparison is rounded):

- conservative (26-separating, S&S Sec. 3.1-3.2): a voxel is set iff its
  closed box meets the triangle's closed bounding box, the triangle's plane
  meets the box (some box corner on each side, or on the plane), and, in each
  of the three coordinate projections, every projected edge's closed inner
  half-plane holds some corner of the projected square;
- 6-separating (S&S Sec. 3.4, Huang et al.'s criterion): the same with the
  box replaced by the voxel's inner diamond ``{x : |x - c|_1 <= 1/2}`` (its
  six vertices ``c +- e_i / 2``) for the plane, and the projected square by
  the square's inner diamond (its four vertices) for the edges; candidates
  are still the voxels whose box meets the bounding box.

The inner side of a projected edge is fixed by the orientation of the
projection: in the plane ``(a, b)`` normal to ``w`` (cyclic), the edge
``v_i -> v_j`` has the inner normal ``s (-(v_j - v_i)_b, (v_j - v_i)_a)``
with ``s = +1`` when ``n_w >= 0``, else ``-1`` (S&S Eq. 2).  A projection
of zero area then tests the segment (or point) against the square or
diamond, as the float references do.

Pure Python: meant for small grids (a few thousand candidate pairs), as an
oracle for tests, not for real meshes.
"""

from __future__ import annotations

from fractions import Fraction
from itertools import product
from typing import Sequence

import numpy as np

_PLANES = ((1, 2, 0), (2, 0, 1), (0, 1, 2))
_HALF = Fraction(1, 2)


def _sub(p, q):
    return [p[0] - q[0], p[1] - q[1], p[2] - q[2]]


def _cross(u, v):
    return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]


def _dot(u, v):
    return sum(x * y for x, y in zip(u, v))


def _meets(values) -> bool:
    """Some value <= 0 and some >= 0: the set spanned by the points meets the zero level."""
    return min(values) <= 0 <= max(values)


def _inner_edges(tri, n):
    """Per projection (a, b): the three (vertex, inner normal) pairs of its edges."""
    out = []
    for a, b, w in _PLANES:
        s = 1 if n[w] >= 0 else -1
        edges = []
        for i in range(3):
            vi, vj = tri[i], tri[(i + 1) % 3]
            edges.append(((vi[a], vi[b]), (-(vj[b] - vi[b]) * s, (vj[a] - vi[a]) * s)))
        out.append((a, b, edges))
    return out


def _voxel_set(tris: np.ndarray, dims: Sequence[int], diamond: bool) -> np.ndarray:
    tris = np.asarray(tris, dtype=np.float64)
    if tris.ndim != 3 or tris.shape[1:] != (3, 3) or not np.isfinite(tris).all():
        raise ValueError(f"tris must be a finite (T, 3, 3) array, got shape {tris.shape}")
    dims = tuple(int(d) for d in dims)
    out = np.zeros(dims, dtype=bool)
    for t in tris:
        tri = [[Fraction(float(x)) for x in v] for v in t]
        n = _cross(_sub(tri[1], tri[0]), _sub(tri[2], tri[0]))
        edges = _inner_edges(tri, n)
        ranges = []
        for ax in range(3):
            lo = min(v[ax] for v in tri)
            hi = max(v[ax] for v in tri)
            # voxel i's closed box [i, i+1] meets [lo, hi] iff i + 1 >= lo and i <= hi (lo, hi
            # are floats, so ceil and floor of them are exact)
            first = max(int(np.ceil(float(lo))) - 1, 0)
            last = min(int(np.floor(float(hi))), dims[ax] - 1)
            ranges.append(range(first, last + 1))
        for ijk in product(*ranges):
            if out[ijk]:
                continue
            if diamond:
                c = [Fraction(2 * i + 1, 2) for i in ijk]
                pts = [[c[k] + (d if k == ax else 0) for k in range(3)] for ax in range(3) for d in (-_HALF, _HALF)]
            else:
                pts = [[Fraction(i + d) for i, d in zip(ijk, corner)] for corner in product((0, 1), repeat=3)]
            if not _meets([_dot(n, _sub(p, tri[0])) for p in pts]):
                continue
            ok = True
            for a, b, proj in edges:
                if diamond:
                    ca, cb = Fraction(2 * ijk[a] + 1, 2), Fraction(2 * ijk[b] + 1, 2)
                    sq = [(ca - _HALF, cb), (ca + _HALF, cb), (ca, cb - _HALF), (ca, cb + _HALF)]
                else:
                    sq = [(Fraction(ijk[a] + da), Fraction(ijk[b] + db)) for da, db in product((0, 1), repeat=2)]
                for (pa, pb), (na, nb) in proj:
                    if max(na * (qa - pa) + nb * (qb - pb) for qa, qb in sq) < 0:
                        ok = False
                        break
                if not ok:
                    break
            if ok:
                out[ijk] = True
    return out


def conservative_surface_rational(tris: np.ndarray, dims: Sequence[int]) -> np.ndarray:
    """The conservative surface by vertex enumeration in exact rationals (module docstring).

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Triangle vertices in voxel space (taken exactly).
    dims : (3,) int
        Grid size ``(nx, ny, nz)``; voxels outside are clipped.

    Returns
    -------
    (nx, ny, nz) bool
    """
    return _voxel_set(tris, dims, diamond=False)


def six_separating_surface_rational(tris: np.ndarray, dims: Sequence[int]) -> np.ndarray:
    """The 6-separating surface by inner-diamond vertex enumeration in exact rationals
    (module docstring); parameters and result as :func:`conservative_surface_rational`."""
    return _voxel_set(tris, dims, diamond=True)
