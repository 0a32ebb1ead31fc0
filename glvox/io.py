"""Reading and writing binary voxel grids: ``.npz`` and ``.binvox``.

npz keys: ``occupancy`` (bool, (nx, ny, nz), indexed [i, j, k]), ``origin``
(float64[3], world position of voxel (0,0,0)'s minimum corner),
``voxel_size`` (float64), ``method`` (str), ``kind`` (str), and one
``extra_<name>`` (bool, (nx, ny, nz)) per mask in ``grid.extras``.

binvox placement
----------------
The binvox header has ``translate`` and ``scale``.  Two readings exist:

* ``'trimesh'`` (default; what ``trimesh.exchange.binvox`` reads and writes):
  ``translate`` is the center of voxel 0 and ``scale`` the distance from the
  first to the last voxel center, (n - 1) h.
* ``'binvox'`` (Patrick Min's binvox tool): ``translate`` is the grid's
  minimum corner and ``scale`` its full length, n h.

glvox writes the trimesh reading so trimesh loads the same occupancy and
placement; pass ``convention='binvox'`` for files made by the binvox tool.
binvox stores cubic grids only (one scale for all axes), so non-cubic grids
are refused: save them as npz.

Sparse octrees (``ss-octree``, :class:`glvox.octree.SparseOctree`)
------------------------------------------------------------------
npz stores the octree itself, never a decoded grid, so a 4096^3 result
stays a few hundred MiB: ``origin``, ``voxel_size``, ``method``, ``kind``
('sparse'), ``octree_dims`` (int64[3]), ``octree_data`` (uint64, one 4^3
sub-grid per level-0 node) and per level L ``octree_L<L>_morton``,
``_parent``, ``_x_next``, ``_x_prev``, ``_count`` (uint32), ``_child``
(uint32) and ``_inside`` (bool) above level 0.  :func:`load` returns a
SparseOctree for such a file.  binvox is dense: an octree is decoded
(:meth:`SparseOctree.to_grid`) when it fits, and refused otherwise.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .errors import FormatError
from .grid import GridSpec, VoxelGrid

CONVENTIONS = ("trimesh", "binvox")


def _suffix(path: Path) -> str:
    s = path.suffix.lower()
    if s not in (".npz", ".binvox"):
        raise FormatError(f"unknown voxel file suffix {path.suffix!r} for {path}: use .npz or .binvox")
    return s


def save(grid: VoxelGrid, path: str | os.PathLike, *, convention: str = "trimesh") -> Path:
    """Write ``grid`` (a VoxelGrid or a SparseOctree) to ``path`` (.npz or .binvox, by suffix)."""
    from .ldi import LDI
    from .octree import SparseOctree

    path = Path(path)
    suffix = _suffix(path)
    if isinstance(grid, LDI):
        if suffix == ".binvox":
            raise FormatError(f"an LDI is saved as .npz (depths per ray), not binvox: {path}")
        return grid.save(path)
    if isinstance(grid, SparseOctree):
        if suffix == ".binvox":
            dense = grid.to_grid()
            path.write_bytes(binvox_bytes(dense, convention=convention))
            return path
        run = grid.run
        np.savez_compressed(
            path, origin=np.asarray(grid.origin, dtype=np.float64), voxel_size=np.float64(grid.voxel_size),
            method=np.str_(run.method if run is not None else ""), kind=np.str_("sparse"),
            **grid.to_arrays(),
        )
        return path
    if _suffix(path) == ".npz":
        run = grid.run
        np.savez_compressed(
            path,
            occupancy=np.asarray(grid.dense(), dtype=bool),
            origin=np.asarray(grid.origin, dtype=np.float64),
            voxel_size=np.float64(grid.voxel_size),
            method=np.str_(run.method if run is not None else ""),
            kind=np.str_(run.kind if run is not None else ""),
            **{f"extra_{k}": np.asarray(g.dense(), dtype=bool) for k, g in grid.extras.items()},
        )
    else:
        path.write_bytes(binvox_bytes(grid, convention=convention))
    return path


def load(path: str | os.PathLike, *, convention: str = "trimesh"):
    """Read a grid written by :func:`save` (or any conforming npz / binvox).

    Returns a VoxelGrid, or a :class:`glvox.octree.SparseOctree` or a
    :class:`glvox.ldi.LDI` for an npz holding one.
    """
    path = Path(path)
    if not path.is_file():
        raise FormatError(f"voxel file not found: {path}")
    if _suffix(path) == ".npz":
        return _load_npz(path)
    return _load_binvox(path.read_bytes(), path, convention)


def _load_npz(path: Path):
    try:
        with np.load(path, allow_pickle=False) as z:
            if "octree_dims" in z.files:
                return _load_octree(path, z)
            if "depths" in z.files and "counts" in z.files:
                from .ldi import LDI

                return LDI.load(path)
            missing = {"occupancy", "origin", "voxel_size"} - set(z.files)
            if missing:
                raise FormatError(f"{path} lacks the npz keys {sorted(missing)}")
            occ = np.asarray(z["occupancy"])
            origin = np.asarray(z["origin"], dtype=np.float64)
            h = float(z["voxel_size"])
            extras = {k[len("extra_"):]: np.asarray(z[k]) for k in z.files if k.startswith("extra_")}
    except FormatError:
        raise
    except Exception as exc:  # noqa: BLE001 - zip/pickle errors vary
        raise FormatError(f"cannot read {path} as npz: {exc}") from None
    if occ.ndim != 3:
        raise FormatError(f"{path}: occupancy must be 3D (nx, ny, nz), got shape {occ.shape}")
    spec = GridSpec(occ.shape, origin, h)
    for k, e in extras.items():
        if e.shape != occ.shape:
            raise FormatError(f"{path}: extra_{k} must have the occupancy's shape {occ.shape}, got {e.shape}")
    return VoxelGrid(occ.astype(bool), spec,
                     extras={k: VoxelGrid(e.astype(bool), spec) for k, e in extras.items()})


def _load_octree(path: Path, z):
    from .octree import SparseOctree

    missing = {"origin", "voxel_size"} - set(z.files)
    if missing:
        raise FormatError(f"{path} lacks the npz keys {sorted(missing)}")
    dims = np.asarray(z["octree_dims"])
    if dims.shape != (3,):
        raise FormatError(f"{path}: octree_dims must hold 3 integers, got shape {dims.shape}")
    spec = GridSpec(tuple(int(d) for d in dims), np.asarray(z["origin"], dtype=np.float64),
                    float(z["voxel_size"]))
    try:
        return SparseOctree.from_arrays({k: z[k] for k in z.files}, spec)
    except FormatError as exc:
        raise FormatError(f"{path}: {exc}") from None


def binvox_bytes(grid: VoxelGrid, *, convention: str = "trimesh") -> bytes:
    """The binvox encoding of ``grid`` (cubic grids only)."""
    if convention not in CONVENTIONS:
        raise FormatError(f"convention must be one of {CONVENTIONS}, got {convention!r}")
    nx, ny, nz = grid.dims
    if not nx == ny == nz:
        raise FormatError(f"binvox stores cubic grids only, got dims {grid.dims}; save as .npz instead")
    n, h = nx, grid.voxel_size
    if convention == "trimesh":
        if n < 2:
            raise FormatError("trimesh's binvox placement needs at least 2 voxels per axis; save as .npz")
        translate, scale = grid.origin + 0.5 * h, (n - 1) * h
    else:
        translate, scale = grid.origin, n * h
    # binvox order: x slowest, then z, then y fastest ("xzy")
    flat = np.ascontiguousarray(np.asarray(grid.dense()).transpose(0, 2, 1)).reshape(-1)
    rle = _rle(flat)
    header = (
        "#binvox 1\n"
        f"dim {nx} {ny} {nz}\n"
        f"translate {float(translate[0])!r} {float(translate[1])!r} {float(translate[2])!r}\n"
        f"scale {float(scale)!r}\n"
        "data\n"
    )
    return header.encode("ascii") + rle


def _rle(flat: np.ndarray) -> bytes:
    """(value, count <= 255) byte pairs of a flat bool array."""
    if flat.size == 0:
        return b""
    change = np.flatnonzero(flat[1:] != flat[:-1]) + 1
    starts = np.concatenate([[0], change])
    lengths = np.diff(np.concatenate([starts, [flat.size]]))
    values = flat[starts].astype(np.uint8)
    reps = (lengths + 254) // 255
    v = np.repeat(values, reps)
    c = np.full(int(reps.sum()), 255, dtype=np.int64)
    last = np.cumsum(reps) - 1
    c[last] = lengths - 255 * (reps - 1)
    return np.stack([v, c.astype(np.uint8)], axis=1).tobytes()


def _load_binvox(data: bytes, path: Path, convention: str) -> VoxelGrid:
    if convention not in CONVENTIONS:
        raise FormatError(f"convention must be one of {CONVENTIONS}, got {convention!r}")
    try:
        end = data.index(b"data\n") + 5
        header = data[:end].decode("ascii").splitlines()
        if not header[0].startswith("#binvox"):
            raise ValueError("missing '#binvox' magic")
        fields = {ln.split()[0]: ln.split()[1:] for ln in header[1:] if ln.strip()}
        dims = tuple(int(x) for x in fields["dim"])
        translate = np.array([float(x) for x in fields["translate"]])
        scale = float(fields["scale"][0])
    except (ValueError, KeyError, IndexError, UnicodeDecodeError) as exc:
        raise FormatError(f"{path} is not a valid binvox file ({exc})") from None
    pairs = np.frombuffer(data[end:], dtype=np.uint8)
    if pairs.size % 2:
        raise FormatError(f"{path}: truncated binvox data (odd byte count)")
    pairs = pairs.reshape(-1, 2)
    flat = np.repeat(pairs[:, 0].astype(bool), pairs[:, 1].astype(np.int64))
    nx, ny, nz = dims
    if flat.size != nx * ny * nz:
        raise FormatError(f"{path}: binvox data holds {flat.size} voxels, header says {nx}x{ny}x{nz}")
    occ = flat.reshape(nx, nz, ny).transpose(0, 2, 1)
    n = nx
    if convention == "trimesh":
        h = scale / (n - 1) if n > 1 else scale
        origin = translate - 0.5 * h
    else:
        h = scale / n
        origin = translate
    return VoxelGrid(np.ascontiguousarray(occ), GridSpec(dims, origin, h))
