"""Layered depth images (LDI): the result type of the ``ldi`` methods.

An LDI of a solid along ``axis`` (docs/design.md, "Kinds of result"; Leung & Wang
2013 Sec. I) has one ray per pixel: the centers of the grid's voxel columns
along the axis, the pixel axes ``(p, q)`` being the other two axes in
increasing order (x, y for rays along z; y, z along x; x, z along y), so pixel
``(i, j)`` is the ray through ``(i + 1/2, j + 1/2)`` of voxel space.  Each ray
holds its samples sorted by depth; pairs ``(2i, 2i + 1)`` bound the solid
along the ray (an entering and a leaving sample), so every count is even.

Depths are in voxel units along the axis, from the grid's origin: ``0`` is the
grid's near face, ``n_axis`` its far face (``depths_world`` gives world
coordinates).  The solid is clipped to the grid along the axis as every glvox
result is: a ray whose solid extends past the far face is closed there.

npz layout (:meth:`LDI.save`, :meth:`LDI.load`; beside the common keys of
:mod:`glvox.results.base`, ``kind`` being ``'ldi'``): ``depths`` (float32,
``(n_p, n_q, n_max)``, voxel units along the axis, NaN past each ray's count),
``counts`` (int32, ``(n_p, n_q)``), ``axis`` (int), ``dims`` (int64[3], the
grid) and ``lod_c`` (int, 0 when not applicable).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import FormatError, GridError
from ..grid import PLACEMENT_RTOL, GridSpec, ldi_axes
from .base import Result, npz_type, read_npz, require_keys
from .voxels import VoxelGrid

AXIS_NAMES = "xyz"


def _first_beyond(samples: np.ndarray, offset: float, scale: float, n: int) -> np.ndarray:
    """For samples s (voxel units), the first slice k whose center (k + 1/2) / scale + offset
    lies beyond s, clipped to [0, n] (n: none).

    A slice's center c is inside a pair (a, b) iff a < c <= b, the convention of
    ``reference-solid`` (a crossing flips the centers strictly beyond it).
    """
    k = np.floor((samples - offset) * scale + 0.5)
    return np.clip(k, 0, n).astype(np.int64)


@npz_type("depths")
class LDI(Result):
    """A layered depth image on a grid's pixel plane.

    Parameters
    ----------
    depths : (n_p, n_q, n_max) float32
        Samples per ray, sorted, voxel units along ``axis``; NaN past each
        ray's count.
    counts : (n_p, n_q) int
        Samples per ray (even).
    spec : GridSpec
        The grid: pixel ``(i, j)`` is the column of voxels ``(i, j)`` along the
        pixel axes, and depths run over ``[0, spec.dims[axis]]``.
    axis : {0, 1, 2}
        Ray direction.
    lod_c : int, optional
        Leung & Wang's LOD-C (cells along the axis of the bit masks), when the
        LDI comes from that method.

    Attributes
    ----------
    run : RunInfo or None
        Method, timings and statistics of the run that made it.
    """

    def __init__(self, depths: np.ndarray, counts: np.ndarray, spec: GridSpec, axis: int, *,
                 lod_c: int | None = None, run=None):
        if axis not in (0, 1, 2):
            raise GridError(f"axis must be 0, 1 or 2, got {axis!r}")
        p, q = ldi_axes(axis)
        shape = (spec.dims[p], spec.dims[q])
        d = np.asarray(depths)
        if d.ndim != 3 or d.shape[:2] != shape:
            raise GridError(f"depths must have shape {shape + ('n_max',)} (pixels along "
                            f"{AXIS_NAMES[p]}, {AXIS_NAMES[q]}, layers), got {d.shape}")
        c = np.asarray(counts)
        if c.shape != shape:
            raise GridError(f"counts must have shape {shape}, got {c.shape}")
        if c.size and (c.min() < 0 or c.max() > d.shape[2]):
            raise GridError(f"counts must lie in [0, {d.shape[2]}] (the layers of depths), "
                            f"got [{c.min()}, {c.max()}]")
        super().__init__(spec, run)
        self.depths = d.astype(np.float32, copy=False)
        self.counts = c.astype(np.int32, copy=False)
        self.axis = int(axis)
        self.lod_c = None if lod_c is None else int(lod_c)

    # -- placement ----------------------------------------------------------
    @property
    def pixel_axes(self) -> tuple[int, int]:
        """``(p, q)``: the axes of the pixel grid (the other two, increasing)."""
        return ldi_axes(self.axis)

    @property
    def n_max(self) -> int:
        """Layers of ``depths`` (the largest count)."""
        return int(self.depths.shape[2])

    @property
    def samples(self) -> int:
        """Samples over all rays."""
        return int(self.counts.sum())

    @property
    def depths_world(self) -> np.ndarray:
        """(n_p, n_q, n_max) float64 world coordinates along the axis (NaN past the counts)."""
        return self.origin[self.axis] + self.depths.astype(np.float64) * self.voxel_size

    def ray(self, i: int, j: int) -> np.ndarray:
        """(counts[i, j],) float32 samples of pixel (i, j), voxel units."""
        return self.depths[i, j, : self.counts[i, j]]

    def intervals(self, i: int, j: int) -> np.ndarray:
        """(counts[i, j] / 2, 2) float32 solid intervals [enter, leave] of pixel (i, j)."""
        return self.ray(i, j).reshape(-1, 2)

    # -- measures -----------------------------------------------------------
    def lengths(self) -> np.ndarray:
        """(n_p, n_q) float64 length of the solid on each ray, voxel units."""
        d = np.nan_to_num(self.depths.astype(np.float64), nan=0.0)
        if self.n_max == 0:
            return np.zeros(self.counts.shape)
        sign = np.where(np.arange(self.n_max) % 2 == 0, -1.0, 1.0)
        return (d * sign).sum(axis=2)

    @property
    def volume(self) -> float:
        """Volume of the sampled solid, world units cubed: each ray stands for its
        pixel's area ``h^2`` times its solid length."""
        return float(self.lengths().sum()) * self.voxel_size ** 3

    # -- conversion -----------------------------------------------------------
    def _fill(self, n_slices: int, offset: float, scale: float) -> np.ndarray:
        """Parity fill along the axis: (n_p, n_q, n_slices) bool, slice k's center at
        (k + 1/2) / scale + offset voxel units."""
        n_pix = self.counts.size
        layer = np.arange(self.n_max)
        valid = layer[None, None, :] < self.counts[:, :, None]
        pix = np.broadcast_to(np.arange(n_pix).reshape(self.counts.shape)[:, :, None], self.depths.shape)
        first = _first_beyond(self.depths[valid].astype(np.float64), offset, scale, n_slices)
        flat = pix[valid] * (n_slices + 1) + first
        flips = (np.bincount(flat, minlength=n_pix * (n_slices + 1)) % 2).astype(np.uint8)
        occ = np.bitwise_xor.accumulate(flips.reshape(*self.counts.shape, n_slices + 1), axis=2)
        return occ[:, :, :n_slices].astype(bool)

    def _to_xyz(self, occ: np.ndarray) -> np.ndarray:
        """(n_p, n_q, n_a) -> indexed [i, j, k] along x, y, z."""
        p, q = self.pixel_axes
        order = [0, 0, 0]
        order[p], order[q], order[self.axis] = 0, 1, 2
        return np.ascontiguousarray(occ.transpose(order))

    def to_grid(self, spec: GridSpec | None = None, *, nz: int | None = None) -> VoxelGrid:
        """The sampled solid as voxels: a voxel is set iff its center lies in a pair
        ``(enter, leave]`` of its column's ray (the ``reference-solid`` convention).

        Parameters
        ----------
        spec : GridSpec, optional
            Any grid sharing this LDI's pixel plane (same voxel size, and the same
            origin and dims along the two pixel axes); its origin and dims along
            the ray axis are free.  Default: the LDI's own grid.
        nz : int, optional
            Shorthand for the LDI's grid with ``nz`` voxels along the ray axis
            (same origin and voxel size: a shorter or longer grid).  For ``nz``
            slices over the same range instead (non-cubic voxels), see
            :meth:`occupancy`.

        Returns
        -------
        VoxelGrid
        """
        if spec is not None and nz is not None:
            raise GridError("give spec or nz, not both")
        if nz is not None:
            dims = list(self.spec.dims)
            dims[self.axis] = int(nz)
            spec = GridSpec(tuple(dims), self.origin, self.voxel_size)
        spec = spec or self.spec
        p, q = self.pixel_axes
        tol = PLACEMENT_RTOL * self.voxel_size
        same = (abs(spec.voxel_size - self.voxel_size) <= tol
                and all(spec.dims[a] == self.spec.dims[a] for a in (p, q))
                and all(abs(spec.origin[a] - self.origin[a]) <= tol for a in (p, q)))
        if not same:
            raise GridError(f"to_grid needs a grid on this LDI's pixel plane ({self.spec}, rays along "
                            f"{AXIS_NAMES[self.axis]}); got {spec}")
        offset = (spec.origin[self.axis] - self.origin[self.axis]) / self.voxel_size
        occ = self._fill(spec.dims[self.axis], offset, 1.0)
        return VoxelGrid(self._to_xyz(occ), spec)

    def occupancy(self, nz: int | None = None) -> np.ndarray:
        """The sampled solid at ``nz`` slices over the grid's range along the axis.

        Parameters
        ----------
        nz : int, optional
            Slices along the ray axis, each ``n_axis / nz`` voxels thick (the
            voxels are not cubic unless ``nz == n_axis``, the default).

        Returns
        -------
        bool array indexed [i, j, k] along x, y, z, with ``nz`` entries along the axis.
        """
        n_a = self.spec.dims[self.axis]
        nz = n_a if nz is None else int(nz)
        if nz < 1:
            raise GridError(f"nz must be a positive number of slices, got {nz}")
        return self._to_xyz(self._fill(nz, 0.0, nz / n_a))

    # -- files ----------------------------------------------------------------
    file_kind = "ldi"

    def npz_arrays(self) -> dict[str, np.ndarray]:
        return {"depths": self.depths, "counts": self.counts, "axis": np.int64(self.axis),
                "dims": np.asarray(self.spec.dims, dtype=np.int64), "lod_c": np.int64(self.lod_c or 0)}

    def save(self, path: str | os.PathLike) -> Path:
        """Write the npz layout of the module docstring to ``path`` (suffix .npz)."""
        if Path(path).suffix.lower() != ".npz":
            raise FormatError(f"an LDI is saved as .npz, got {path}")
        return super().save(path)

    @classmethod
    def from_npz(cls, z, path: Path) -> "LDI":
        require_keys(z, path, {"depths", "counts", "origin", "voxel_size", "axis", "dims"}, "LDI ")
        spec = GridSpec(tuple(int(x) for x in z["dims"]), np.asarray(z["origin"], dtype=np.float64),
                        float(z["voxel_size"]))
        lod_c = int(z["lod_c"]) if "lod_c" in z.files else 0
        try:
            return cls(np.asarray(z["depths"]), np.asarray(z["counts"]), spec, int(z["axis"]),
                       lod_c=lod_c or None)
        except GridError as exc:
            raise FormatError(f"{path}: {exc}") from None

    @classmethod
    def load(cls, path: str | os.PathLike) -> "LDI":
        """Read an LDI written by :meth:`save`."""
        path = Path(path)
        if not path.is_file():
            raise FormatError(f"LDI file not found: {path}")
        return read_npz(path, expect=cls)

    def __repr__(self) -> str:
        m = f", method={self.run.method!r}" if self.run is not None else ""
        lod = f", lod_c={self.lod_c}" if self.lod_c else ""
        return (f"LDI(axis={AXIS_NAMES[self.axis]}, pixels={self.counts.shape}, n_max={self.n_max}, "
                f"samples={self.samples}{lod}{m})")


def close_odd(depths: np.ndarray, counts: np.ndarray, n_axis: int) -> tuple[np.ndarray, np.ndarray]:
    """Close rays with an odd number of samples at the grid's far face.

    An odd count means the solid (by parity of crossings) extends past the
    last sample to the end of the grid: the clipped solid leaves at ``n_axis``.
    Only open meshes (or rays through ties) produce odd counts.

    Parameters
    ----------
    depths : (n_p, n_q, n_max) float
        Sorted samples, NaN past the counts.
    counts : (n_p, n_q) int

    Returns
    -------
    depths, counts
        With a sample ``n_axis`` appended to the odd rays (one more layer when needed).
    """
    odd = counts % 2 == 1
    if not odd.any():
        return depths, counts
    need = int((counts + odd).max())
    if need > depths.shape[2]:
        pad = np.full(depths.shape[:2] + (need - depths.shape[2],), np.nan, dtype=depths.dtype)
        depths = np.concatenate([depths, pad], axis=2)
    else:
        depths = depths.copy()
    i, j = np.nonzero(odd)
    depths[i, j, counts[odd]] = n_axis
    return depths, counts + odd
