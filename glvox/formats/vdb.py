"""OpenVDB (``.vdb``) through OpenVDB's own Python module.

The module is not on PyPI as wheels: Debian and Ubuntu ship it as
``python3-openvdb`` (``.ci/setup`` installs it and links just that module
into the virtual environment when the Python versions match), conda-forge as
``openvdb``, or build OpenVDB with ``OPENVDB_BUILD_PYTHON_MODULE=ON``.

Written: a ``BoolGrid`` named ``occupancy`` (active voxels with value True;
background False) and one ``BoolGrid`` ``extra_<name>`` per extra mask, each
with the linear transform ``index -> world = index * h + origin + h / 2``:
VDB voxels are cell-centred at integer index coordinates, so voxel (i, j, k)
is VDB index (i, j, k) and its world center ``origin + (i, j, k) h + h/2``.
String metadata ``glvox_dims`` ("nx ny nz", the grid's extent, which a
sparse VDB does not otherwise keep) and ``glvox_placement``.  A
:class:`SparseOctree` is written without a dense grid: each uniform inside
node is one box fill (whole 8^3-aligned blocks become VDB tiles), and each
level-0 4^3 sub-grid a box when full, else a box per full 4 x 4 slab and a
run per x row; with ``coverage=True`` (default) its coverage counts go to a
``FloatGrid`` ``coverage`` at a quarter of the resolution (voxel size 4h,
cell (a, b, c) centred at ``origin + (4 (a, b, c) + 2) h``, values those of
:meth:`SparseOctree.coverage`, zero cells inactive).  A dense grid is
written as one box per x run.  Trees are pruned (uniform leaves become tiles).

A signed distance field (:class:`SDFGrid`) is written as an OpenVDB narrow-band
level set: one ``FloatGrid`` named ``surface`` (Houdini's and OpenVDB's tools'
name for a polygon level set), grid class ``level set``, the same transform,
values in world units, negative inside.  The active voxels are exactly the
SDF's band (where glvox's distance is exact); the background is the band's
half-width in world units (``band_width * h``; the truncation when truncated;
the largest ``|sdf|`` with ``band='all'``, where every voxel is active), and the
inactive voxels inside the mesh hold ``-background`` (OpenVDB's sign
convention), those outside ``+background``.  String metadata
``glvox_dims``, ``glvox_placement``, ``glvox_band_width`` (voxels) and
``glvox_truncation`` (world units, ``none``).  The ``uncertain`` mask is not
written (a warning says so).  glvox does not read level sets back (it refuses
them by name): load the ``.npz`` for that.

Debian's module is built against numpy 1.x; under numpy 2 every call that
takes or returns an array (``copyFromArray``, matrices, float metadata)
crashes, so glvox passes only ints, tuples and strings (box fills and the
accessor) and silences the import's numpy complaint.

Read: the ``BoolGrid`` named ``occupancy``, else the only BoolGrid, into a
dense VoxelGrid (dims from ``glvox_dims``, else the active bounding box);
``extra_<name>`` BoolGrids become extra masks.  The transform must be linear
with one voxel size and the world's axes (up to order and sign).
"""

from __future__ import annotations

import contextlib
import importlib
import io
import math
import warnings
from pathlib import Path

import numpy as np

from ..errors import FormatError, FormatWarning
from ..grid import MAX_VOXELS
from ..results import Result, SparseOctree, VoxelGrid
from ..results.sdf import SDFGrid
from .common import Format, grid_from_matrix, warn_dropped

INSTALL_HINT = ("OpenVDB's Python module is not on PyPI: on Debian/Ubuntu `apt-get install python3-openvdb` "
                "and link pyopenvdb*.so into the environment (as .ci/setup does), or `conda install -c "
                "conda-forge openvdb`")

PLACEMENT_NOTE = "voxel (i, j, k) is index (i, j, k); world center = origin + (i, j, k) h + h/2"


def _library():
    """OpenVDB's module: ``pyopenvdb`` (OpenVDB <= 10, Debian's) or ``openvdb`` (11 and later)."""
    for name in ("pyopenvdb", "openvdb"):
        # a module built against numpy 1.x prints numpy 2's refusal while importing
        # (the module itself loads; glvox calls none of its array functions)
        with contextlib.redirect_stderr(io.StringIO()):
            try:
                return importlib.import_module(name)
            except ImportError:
                continue
    raise FormatError(f".vdb files need OpenVDB's Python module (pyopenvdb): {INSTALL_HINT}")


def _transform(vdb, h: float, first_center: np.ndarray):
    """index -> world: ``index * h + first_center`` (first_center: world center of index 0)."""
    t = vdb.createLinearTransform(voxelSize=float(h))
    t.translate(tuple(float(x) for x in first_center))
    return t


def _apply(grid, boxes: np.ndarray, singles: np.ndarray, value) -> None:
    """Set ``boxes`` (K, 6: min xyz, max xyz inclusive) and ``singles`` (K, 3) active to ``value``."""
    fill = grid.fill
    for b in boxes.tolist():
        fill((b[0], b[1], b[2]), (b[3], b[4], b[5]), value, True)
    set_on = grid.getAccessor().setValueOn
    for p in singles.tolist():
        set_on((p[0], p[1], p[2]), value)


def _split(boxes: np.ndarray, dims) -> tuple[np.ndarray, np.ndarray]:
    """Clip boxes to the grid, drop empty ones, and split off the single voxels."""
    boxes = boxes.copy()
    boxes[:, 3:] = np.minimum(boxes[:, 3:], np.asarray(dims) - 1)
    boxes = boxes[np.all(boxes[:, :3] <= boxes[:, 3:], axis=1)]
    one = np.all(boxes[:, :3] == boxes[:, 3:], axis=1)
    return boxes[~one], boxes[one, :3]


def dense_boxes(occ: np.ndarray) -> np.ndarray:
    """(K, 6) int64 boxes (min xyz, max xyz inclusive): the x runs of a bool (nx, ny, nz) grid."""
    rows = np.ascontiguousarray(np.transpose(occ, (2, 1, 0))).reshape(-1, occ.shape[0])   # (nz ny, nx)
    pad = np.zeros((rows.shape[0], 1), dtype=np.int8)
    step = np.diff(np.concatenate([pad, rows.view(np.int8), pad], axis=1), axis=1)
    r0, x0 = np.nonzero(step == 1)
    _, x1 = np.nonzero(step == -1)                            # row-major: ends pair with starts
    ny = occ.shape[1]
    j, k = r0 % ny, r0 // ny
    return np.stack([x0, j, k, x1 - 1, j, k], axis=1).astype(np.int64)


def _run_table() -> np.ndarray:
    """(256, 9) int64: for each 8-bit row value, its x runs (count, then x0, x1 of up to four)."""
    bits = (np.arange(256)[:, None] >> np.arange(8)) & 1
    step = np.diff(np.pad(bits, ((0, 0), (1, 1))), axis=1)
    table = np.zeros((256, 9), dtype=np.int64)
    for v in range(256):
        starts, ends = np.flatnonzero(step[v] == 1), np.flatnonzero(step[v] == -1) - 1
        table[v, 0] = len(starts)
        table[v, 1:1 + 2 * len(starts)] = np.stack([starts, ends], axis=1).reshape(-1)
    return table


#: x runs of each byte of an 8^3 block's row (see :func:`_run_table`).
_RUNS = _run_table()


def octree_boxes(octree: SparseOctree) -> np.ndarray:
    """(K, 6) int64 boxes (min xyz, max xyz inclusive) covering exactly the octree's set
    voxels, never a dense grid.

    Uniform inside nodes (levels >= 1) are one box each.  The level-0 sub-grids
    are taken eight at a time as the 8^3 block of their level-1 parent (a VDB
    leaf): a full block is one box, a full 8 x 8 z slab one box, and the other
    rows give one box per x run, spanning the consecutive y rows of the slab
    that hold the same byte.  Boxes may reach beyond the grid (the octree's
    cube is larger, and bits beyond the grid's faces are not part of the
    result): :func:`_split` clips them.
    """
    out = [np.zeros((0, 6), np.int64)]
    for level, coords in octree.uniform_blocks():
        lo = coords * (4 << level)
        out.append(np.concatenate([lo, lo + (4 << level) - 1], axis=1))
    coords, rows = octree.leaf_rows()
    base = 8 * coords
    full = (rows == 0xFF).all(axis=(1, 2))
    out.append(np.concatenate([base[full], base[full] + 7], axis=1))
    rows[full] = 0
    slab = (rows == 0xFF).all(axis=2)                                              # (P, 8 z)
    p, z = np.nonzero(slab)
    lo = base[p] + np.stack([0 * z, 0 * z, z], axis=1)
    out.append(np.concatenate([lo, lo + [7, 7, 0]], axis=1))
    rows[slab] = 0
    # groups of consecutive y rows with the same nonzero byte, per (block, z)
    start = rows != 0
    start[:, :, 1:] &= rows[:, :, 1:] != rows[:, :, :-1]
    p, z, y = np.nonzero(start)
    flat = (p * 8 + z) * 8 + y
    same = rows.reshape(-1)
    y1 = y.copy()
    more = np.ones(len(y), bool)
    while more.any():                                                              # at most 7 steps
        nxt = flat + (y1 - y) + 1
        more &= (y1 < 7) & (same[np.minimum(nxt, same.size - 1)] == same[flat])
        y1 += more
    value = same[flat]
    for r in range(4):
        sel = _RUNS[value, 0] > r
        x0, x1 = _RUNS[value[sel], 1 + 2 * r], _RUNS[value[sel], 2 + 2 * r]
        lo = base[p[sel]] + np.stack([x0, y[sel], z[sel]], axis=1)
        hi = base[p[sel]] + np.stack([x1, y1[sel], z[sel]], axis=1)
        out.append(np.concatenate([lo, hi], axis=1))
    return np.concatenate(out, axis=0).astype(np.int64)


def _coverage(vdb, octree: SparseOctree):
    """The octree's level-0 coverage (:meth:`SparseOctree.coverage`) as a sparse FloatGrid."""
    grid = vdb.FloatGrid()
    dims = np.asarray(octree.dims)
    cd = -(-dims // 4)
    edge = dims - 4 * (cd - 1)                                  # in-grid voxels of the last cell per axis
    for level, coords in octree.uniform_blocks():
        f = 1 << level
        lo = coords * f
        hi = np.minimum(lo + f, cd) - 1
        ok = np.all(lo <= hi, axis=1)
        lo, hi = lo[ok], hi[ok]
        _apply(grid, np.concatenate([lo, hi], axis=1), np.zeros((0, 3), np.int64), 1.0)
        # cells on a +face cut by the grid hold a fraction (ex ey ez / 64), as coverage() does
        for a, b in zip(lo.tolist(), hi.tolist()):
            if all(b[ax] < cd[ax] - 1 or edge[ax] == 4 for ax in range(3)):
                continue
            ijk = np.stack(np.meshgrid(*[np.arange(a[ax], b[ax] + 1) for ax in range(3)], indexing="ij"),
                           axis=-1).reshape(-1, 3)
            ijk = ijk[np.any((ijk == cd - 1) & (edge < 4), axis=1)]
            e = np.where(ijk == cd - 1, edge, 4).astype(np.float64)
            vals = (e.prod(axis=1) / 64.0).astype(np.float32)
            acc = grid.getAccessor()
            for p, v in zip(ijk.tolist(), vals.tolist()):
                acc.setValueOn((p[0], p[1], p[2]), v)
    lv0 = octree.levels[0]
    ijk = lv0.coords()
    keep = np.all(ijk < cd, axis=1) & (lv0.count > 0)
    vals = (lv0.count[keep].astype(np.float64) / 64.0).astype(np.float32)
    acc = grid.getAccessor()
    for p, v in zip(ijk[keep].tolist(), vals.tolist()):
        acc.setValueOn((p[0], p[1], p[2]), v)
    grid.name = "coverage"
    grid.transform = _transform(vdb, 4 * octree.voxel_size, octree.origin + 2 * octree.voxel_size)
    grid["glvox_dims"] = " ".join(str(int(c)) for c in cd)
    grid["glvox_placement"] = "cell (a, b, c) covers voxels 4 (a, b, c) .. 4 (a, b, c) + 3; value: inside fraction"
    return grid


def _bool_grid(vdb, name: str, boxes: np.ndarray, result: Result):
    grid = vdb.BoolGrid()
    big, singles = _split(boxes, result.dims)
    _apply(grid, big, singles, True)
    grid.prune()
    grid.name = name
    h = result.voxel_size
    grid.transform = _transform(vdb, h, result.origin + 0.5 * h)
    grid["glvox_dims"] = " ".join(str(int(d)) for d in result.dims)
    grid["glvox_placement"] = PLACEMENT_NOTE
    return grid


#: The name of the level set glvox writes for an SDF.
LEVEL_SET_NAME = "surface"


def level_set_background(result: SDFGrid) -> float:
    """The level set's background, world units: the truncation, else the band's half-width
    ``band_width * voxel_size``, else (``band='all'``) the largest ``|sdf|``."""
    if result.truncation is not None:
        return float(result.truncation)
    if math.isfinite(result.band_width):
        return float(result.band_width * result.voxel_size)
    return float(np.abs(result.sdf).max()) if result.sdf.size else float(result.voxel_size)


def _level_set(vdb, result: SDFGrid):
    """The SDF as a narrow-band FloatGrid level set (see the module docstring)."""
    bg = level_set_background(result)
    grid = vdb.FloatGrid(bg)
    grid.gridClass = vdb.GridClass.LEVEL_SET
    # inactive inside voxels hold -background: box fills over x runs (whole 8^3 blocks become tiles)
    big, singles = _split(dense_boxes((result.sdf < 0) & ~result.band), result.dims)
    fill = grid.fill
    for b in big.tolist():
        fill((b[0], b[1], b[2]), (b[3], b[4], b[5]), -bg, False)
    acc = grid.getAccessor()
    set_off, set_on = acc.setValueOff, acc.setValueOn
    for p in singles.tolist():
        set_off((p[0], p[1], p[2]), -bg)
    # the band's exact distances, one accessor call each (copyFromArray crashes under numpy 2)
    ijk = np.argwhere(result.band)
    for p, v in zip(ijk.tolist(), result.sdf[result.band].tolist()):
        set_on((p[0], p[1], p[2]), v)
    grid.prune()
    grid.name = LEVEL_SET_NAME
    h = result.voxel_size
    grid.transform = _transform(vdb, h, result.origin + 0.5 * h)
    grid["glvox_dims"] = " ".join(str(int(d)) for d in result.dims)
    grid["glvox_placement"] = PLACEMENT_NOTE
    grid["glvox_band_width"] = repr(float(result.band_width))
    grid["glvox_truncation"] = "none" if result.truncation is None else repr(float(result.truncation))
    return grid


def write(result: Result, path: Path, *, coverage: bool = True) -> None:
    """Write ``result`` as BoolGrids (and an octree's coverage FloatGrid when ``coverage``).

    A :class:`SparseOctree` goes straight from its nodes to the VDB (no dense
    grid, so any octree glvox makes fits); a VoxelGrid by its x runs.
    """
    vdb = _library()
    if isinstance(result, SDFGrid):
        if result.n_uncertain:
            warnings.warn(FormatWarning(f"OpenVDB keeps the level set (distances, band as active voxels); the "
                                        f"uncertain mask ({result.n_uncertain} voxels) is not written (.npz "
                                        "and .vti keep it)"), stacklevel=3)
        grids = [_level_set(vdb, result)]
    elif isinstance(result, SparseOctree):
        grids = [_bool_grid(vdb, "occupancy", octree_boxes(result), result)]
        if coverage:
            grids.append(_coverage(vdb, result))
    elif isinstance(result, VoxelGrid):
        # float fields and attributes would go cell by cell through the accessor (numpy 2 cannot reach
        # Debian's copyFromArray): named in a warning instead
        warn_dropped(result, "OpenVDB", keeps="the occupancy and the masks", keeps_masks=True)
        grids = [_bool_grid(vdb, "occupancy", dense_boxes(result.dense()), result)]
        grids += [_bool_grid(vdb, f"extra_{k}", dense_boxes(g.dense()), result) for k, g in result.extras.items()]
    else:
        raise FormatError(f"an LDI is saved as .npz (depths per ray), not OpenVDB: {path}")
    vdb.write(str(path), grids=grids, metadata={"creator": "glvox"})


def _steps(grid) -> tuple[np.ndarray, np.ndarray]:
    """(3, 3) world steps of the index axes and the world center of index 0 (FormatError if not linear)."""
    t = grid.transform
    if not t.isLinear:
        raise FormatError(f"glvox reads VDB grids with a linear transform, got {t.typeName()}")
    c0 = np.array(t.indexToWorld((0.0, 0.0, 0.0)), dtype=np.float64)
    steps = np.stack([np.array(t.indexToWorld(tuple(float(v) for v in e)), dtype=np.float64) - c0
                      for e in np.eye(3)], axis=1)
    return steps, c0


def _fill_dense(grid, lo: np.ndarray, dims: tuple[int, int, int], path: Path) -> np.ndarray:
    """bool (dims) of the grid's active True values (voxels and tiles), index ``lo`` at [0, 0, 0]."""
    mins, maxs = [], []
    for item in grid.iterOnValues():
        if item.value:
            mins.append(item.min)
            maxs.append(item.max)
    a = np.asarray(mins, dtype=np.int64).reshape(-1, 3) - lo
    b = np.asarray(maxs, dtype=np.int64).reshape(-1, 3) - lo
    outside = (a < 0).any(axis=1) | (b >= np.asarray(dims)).any(axis=1)
    if outside.any():
        i = int(np.argmax(outside))
        raise FormatError(f"{path}: grid {grid.name!r} has active voxels in {tuple((a[i] + lo).tolist())}.."
                          f"{tuple((b[i] + lo).tolist())}, outside the extent {tuple(lo.tolist())}.."
                          f"{tuple((lo + np.asarray(dims) - 1).tolist())} of its glvox_dims")
    out = np.zeros(dims, dtype=bool, order="F")               # x fastest, as the bit packing reads it
    one = np.all(a == b, axis=1)
    out[tuple(a[one].T)] = True
    for (x0, y0, z0), (x1, y1, z1) in zip(a[~one].tolist(), b[~one].tolist()):
        out[x0:x1 + 1, y0:y1 + 1, z0:z1 + 1] = True
    return out


def read(path: Path) -> VoxelGrid:
    """A dense VoxelGrid from a VDB file's BoolGrid ``occupancy`` (or its only BoolGrid)."""
    vdb = _library()
    try:
        grids, _ = vdb.readAll(str(path))
    except Exception as exc:  # noqa: BLE001 - OpenVDB raises IOError, KeyError, RuntimeError...
        raise FormatError(f"cannot read {path} as OpenVDB: {exc}") from None
    bools = {g.name: g for g in grids if g.valueTypeName == "bool"}
    level_sets = [g.name for g in grids if g.gridClass == vdb.GridClass.LEVEL_SET]
    if not bools and level_sets:
        raise FormatError(f"{path} holds the level set {level_sets[0]!r}: glvox reads OpenVDB occupancy "
                          "(BoolGrids), not level sets; load the SDF's .npz, or read the .vdb with pyopenvdb")
    occ = bools.get("occupancy") or (next(iter(bools.values())) if len(bools) == 1 else None)
    if occ is None:
        found = [f"{g.name} ({g.valueTypeName})" for g in grids]
        raise FormatError(f"{path}: glvox reads the BoolGrid 'occupancy' (or a file's only BoolGrid); "
                          f"found {found}")
    if "glvox_dims" in occ:
        lo = np.zeros(3, dtype=np.int64)
        dims = tuple(int(x) for x in str(occ["glvox_dims"]).split())
    else:
        if occ.empty():
            raise FormatError(f"{path}: grid {occ.name!r} is empty and has no glvox_dims to give its extent")
        a, b = occ.evalActiveVoxelBoundingBox()
        lo, dims = np.asarray(a, dtype=np.int64), tuple(int(y - x + 1) for x, y in zip(a, b))
    n = dims[0] * dims[1] * dims[2]
    if n > MAX_VOXELS:
        raise FormatError(f"{path}: glvox reads .vdb into a dense grid; dims {dims} ({n} voxels) exceed the "
                          f"{MAX_VOXELS} it keeps dense")
    steps, c0 = _steps(occ)
    first = c0 + steps @ lo
    extras = {k[len("extra_"):]: _fill_dense(g, lo, dims, path) for k, g in bools.items()
              if k.startswith("extra_") and g is not occ}
    return grid_from_matrix(_fill_dense(occ, lo, dims, path), steps, first, path, extras=extras)


FORMAT = Format("OpenVDB", (".vdb",), write, read, library=_library, options=("coverage",), sparse=True,
                sdf=True)
