"""The sparse octree solid of Schwarz & Seidel 2010, Sec. 5 (result of ``ss-octree``).

Layout
------
Voxel (i, j, k) of the grid is sub-grid (SG) voxel ``(i % 4, j % 4, k % 4)``
of level-0 node ``(i // 4, j // 4, k // 4)``; a level-L node covers a block
of ``4 * 2**L`` voxels per axis.  The top level ``top`` holds all
``4 x 4 x 4`` nodes of a cube of ``16 * 2**top`` voxels that contains the
grid (the paper stops two levels below the root).  A node has either no
children or all eight.

Each level's nodes are stored contiguously in Morton order (code
``... k1 j1 i1 k0 j0 i0`` of the node's level coordinates), so a node's
children are contiguous, the first at an index that is a multiple of 8, and
child ``c = i0 | j0 << 1 | k0 << 2`` of its parent.  Pointers are indices
within the level they point into; :data:`NONE` (``0xFFFFFFFF``) marks none.

State: a level-0 node stores its 4^3 SG voxels in a uint64 (:attr:`SparseOctree.data`),
SG voxel ``(x, y, z)`` being bit ``x + 4 y + 16 z``; a node above level 0
without children is uniform, inside the solid iff its ``inside`` flag is set.
Bits and blocks beyond the grid's faces (the cube is larger than the grid)
are not part of the result: :meth:`SparseOctree.to_grid`, :attr:`SparseOctree.count`
and :meth:`SparseOctree.coverage` ignore them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FormatError, GridError, LimitError
from ..grid import MAX_VOXELS, GridSpec
from .base import Result, npz_type, require_keys
from .voxels import VoxelGrid

#: Pointer value meaning "no node".
NONE = np.uint32(0xFFFFFFFF)

#: Largest grid size along an axis the octree supports: the top level is 8,
#: level-0 Morton codes fit in 30 bits (uint32 on the GPU), the Morton-indexed
#: bit array of level-1 nodes is 2^27 bits (16 MiB), and the voxel count of a
#: top-level node (2^30) fits a uint32 coverage counter.
MAX_OCTREE_DIM = 4096


def top_level(dims) -> int:
    """The stored top level for grid ``dims``: two levels below the smallest
    root (a level-R node covers ``4 * 2**R`` voxels) that covers the grid, and
    at least 1 (level-1 nodes are the active nodes of Sec. 5.1)."""
    m = max(int(d) for d in dims)
    if m > MAX_OCTREE_DIM:
        raise LimitError(
            f"ss-octree supports grids up to {MAX_OCTREE_DIM} voxels per axis (32-bit Morton codes "
            f"and coverage counts), got dims {tuple(int(d) for d in dims)}"
        )
    r = 0
    while 4 << r < m:
        r += 1
    return max(r - 2, 1)


def spread3(v: np.ndarray) -> np.ndarray:
    """Morton interleave: bit b of v goes to bit 3 b (v < 2**21), uint64."""
    v = np.asarray(v, dtype=np.uint64) & np.uint64(0x1FFFFF)
    for shift, mask in ((32, 0x1F00000000FFFF), (16, 0x1F0000FF0000FF), (8, 0x100F00F00F00F00F),
                        (4, 0x10C30C30C30C30C3), (2, 0x1249249249249249)):
        v = (v | (v << np.uint64(shift))) & np.uint64(mask)
    return v


def compact3(v: np.ndarray) -> np.ndarray:
    """Inverse of :func:`spread3` on every third bit."""
    v = np.asarray(v, dtype=np.uint64) & np.uint64(0x1249249249249249)
    for shift, mask in ((2, 0x10C30C30C30C30C3), (4, 0x100F00F00F00F00F), (8, 0x1F0000FF0000FF),
                        (16, 0x1F00000000FFFF), (32, 0x1FFFFF)):
        v = (v | (v >> np.uint64(shift))) & np.uint64(mask)
    return v


def morton_encode(i, j, k) -> np.ndarray:
    """Morton codes (uint64) of level coordinates, ``... k0 j0 i0``."""
    return spread3(i) | (spread3(j) << np.uint64(1)) | (spread3(k) << np.uint64(2))


def morton_decode(m) -> np.ndarray:
    """(N, 3) int64 level coordinates (i, j, k) of Morton codes."""
    m = np.asarray(m, dtype=np.uint64)
    return np.stack([compact3(m), compact3(m >> np.uint64(1)), compact3(m >> np.uint64(2))],
                    axis=-1).astype(np.int64)


@dataclass
class OctreeLevel:
    """The nodes of one level, in Morton order.

    Attributes
    ----------
    level : int
    morton : (M,) uint32
        Morton code of each node's level coordinates.
    parent : (M,) uint32
        Index of the parent in level + 1 (NONE on the top level).
    x_next, x_prev : (M,) uint32
        Index of the +x / -x neighbour in this level (NONE where that
        neighbour is not stored).
    child : (M,) uint32 or None
        Index of the first of the eight children in level - 1, NONE for a
        node without children; None on level 0.
    inside : (M,) bool or None
        For a node without children: the whole block is inside the solid.
        False for nodes with children; None on level 0 (see ``data``).
    count : (M,) uint32
        Set voxels of the node's block that lie in the grid (coverage count).
    """

    level: int
    morton: np.ndarray
    parent: np.ndarray
    x_next: np.ndarray
    x_prev: np.ndarray
    child: np.ndarray | None
    inside: np.ndarray | None
    count: np.ndarray

    def __len__(self) -> int:
        return int(len(self.morton))

    @property
    def side(self) -> int:
        """Voxels per axis of a node's block."""
        return 4 << self.level

    def coords(self) -> np.ndarray:
        """(M, 3) int64 level coordinates (i, j, k) of the nodes."""
        return morton_decode(self.morton)

    def structure_bytes(self) -> int:
        arrays = [self.morton, self.parent, self.x_next, self.x_prev]
        if self.child is not None:
            arrays.append(self.child)
        return int(sum(a.nbytes for a in arrays))


_FIELDS = ("morton", "parent", "x_next", "x_prev", "child", "inside", "count")


@npz_type("octree_dims")
class SparseOctree(Result):
    """A sparse solid voxelization (Schwarz & Seidel 2010, Sec. 5) on a :class:`GridSpec`.

    Attributes
    ----------
    spec : GridSpec
        The grid the octree voxelizes (dims may exceed what fits densely).
    levels : list of OctreeLevel
        ``levels[L]`` for L = 0 .. top.
    data : (M0,) uint64
        The 4^3 sub-grid of each level-0 node, SG voxel (x, y, z) at bit
        ``x + 4 y + 16 z``.
    run : RunInfo or None
        Set by :func:`glvox.methods.run_method`.
    """

    def __init__(self, spec: GridSpec, levels: list[OctreeLevel], data: np.ndarray, *, run: Any = None):
        super().__init__(spec, run)
        self.levels = list(levels)
        self.data = np.asarray(data, dtype=np.uint64)
        top = top_level(spec.dims)
        if len(self.levels) != top + 1:
            raise GridError(f"an octree on dims {spec.dims} has levels 0..{top}, got {len(self.levels)} levels")
        if len(self.data) != len(self.levels[0]):
            raise GridError(f"expected one uint64 sub-grid per level-0 node ({len(self.levels[0])}), "
                            f"got {len(self.data)}")
        if len(self.levels[top]) != 64:
            raise GridError(f"the top level holds all 4x4x4 nodes, got {len(self.levels[top])}")

    # -- structure -----------------------------------------------------------
    @property
    def top(self) -> int:
        """The top level (all 64 nodes stored)."""
        return len(self.levels) - 1

    @property
    def nodes_per_level(self) -> list[int]:
        return [len(lv) for lv in self.levels]

    # -- content -------------------------------------------------------------
    @property
    def count(self) -> int:
        """Number of set (inside) voxels of the grid."""
        return int(self.levels[self.top].count.astype(np.uint64).sum())

    def __len__(self) -> int:
        return self.count

    def memory(self) -> dict[str, Any]:
        """Memory of the octree as stored here, against a dense bit grid (Table 3).

        Returns
        -------
        dict
            ``structure`` (bytes of Morton codes and child, parent and
            x-neighbour pointers, uint32 each), ``data`` (8 bytes of sub-grid
            per level-0 node, 1 byte of inside flag per node above),
            ``total`` (structure + data), ``coverage`` (the uint32 coverage
            counts, not in the total), ``dense`` (bytes of the grid as bits),
            ``percent_of_dense``, ``level0_nodes``, ``level0_percent`` (stored
            level-0 nodes over all ceil(dims / 4) positions, Table 3's
            "stored level-0 nodes") and ``nodes`` (per level).
        """
        structure = sum(lv.structure_bytes() for lv in self.levels)
        data = int(self.data.nbytes) + sum(len(lv) for lv in self.levels[1:])
        dense = -(-self.spec.n_voxels // 8)
        positions = int(np.prod([-(-d // 4) for d in self.dims], dtype=np.int64))
        m0 = len(self.levels[0])
        return {
            "structure": int(structure), "data": int(data), "total": int(structure + data),
            "coverage": int(sum(lv.count.nbytes for lv in self.levels)),
            "dense": int(dense), "percent_of_dense": 100.0 * (structure + data) / dense,
            "level0_nodes": m0, "level0_percent": 100.0 * m0 / positions,
            "nodes": self.nodes_per_level,
        }

    def uniform_blocks(self, min_level: int = 1):
        """(level, (K, 3) int64 level coordinates) of the inside nodes without children
        from ``min_level`` up, top first: each covers ``4 * 2**level`` voxels per axis."""
        for lv in reversed(self.levels[max(min_level, 1):]):
            sel = (lv.child == NONE) & lv.inside
            if sel.any():
                yield lv.level, morton_decode(lv.morton[sel])

    def leaf_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """The 8^3 blocks of the refined level-1 nodes (the level-0 sub-grids, eight at a time).

        Returns
        -------
        coords : (P, 3) int64
            Level-1 coordinates (a, b, c) of the nodes with children; the block
            covers voxels ``8 (a, b, c)`` to ``8 (a, b, c) + 7``.
        rows : (P, 8, 8) uint8
            ``rows[p, z, y]`` bit x is voxel ``8 (a, b, c) + (x, y, z)``, bits
            beyond the grid's faces as the sub-grids hold them.
        """
        lv1 = self.levels[1]
        par = np.flatnonzero(lv1.child != NONE)
        d = self.data[lv1.child[par].astype(np.int64)[:, None] + np.arange(8)]  # (P, 8)
        r = np.arange(8)
        y8, z8 = r[None, :], r[:, None]                                      # rows (z8, y8)
        shift = (4 * (y8 & 3) + 16 * (z8 & 3)).astype(np.uint64)
        lo_child = ((y8 >> 2) << 1) | ((z8 >> 2) << 2)                      # x = 0 child
        lo = (d[:, lo_child] >> shift) & np.uint64(0xF)
        hi = (d[:, lo_child | 1] >> shift) & np.uint64(0xF)
        return morton_decode(lv1.morton[par]), (lo | (hi << np.uint64(4))).astype(np.uint8)

    def to_grid(self) -> VoxelGrid:
        """The decoded dense grid (VoxelGrid on the same spec, ``run`` shared).

        Raises
        ------
        LimitError
            The grid has more voxels than glvox keeps dense.
        """
        nx, ny, nz = self.dims
        if self.spec.n_voxels > MAX_VOXELS:
            raise LimitError(
                f"decoding {self.dims} ({self.spec.n_voxels} voxels) needs more than the {MAX_VOXELS} "
                "voxels glvox keeps dense; use coverage(level), count or the node arrays"
            )
        bx, by, bz = -(-nx // 8), 8 * -(-ny // 8), 8 * -(-nz // 8)
        # bytes of 8 voxels along x, rows (z, y): a level-1 node is one byte
        # in each of its 8 x 8 rows, so its children fill whole bytes
        grid = np.zeros((bz, by, bx), dtype=np.uint8)
        coords, rows = self.leaf_rows()
        if len(coords):
            a, b, c = coords.T
            r = np.arange(8)
            grid[8 * c[:, None, None] + r[:, None], 8 * b[:, None, None] + r[None, :], a[:, None, None]] = rows
        for level, coords in self.uniform_blocks():
            s = 4 << level
            sx = s // 8
            for a, b, c in coords:
                grid[c * s:(c + 1) * s, b * s:(b + 1) * s, a * sx:(a + 1) * sx] = 0xFF
        wpr = -(-nx // 32)
        rows = np.zeros((nz, ny, 4 * wpr), dtype=np.uint8)
        rows[:, :, :bx] = grid[:nz, :ny, :bx]
        if nx % 8:
            rows[:, :, nx // 8] &= np.uint8((1 << (nx % 8)) - 1)
        return VoxelGrid(words=rows.view("<u4").reshape(nz, ny, wpr), spec=self.spec, run=self.run)

    def coverage(self, level: int = 0) -> np.ndarray:
        """Coverage factors of the blocks of ``level`` (Sec. 5.5).

        Each value is the fraction of the block's ``(4 * 2**level)**3`` voxels
        that are inside, counting voxels beyond the grid as outside: the mean
        of :meth:`to_grid` over the block, exactly (the octree keeps integer
        counts; the value is their quotient rounded once to float32).  Level 0
        is the paper's 64x supersampled scalar grid at a quarter of the
        resolution.

        Returns
        -------
        (cx, cy, cz) float32
            ``c = ceil(dims / (4 * 2**level))``, indexed [i, j, k].
        """
        if not 0 <= level <= self.top:
            raise GridError(f"level must be in 0..{self.top}, got {level!r}")
        s = 4 << level
        vol = float(s) ** 3
        cd = [-(-d // s) for d in self.dims]
        # voxels of each block inside the grid, per axis (s except on the +x, +y, +z faces)
        e = [np.clip(d - s * np.arange(n), 0, s).astype(np.float64) for d, n in zip(self.dims, cd)]
        out = np.zeros(cd, dtype=np.float32)
        for lvl, coords in self.uniform_blocks(level + 1):
            f = 1 << (lvl - level)
            for a, b, c in coords:
                ex, ey, ez = e[0][a * f:(a + 1) * f], e[1][b * f:(b + 1) * f], e[2][c * f:(c + 1) * f]
                frac = ex[:, None, None] * ey[None, :, None] * ez[None, None, :] / vol
                out[a * f:a * f + len(ex), b * f:b * f + len(ey), c * f:c * f + len(ez)] = frac
        lv = self.levels[level]
        ijk = lv.coords()
        keep = np.all(ijk < np.asarray(cd), axis=1)
        i, j, k = ijk[keep].T
        out[i, j, k] = (lv.count[keep].astype(np.float64) / vol).astype(np.float32)
        return out

    # -- persistence ------------------------------------------------------------
    def to_arrays(self) -> dict[str, np.ndarray]:
        """The octree as named arrays (what ``glvox.save`` writes to npz)."""
        out: dict[str, np.ndarray] = {"octree_dims": np.asarray(self.dims, dtype=np.int64),
                                      "octree_data": self.data}
        for lv in self.levels:
            for f in _FIELDS:
                v = getattr(lv, f)
                if v is not None:
                    out[f"octree_L{lv.level}_{f}"] = v
        return out

    @classmethod
    def from_arrays(cls, arrays, spec: GridSpec) -> "SparseOctree":
        """Inverse of :meth:`to_arrays` (``arrays`` maps names to arrays)."""
        try:
            dims = tuple(int(x) for x in arrays["octree_dims"])
            if dims != spec.dims:
                raise FormatError(f"octree dims {dims} do not match the grid's {spec.dims}")
            top = top_level(dims)
            levels = []
            for level in range(top + 1):
                get = {f: arrays.get(f"octree_L{level}_{f}") for f in _FIELDS}
                levels.append(OctreeLevel(
                    level=level,
                    morton=np.asarray(get["morton"], np.uint32), parent=np.asarray(get["parent"], np.uint32),
                    x_next=np.asarray(get["x_next"], np.uint32), x_prev=np.asarray(get["x_prev"], np.uint32),
                    child=None if level == 0 else np.asarray(get["child"], np.uint32),
                    inside=None if level == 0 else np.asarray(get["inside"], bool),
                    count=np.asarray(get["count"], np.uint32)))
            return cls(spec, levels, np.asarray(arrays["octree_data"], np.uint64))
        except (KeyError, TypeError, ValueError, GridError) as exc:
            raise FormatError(f"not a complete sparse octree ({exc})") from None

    def npz_arrays(self) -> dict[str, np.ndarray]:
        return self.to_arrays()

    @classmethod
    def from_npz(cls, z, path: Path) -> "SparseOctree":
        require_keys(z, path, {"origin", "voxel_size"})
        dims = np.asarray(z["octree_dims"])
        if dims.shape != (3,):
            raise FormatError(f"{path}: octree_dims must hold 3 integers, got shape {dims.shape}")
        spec = GridSpec(tuple(int(d) for d in dims), np.asarray(z["origin"], dtype=np.float64),
                        float(z["voxel_size"]))
        try:
            return cls.from_arrays({k: z[k] for k in z.files}, spec)
        except FormatError as exc:
            raise FormatError(f"{path}: {exc}") from None

    def __repr__(self) -> str:
        m = f", method={self.run.method!r}" if self.run is not None else ""
        mem = self.memory()
        return (f"SparseOctree(dims={self.dims}, levels=0..{self.top}, nodes={self.nodes_per_level}, "
                f"level0={mem['level0_percent']:.2f}%, count={self.count}, "
                f"memory={mem['total'] / 2**20:.2f} MiB{m})")
