"""Zhang et al. 2018, Table 1: the test triangle and the Schwarz & Seidel operation count.

The paper compares the comparisons and additions of its scanline (ILV)
with those of the Schwarz & Seidel triangle/box test on an equilateral
triangle voxelized at 32^3, rotated about y and about z in 15 degree steps.
The scanline side is counted by the instrumented CPU scanline
(:func:`glvox.reference.scanline.scanline_surface` with ``counts=``); the
S&S side by :func:`ss_counts` here.  ``compare/zhang_table1.py`` prints the
table, ``tests/test_scanline.py`` checks the paper's claim with them.

Units (the paper's, Sec. 5): an S&S sub-test (one edge function of a 2D
projection) is 1 comparison and 2 additions (and 2 multiplications, not
counted); a scanline voxel step is k - 1 comparisons and k additions for k
moving axes (2D: 1 and 2), an Eq. 9 end candidate 3 comparisons and 1
addition.  Set-up (normals, sorting, products) is counted for neither.

The paper does not give the triangle's size or position; here it is
inscribed in the grid: circumradius :data:`RADIUS` voxels around the grid
center, in the yz plane at 0 degrees (x = 16.5, inside one voxel slab, so
S&S takes its 2D path as the paper's 0 degree row implies), one vertex
along (0, 1, 1), so that its rotations about y and about z are mirror images
of each other (the paper's "Ours" columns are identical for y and z).  The
S&S count follows the specialized test of S&S Sec. 3.2: bounding-box voxels
whose box meets the triangle's bounding box; a box one voxel thick along one
axis is the 2D case (3 edge tests per voxel, stopping at the first that
fails), one voxel thick along two axes the 1D case (no test); otherwise, per
column along the dominant axis, 3 edge tests in the dominant plane, then for
each voxel of the column range the plane can reach, the 6 edge tests of the
other two planes (stopping at the first failure).
"""

from __future__ import annotations

import math

import numpy as np

#: Grid size N (an N^3 grid) of the experiment.
N = 32
#: Circumradius of the test triangle, voxels.
RADIUS = 15.0
#: The grid center in voxel space, around which the triangle is placed and rotated.
CENTER = np.array([16.5, 16.5, 16.5])
#: The rotation angles of the paper's rows, degrees.
ANGLES = (0, 15, 30, 45, 60, 75, 90)

_PLANES = ((1, 2, 0), (2, 0, 1), (0, 1, 2))  # (a, b, normal axis) of the yz, zx, xy projections


def triangle(axis: str, degrees: float) -> np.ndarray:
    """The test triangle, float64 (3, 3) in voxel space, rotated about ``axis`` ('y' or 'z')
    through :data:`CENTER` by ``degrees``."""
    u = np.array([0.0, 1.0, 1.0]) / math.sqrt(2.0)   # first vertex direction, in the yz plane
    v = np.array([0.0, -1.0, 1.0]) / math.sqrt(2.0)
    pts = [RADIUS * (math.cos(a) * u + math.sin(a) * v) for a in (0.0, 2 * math.pi / 3, 4 * math.pi / 3)]
    t = math.radians(degrees)
    c, s = math.cos(t), math.sin(t)
    R = {"y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
         "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]
    return np.array([CENTER + R @ p for p in pts])


def _edges(tri: np.ndarray, n: np.ndarray, plane) -> list[tuple[float, float, float]]:
    """The three edge functions (n_a, n_b, d) of the projection, conservative offsets (S&S Eq. 2-3)."""
    a, b, w = plane
    sgn = 1.0 if n[w] >= 0 else -1.0
    out = []
    for i in range(3):
        e = tri[(i + 1) % 3] - tri[i]
        na, nb = -e[b] * sgn, e[a] * sgn
        d = -(na * tri[i][a] + nb * tri[i][b]) + max(0.0, na) + max(0.0, nb)
        out.append((na, nb, d))
    return out


class _SubTests:
    """Edge-function evaluations, each one S&S sub-test."""

    def __init__(self):
        self.count = 0

    def passes(self, fs, p, q) -> bool:
        for na, nb, d in fs:
            self.count += 1
            if na * p + nb * q + d < 0.0:
                return False
        return True


def ss_counts(tri: np.ndarray, dims=(N, N, N)) -> tuple[int, int]:
    """Sub-tests of the specialized S&S test on one triangle (3, 3), voxel space: (comparisons, additions)."""
    n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    lo = np.maximum(np.floor(tri.min(0)).astype(int), 0)
    hi = np.minimum(np.floor(tri.max(0)).astype(int), np.asarray(dims) - 1)
    thick = hi - lo + 1
    t = _SubTests()
    if (thick == 1).sum() >= 2:  # 1D: every bounding-box voxel, no test
        return 0, 0
    if (thick == 1).sum() == 1:  # 2D: the projection along the thin axis only
        w = int(np.argmax(thick == 1))
        plane = [p for p in _PLANES if p[2] == w][0]
        fs = _edges(tri, n, plane)
        a, b, _ = plane
        for i in range(lo[a], hi[a] + 1):
            for j in range(lo[b], hi[b] + 1):
                t.passes(fs, i, j)
        return t.count, 2 * t.count
    w = int(np.argmax(np.abs(n)))
    plane = [p for p in _PLANES if p[2] == w][0]
    others = [p for p in _PLANES if p[2] != w]
    fs = _edges(tri, n, plane)
    f_other = [_edges(tri, n, p) for p in others]
    a, b, _ = plane
    for i in range(lo[a], hi[a] + 1):
        for j in range(lo[b], hi[b] + 1):
            if not t.passes(fs, i, j):
                continue
            # the plane's w over the column's square, and the voxels it reaches
            ws = [tri[0][w] - (n[a] * (x - tri[0][a]) + n[b] * (y - tri[0][b])) / n[w]
                  for x in (i, i + 1) for y in (j, j + 1)]
            for k in range(max(lo[w], math.floor(min(ws))), min(hi[w], math.floor(max(ws))) + 1):
                v = {a: i, b: j, w: k}
                for (pa, pb, _), f in zip(others, f_other):
                    if not t.passes(f, v[pa], v[pb]):
                        break
    return t.count, 2 * t.count
