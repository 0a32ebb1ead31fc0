"""CAD-like solids made of lattice cells, with their exact voxelizations.

A shape is a set of occupied cells of a breakpoint lattice (``bp[a]``: the
sorted breakpoints along axis ``a``; cell ``(i, j, k)`` spans
``[bp[0][i], bp[0][i+1]] x ...``): boxes, L-shapes, stairs.  Its boundary is
a closed, outward-oriented triangle mesh (:func:`cells_mesh`), and its exact
voxelizations follow from the breakpoints in voxel space alone, with no
triangle test (naive references for the tests, as kaolin keeps them):

- :func:`conservative_expected`: every voxel whose closed box meets a
  boundary face (a boundary face is a closed axis-aligned rectangle);
- :func:`solid_expected`: the parity solid along ray axis ``a`` with the
  half-open rule along the ray (a center inside iff it lies beyond the
  entering crossing and not beyond the leaving one) and the top-left rule
  across it (S&S Sec. 4.1), i.e. the center nudged by ``(-d, +d', -d'')``
  along ``(a, a+1, a+2)``, which is inside iff the center lies in the
  half-open box ``(x0, x1] x [u0, u1) x (v0, v1]`` of an occupied cell;
- :func:`on_surface`: the voxels whose center lies exactly on the surface,
  where those rules (and the ray direction) decide.

Breakpoints in voxel space must be the values every method sees (snapped by
:func:`glvox.grid.snap_to_planes`).  Shapes whose cells touch only along an
edge or at a corner are not manifold; :data:`SHAPES` has none.
"""

from __future__ import annotations

from typing import Iterator, Sequence

import numpy as np

#: Named shapes: cells per axis and the occupied cells.
SHAPES = {"box": ((1, 1, 1), [(0, 0, 0)]),
          "L": ((2, 2, 1), [(0, 0, 0), (1, 0, 0), (0, 1, 0)]),
          "stairs": ((3, 1, 3), [(i, 0, k) for i in range(3) for k in range(i + 1)])}


def occupancy(shape: str) -> np.ndarray:
    """The occupied cells of a named shape, bool (cells along x, y, z)."""
    dims, cells = SHAPES[shape]
    occ = np.zeros(dims, bool)
    for c in cells:
        occ[c] = True
    return occ


def boundary_faces(occ: np.ndarray) -> Iterator[tuple[int, int, tuple[int, int, int], int]]:
    """Every boundary face: ``(a, plane, cell, sign)``, its normal axis, the index of its
    breakpoint along ``a``, the occupied cell it bounds and its outward direction (+-1)."""
    pad = np.pad(occ, 1)
    for idx in zip(*np.nonzero(occ)):
        for a in range(3):
            for s in (-1, 1):
                nb = np.array(idx) + 1
                nb[a] += s
                if not pad[tuple(nb)]:
                    yield a, int(idx[a]) + (s > 0), tuple(int(i) for i in idx), s


def cells_mesh(bp: Sequence[np.ndarray], occ: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The closed, outward-oriented boundary of the cells: two triangles per boundary face.

    Parameters
    ----------
    bp : three (n_a + 1,) float64
        Breakpoints per axis (any units; world for a mesh to voxelize).
    occ : (n_x, n_y, n_z) bool
        Occupied cells.

    Returns
    -------
    vertices : (V, 3) float64
        Every lattice point (unused ones included).
    faces : (F, 3) int64
    """
    shape = tuple(len(b) for b in bp)
    grid = np.stack(np.meshgrid(*bp, indexing="ij"), axis=-1).reshape(-1, 3)
    faces = []
    for a, plane, idx, s in boundary_faces(occ):
        u, v = (a + 1) % 3, (a + 2) % 3
        quad = []
        for du, dv in ((0, 0), (1, 0), (1, 1), (0, 1)):  # counter-clockwise seen from +a
            p = list(idx)
            p[a], p[u], p[v] = plane, idx[u] + du, idx[v] + dv
            quad.append(np.ravel_multi_index(p, shape))
        if s < 0:
            quad = quad[::-1]
        faces += [quad[:3], [quad[0], quad[2], quad[3]]]
    return grid, np.array(faces, dtype=np.int64)


def _grid(masks: list[np.ndarray]) -> np.ndarray:
    return masks[0][:, None, None] & masks[1][None, :, None] & masks[2][None, None, :]


def conservative_expected(bpv: Sequence[np.ndarray], occ: np.ndarray, dims: Sequence[int]) -> np.ndarray:
    """Voxels whose closed box meets a boundary face, (nx, ny, nz) bool.

    ``bpv``: the breakpoints in voxel space.  Along each axis the voxels
    ``ceil(lo) - 1 .. floor(hi)`` meet ``[lo, hi]`` (a face's plane: lo = hi).
    """
    out = np.zeros(tuple(dims), bool)
    for a, plane, idx, _ in boundary_faces(occ):
        sl = []
        for ax in range(3):
            lo, hi = (bpv[a][plane],) * 2 if ax == a else (bpv[ax][idx[ax]], bpv[ax][idx[ax] + 1])
            sl.append(slice(max(int(np.ceil(lo)) - 1, 0), max(min(int(np.floor(hi)), dims[ax] - 1) + 1, 0)))
        out[tuple(sl)] = True
    return out


def solid_expected(bpv: Sequence[np.ndarray], occ: np.ndarray, dims: Sequence[int], axis: int) -> np.ndarray:
    """The parity solid along ``axis`` with the half-open and top-left rules, (nx, ny, nz) bool."""
    u = (axis + 1) % 3
    out = np.zeros(tuple(dims), bool)
    for idx in zip(*np.nonzero(occ)):
        m = []
        for ax in range(3):
            c = np.arange(dims[ax]) + 0.5
            lo, hi = bpv[ax][idx[ax]], bpv[ax][idx[ax] + 1]
            m.append((c >= lo) & (c < hi) if ax == u else (c > lo) & (c <= hi))
        out |= _grid(m)
    return out


def on_surface(bpv: Sequence[np.ndarray], occ: np.ndarray, dims: Sequence[int]) -> np.ndarray:
    """Voxels whose center lies exactly on a boundary face, (nx, ny, nz) bool."""
    out = np.zeros(tuple(dims), bool)
    c = [np.arange(n) + 0.5 for n in dims]
    for a, plane, idx, _ in boundary_faces(occ):
        out |= _grid([(c[a] == bpv[a][plane]) if ax == a else
                      (c[ax] >= bpv[ax][idx[ax]]) & (c[ax] <= bpv[ax][idx[ax] + 1]) for ax in range(3)])
    return out
