"""Slivers as thin as float32 vertices make them, for the crossing tests of the parity solids.

:func:`float32_sliver` is a triangle whose long edge A -> C runs through the column
center (0.5, 0.5) across the rays, its midpoint, along (F30, F31) units of 2^-22 voxel,
with B - A = (F29, F30) (consecutive Fibonacci numbers: F29 F31 - F30^2 = 1, so the
projected area is 2^-45 voxel^2).  A and C lie 1000.25 voxels on either side of 33.5
along the rays, so the exact crossing of that column is 33.5, a voxel center.  The
plane's crossing formula in double is off there by up to 0.04 voxel, by the vertex order
(a division by the tiny normal component along the rays); the barycentric one with
exact edge functions as weights is exact.
"""

from __future__ import annotations

import numpy as np

#: The column center the sliver's long edge runs through, (u, v) across the rays.
CENTER = (0.5, 0.5)
#: Where that column crosses the sliver, along the rays.
CROSSING = 33.5
#: The bits of the fixed point the sliver's (u, v) are exact in.
BITS = 22
#: Its vertex orders: each gives the same triangle.
ORDERS = ((0, 1, 2), (2, 1, 0), (1, 2, 0), (1, 0, 2))


def float32_sliver() -> np.ndarray:
    """(3, 3) float64, exact in float32: the vertices A, B, C as (along the rays, u, v)."""
    f29, f30, f31 = 514229, 832040, 1346269
    c = np.array(CENTER)
    w = np.array([f30, f31]) / 2.0 ** BITS
    a = np.r_[CROSSING - 1000.25, c - w]
    cc = np.r_[CROSSING + 1000.25, c + w]
    b = np.r_[500.1, c - w + np.array([f29, f30]) / 2.0 ** BITS]
    tri = np.array([a, b, cc])
    b32 = float(np.float32(500.1))
    tri[1, 0] = b32  # B's position along the rays as float32 holds it
    assert np.array_equal(tri.astype(np.float32).astype(np.float64), tri)
    return tri
