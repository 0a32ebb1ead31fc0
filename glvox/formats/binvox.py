"""binvox: cubic occupancy grids, run-length encoded.

Placement
---------
The binvox header has ``translate`` and ``scale``.  Two readings exist:

* ``'trimesh'`` (default; what ``trimesh.exchange.binvox`` reads and writes):
  ``translate`` is the center of voxel 0 and ``scale`` the distance from the
  first to the last voxel center, (n - 1) h.
* ``'binvox'`` (Patrick Min's binvox tool): ``translate`` is the grid's
  minimum corner and ``scale`` its full length, n h.

glvox writes the trimesh reading so trimesh loads the same occupancy and
placement; pass ``convention='binvox'`` for files made by the binvox tool (or
read by its viewers).

Files are written as binvox writes them: ``#binvox 1``, ``dim``,
``translate``, ``scale``, ``data`` in this order, LF line ends, numbers in
``%g`` (binvox's C++ default; where ``%g``'s 6 digits would move the
placement, the shortest exact repr instead), runs of at most 255.  They are
read as binvox's reference reader reads them (:func:`parse_header`):
comments, blank lines and unknown keywords are skipped, keywords come in
any order.
binvox stores cubic grids only (one scale for all axes), so non-cubic grids
are refused: save them as npz.  A sparse octree is decoded
(:meth:`SparseOctree.to_grid`) when it fits, and refused otherwise; an LDI
is not a grid and is refused.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterator

import numpy as np

from ..errors import FormatError
from ..grid import GridSpec, pack_bits
from ..results import Result, VoxelGrid
from .common import Format, as_grid, warn_dropped

CONVENTIONS = ("trimesh", "binvox")


def check_dims(dims, convention: str = "trimesh") -> None:
    """FormatError unless binvox can hold a grid of ``dims`` in ``convention``."""
    if convention not in CONVENTIONS:
        raise FormatError(f"convention must be one of {CONVENTIONS}, got {convention!r}")
    dims = tuple(int(d) for d in dims)
    if not dims[0] == dims[1] == dims[2]:
        raise FormatError(f"binvox stores cubic grids only, got dims {dims}; save as .npz instead")
    if convention == "trimesh" and dims[0] < 2:
        raise FormatError("trimesh's binvox placement needs at least 2 voxels per axis; save as .npz")


def write(result: Result, path: Path, *, convention: str = "trimesh") -> None:
    """Write ``result`` (a VoxelGrid, or an octree decoded) as binvox in ``convention``.

    Streamed: the header, then the runs of each x slab as they are found
    (:func:`binvox_chunks`), so memory beyond the grid's packed bits stays at
    a few slabs (tens of MiB at 1024^3), never the dense grid."""
    grid = as_grid(result, "binvox")
    chunks = binvox_chunks(grid, convention=convention)  # checks dims before the file is opened
    warn_dropped(grid, "binvox")
    with open(path, "wb") as f:
        for chunk in chunks:
            f.write(chunk)


def binvox_bytes(grid: VoxelGrid, *, convention: str = "trimesh") -> bytes:
    """The binvox encoding of ``grid`` (cubic grids only)."""
    return b"".join(binvox_chunks(grid, convention=convention))


def binvox_chunks(grid: VoxelGrid, *, convention: str = "trimesh") -> Iterator[bytes]:
    """The binvox encoding of ``grid`` in pieces: the header, then the (value, count)
    pairs slab by slab.

    binvox orders voxels x slowest, then z, then y fastest; each x slab of
    :meth:`VoxelGrid.x_slabs` (unpacked from the packed words when the grid
    holds no dense array) is put in that order and its runs found; the last
    run of a slab is held back, as it may go on in the next one.  The bytes
    equal those of run-length encoding the whole (nx, nz, ny) grid at once.

    Raises
    ------
    FormatError
        A non-cubic grid, or ``convention`` unknown (raised here, before any piece).
    """
    check_dims(grid.dims, convention)
    nx, ny, nz = grid.dims
    n, h = nx, grid.voxel_size
    if convention == "trimesh":
        translate, scale = grid.origin + 0.5 * h, (n - 1) * h
    else:
        translate, scale = grid.origin, n * h
    header = (
        "#binvox 1\n"
        f"dim {nx} {ny} {nz}\n"
        f"translate {_num(translate[0])} {_num(translate[1])} {_num(translate[2])}\n"
        f"scale {_num(scale)}\n"
        "data\n"
    )
    return _chunks(header.encode("ascii"), grid)


def _chunks(header: bytes, grid: VoxelGrid) -> Iterator[bytes]:
    yield header
    value, length = 0, 0  # the run held back from the slabs before (length 0: none)
    for _, slab in grid.x_slabs():
        flat = np.ascontiguousarray(slab.transpose(0, 2, 1)).reshape(-1)  # binvox order: x, z, y fastest
        starts = np.concatenate([[0], np.flatnonzero(flat[1:] != flat[:-1]) + 1])
        lengths = np.diff(np.concatenate([starts, [flat.size]]))
        values = flat[starts].astype(np.uint8)
        if length and values[0] == value:
            lengths[0] += length
        elif length:
            yield _pairs(np.array([value], np.uint8), np.array([length]))
        if len(values) > 1:
            yield _pairs(values[:-1], lengths[:-1])
        value, length = int(values[-1]), int(lengths[-1])
    if length:
        yield _pairs(np.array([value], np.uint8), np.array([length]))


def _num(x) -> str:
    """A header number as binvox writes it (C++ ostream's default, ``%g``: 6 significant
    digits), or, where ``%g`` would move the placement, the shortest repr that reads back exactly."""
    x = float(x)
    g = "%g" % x
    # a few ulps: n * (scale / n) need not give back scale's own bits
    return g if abs(float(g) - x) <= 4 * np.spacing(abs(x)) else repr(x)


def _pairs(values: np.ndarray, lengths: np.ndarray) -> bytes:
    """(value, count <= 255) byte pairs of runs of ``values`` (uint8) of ``lengths``:
    a run longer than 255 becomes runs of 255 and the rest, as binvox writes it."""
    reps = (lengths + 254) // 255
    v = np.repeat(values, reps)
    c = np.full(int(reps.sum()), 255, dtype=np.int64)
    last = np.cumsum(reps) - 1
    c[last] = lengths - 255 * (reps - 1)
    return np.stack([v, c.astype(np.uint8)], axis=1).tobytes()


def parse_header(data: bytes) -> tuple[tuple[int, int, int], np.ndarray, float, int, int]:
    """dims, translate (3,) float64, scale, version and the offset of the first data byte.

    As binvox's reference reader (``read_binvox.cc``) reads a header: the
    first token ``#binvox`` and an integer version, then keywords in any
    order, separated by any whitespace, until the token ``data``, which one
    byte (the line feed) ends; ``dim`` takes three integers, ``translate``
    three numbers and ``scale`` one; every other line (comments ``#...``,
    unknown keywords) is skipped to its end.  ``dim`` is required;
    ``translate`` and ``scale`` default to 0 and 1 (the unit cube), as the
    reference reader, which ignores them, places every file.

    Raises
    ------
    ValueError
        Naming what is wrong (the caller adds the file).
    """
    pos, n = 0, len(data)

    def token() -> bytes:
        nonlocal pos
        while pos < n and data[pos:pos + 1].isspace():
            pos += 1
        start = pos
        while pos < n and not data[pos:pos + 1].isspace():
            pos += 1
        return data[start:pos]

    def skip_line() -> None:
        nonlocal pos
        end = data.find(b"\n", pos)
        pos = n if end < 0 else end + 1

    def number(kind, keyword: str):
        word = token()
        try:
            return kind(word.decode("ascii"))
        except (ValueError, UnicodeDecodeError):
            raise ValueError(f"'{keyword}' takes {'integers' if kind is int else 'numbers'}, "
                             f"got {word[:20].decode('ascii', 'replace')!r}") from None

    magic = token()
    if magic != b"#binvox":
        raise ValueError("missing '#binvox' magic" if not magic.startswith(b"#binvox") else
                         f"the magic '#binvox' must be followed by a space and a version, got {magic[:20]!r}")
    version = token()
    if not version.isdigit():
        raise ValueError(f"'#binvox' must be followed by an integer version, got {version[:20]!r}")
    skip_line()
    dims, translate, scale = None, np.zeros(3), 1.0
    while True:
        word = token()
        if word == b"":
            raise ValueError("the header ends without 'data'")
        if word == b"data":
            if data[pos:pos + 1] != b"\n":
                raise ValueError("'data' must end its line with a line feed (LF)")
            pos += 1
            break
        if word == b"dim":
            dims = tuple(number(int, "dim") for _ in range(3))
        elif word == b"translate":
            translate = np.array([number(float, "translate") for _ in range(3)])
        elif word == b"scale":
            scale = number(float, "scale")
        else:  # a comment or a keyword binvox's reader does not know: the rest of the line
            skip_line()
    if dims is None:
        raise ValueError("no 'dim' line before 'data'")
    if min(dims) < 1:
        raise ValueError(f"dim must be positive, got {dims}")
    return dims, translate, scale, int(version), pos


def read(path: Path, *, convention: str = "trimesh") -> VoxelGrid:
    """Read a binvox file in ``convention``'s placement (see the module docstring).

    The header as binvox's reference reader takes it (:func:`parse_header`);
    the data: (value, count) byte pairs until the grid is full (a run past
    its end, or data that stop short, is an error; bytes after it are
    ignored, as binvox's reader ignores them); any nonzero value is set
    (version 2 files carry values 1..255).
    """
    data = path.read_bytes()
    if convention not in CONVENTIONS:
        raise FormatError(f"convention must be one of {CONVENTIONS}, got {convention!r}")
    try:
        dims, translate, scale, _, end = parse_header(data)
    except (ValueError, UnicodeDecodeError) as exc:
        raise FormatError(f"{path} is not a valid binvox file ({exc})") from None
    nx, ny, nz = dims
    total = nx * ny * nz
    raw = np.frombuffer(data, dtype=np.uint8, offset=end)
    pairs = raw[: raw.size // 2 * 2].reshape(-1, 2)
    filled = np.cumsum(pairs[:, 1], dtype=np.int64)
    used = int(np.searchsorted(filled, total)) + 1  # pairs up to the one that fills the grid
    if used > len(pairs):
        raise FormatError(f"{path}: truncated binvox data: {int(filled[-1]) if len(filled) else 0} voxels, "
                          f"header says {nx}x{ny}x{nz}")
    if filled[used - 1] != total:
        raise FormatError(f"{path}: binvox data overrun: a run ends at voxel {int(filled[used - 1])}, "
                          f"past the {nx}x{ny}x{nz} grid")
    pairs = pairs[:used]
    flat = np.repeat(pairs[:, 0] != 0, pairs[:, 1].astype(np.int64))
    occ = flat.reshape(nx, nz, ny).transpose(0, 2, 1)
    n = nx
    if convention == "trimesh":
        h = scale / (n - 1) if n > 1 else scale
        origin = translate - 0.5 * h
    else:
        h = scale / n
        origin = translate
    # packed as read (x slowest in the file): no dense copy is made or kept
    return VoxelGrid(words=pack_bits(occ), spec=GridSpec(dims, origin, h))


FORMAT = Format("binvox", (".binvox",), write, read, options=("convention",), read_options=("convention",),
                check_dims=check_dims)
