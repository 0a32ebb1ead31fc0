"""Grid specification: placement, fit, the bit-packed layout.

Convention (docs/design.md, shared by every method and reference)
-------------------------------------------------------------------
A grid has ``dims = (nx, ny, nz)``, a world ``origin`` (the minimum corner of
voxel (0, 0, 0)) and one isotropic voxel size ``h``.  Voxel (i, j, k) is the
closed box ``origin + [i, i+1] x [j, j+1] x [k, k+1] * h``; its center is at
``origin + (i + 0.5, j + 0.5, k + 0.5) * h``.  Voxel space is world space
shifted by ``origin`` and divided by ``h``: voxel (i, j, k) is the unit cube
at (i, j, k).

Worked example: a mesh whose bounding box is [0, 2] x [0, 1] x [0, 1] at
resolution 4 gets h = 2/4 = 0.5, dims (4, 4, 4), and is centered: the grid
spans [0, 2] in x and [-0.5, 1.5] in y and z, so origin = (0, -0.5, -0.5).
Voxel (0, 1, 1)'s center is (0.25, 0.25, 0.25).  With ``tight=True`` the
dims become (4, 2, 2) and origin (0, 0, 0).

Attributes (``attributes=[...]``, ``--attributes``)
---------------------------------------------------
A set voxel takes its data from its *source triangle*: among the triangles
that overlap or touch its closed box (the conservative test, whatever the
method), the one whose closest point to the voxel's center is nearest;
ties (equal distances) go to the lowest triangle index.  ``triangle``,
``material``, ``color`` and ``normal`` are that triangle's, evaluated at that
closest point (vertex colours, UVs and vertex normals interpolated with its
barycentric weights).  A set voxel no triangle overlaps (a solid's interior,
a scanline-ilv voxel off the surface) has none (triangle -1, alpha 0), or,
with ``fill_attributes='nearest'``, those of the nearest voxel that has them.
Per-voxel arrays list the set voxels in C order of the dense (nx, ny, nz)
array (``np.argwhere(grid.dense())``, i.e. :meth:`VoxelGrid.indices`).
GPU and reference agree except at proven ties (two distances within
``glvox.tolerances.ATTR_TIE_EPS``, or an overlap that is itself a tie).

Bit-packed layout (shared with the GLSL side, ``shaders/common/voxel_space.glsl``)
-------------------------------------------------------------------------------
Adjacent x voxels are consecutive bits of 32-bit words (S&S Sec. 3.2): a row
(j, k) holds ``words_per_row = ceil(nx / 32)`` words; voxel (i, j, k) is bit
``i % 32`` of word ``(k * ny + j) * words_per_row + i // 32``.  Bits past nx
in the last word of a row are zero.
"""

from __future__ import annotations

import math
import os
import threading
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .errors import GridError
from .tolerances import FIT_CEIL_SLACK, PLACEMENT_RTOL, SNAP_EPS

#: Largest voxel count of a *dense* result (2^31 - 1 keeps flat indices in
#: int32 on the GPU; the bit array of such a grid is 256 MiB).  Sparse methods
#: (ss-octree) take larger grids; :func:`glvox.methods.run_method` refuses
#: the others beyond it.
MAX_VOXELS = 2**31 - 1

#: Largest grid size along one axis a spec accepts (voxel indices stay in
#: int32 with room to spare).  Methods have their own, lower limits: dense
#: grids are bounded by MAX_VOXELS and the storage-block size, ss-octree by
#: glvox.results.octree.MAX_OCTREE_DIM (4096, 32-bit Morton codes).
MAX_DIM = 2**16

#: Dense grids of at least this many bytes are unpacked by :func:`host_threads`
#: threads (``np.unpackbits`` releases the GIL); below it a thread costs more
#: than it saves.
THREADED_UNPACK_BYTES = 1 << 23

#: Bytes of dense output per ``np.unpackbits`` call when unpacking in threads:
#: each call's temporary stays in the cache before it is copied to the result.
UNPACK_CHUNK_BYTES = 1 << 20

#: Most threads :func:`host_threads` gives by default.
MAX_HOST_THREADS = 8

#: N of the cubic N^3 grid used when no grid is given (``glvox voxelize MESH``,
#: ``glvox.voxelize(mesh)``, ``glvox ldi``, ``glvox volume``, ``glvox batch``):
#: fine enough to show a scanned model's shape, small enough (2 Mi voxels,
#: 256 KiB of bits) for every method and for a software rasterizer.
DEFAULT_RESOLUTION = 128


def _as_dims(dims: Sequence[int]) -> tuple[int, int, int]:
    try:
        d = tuple(int(x) for x in dims)
        ok = len(d) == 3 and all(int(x) == x for x in dims)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise GridError(f"dims must be three integers (nx, ny, nz), got {dims!r}")
    if min(d) < 1:
        raise GridError(f"dims must be at least 1 along every axis, got {d}")
    if max(d) > MAX_DIM:
        raise GridError(f"dims must be at most {MAX_DIM} along every axis, got {d}")
    return d  # type: ignore[return-value]


@dataclass(frozen=True)
class GridSpec:
    """Where the voxels are: dims, world origin and isotropic voxel size.

    Parameters
    ----------
    dims : (3,) int
        Voxels along x, y, z.
    origin : (3,) float64
        World position of voxel (0, 0, 0)'s minimum corner.
    voxel_size : float
        Edge length h of every voxel, world units.
    """

    dims: tuple[int, int, int]
    origin: np.ndarray
    voxel_size: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "dims", _as_dims(self.dims))
        o = np.asarray(self.origin, dtype=np.float64).reshape(-1)
        if o.shape != (3,) or not np.all(np.isfinite(o)):
            raise GridError(f"origin must be 3 finite numbers, got {self.origin!r}")
        o.setflags(write=False)
        object.__setattr__(self, "origin", o)
        h = float(self.voxel_size)
        if not (math.isfinite(h) and h > 0):
            raise GridError(f"voxel_size must be a finite positive number, got {self.voxel_size!r}")
        object.__setattr__(self, "voxel_size", h)

    # -- derived -------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int, int]:
        return self.dims

    @property
    def n_voxels(self) -> int:
        nx, ny, nz = self.dims
        return nx * ny * nz

    @property
    def words_per_row(self) -> int:
        return (self.dims[0] + 31) // 32

    @property
    def n_words(self) -> int:
        """32-bit words of the bit-packed grid."""
        return self.words_per_row * self.dims[1] * self.dims[2]

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float64: world min and max corner of the whole grid."""
        return np.stack([self.origin, self.origin + np.asarray(self.dims) * self.voxel_size])

    def world_to_voxel(self, points: np.ndarray) -> np.ndarray:
        """World points (..., 3) -> voxel-space points (..., 3), float64."""
        return (np.asarray(points, dtype=np.float64) - self.origin) / self.voxel_size

    def vertices_to_voxel(self, points: np.ndarray, eps: float = SNAP_EPS) -> np.ndarray:
        """Mesh vertices (..., 3) -> voxel space as every method sees them, float64:
        :meth:`world_to_voxel`, then :func:`snap_to_planes` (within ``eps`` voxel)."""
        return snap_to_planes(self.world_to_voxel(points), eps)

    def voxel_to_world(self, points: np.ndarray) -> np.ndarray:
        """Voxel-space points (..., 3) -> world points (..., 3), float64."""
        return np.asarray(points, dtype=np.float64) * self.voxel_size + self.origin

    def centers(self, indices: np.ndarray) -> np.ndarray:
        """World centers (M, 3) of integer voxel indices (M, 3)."""
        return self.voxel_to_world(np.asarray(indices, dtype=np.float64) + 0.5)

    def same_placement(self, other: "GridSpec", rtol: float = PLACEMENT_RTOL) -> bool:
        """True when dims agree and origin and voxel size agree within ``rtol * h``."""
        tol = rtol * self.voxel_size
        return (
            self.dims == other.dims
            and abs(self.voxel_size - other.voxel_size) <= tol
            and bool(np.all(np.abs(self.origin - other.origin) <= tol))
        )

    def to_dict(self) -> dict[str, Any]:
        return {"dims": list(self.dims), "origin": self.origin.tolist(), "voxel_size": self.voxel_size}

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, GridSpec):
            return NotImplemented
        return (self.dims == other.dims and self.voxel_size == other.voxel_size
                and bool(np.array_equal(self.origin, other.origin)))

    def __hash__(self) -> int:
        return hash((self.dims, self.voxel_size, tuple(self.origin.tolist())))

    def __repr__(self) -> str:
        o = ", ".join(f"{x:.6g}" for x in self.origin)
        return f"GridSpec(dims={self.dims}, origin=({o}), voxel_size={self.voxel_size:.6g})"


def snap_to_planes(points: np.ndarray, eps: float = SNAP_EPS) -> np.ndarray:
    """Voxel-space coordinates within ``eps`` of a multiple of 1/2 moved onto it.

    The one tie policy for geometry on voxel planes (README, "Ties"): every
    method and reference sees mesh vertices through this rule, the GPU in
    double before its float32 rounding (``shaders/common/snap.glsl``, the
    same operations), so a face that lies on a voxel face plane (integer) or
    a voxel center plane (integer + 1/2) up to rounding lies exactly on it
    for all of them, and the definitions (touching counts; the half-open and
    top-left rules of solids) decide it, not the rounding.

    Parameters
    ----------
    points : (..., 3) float64
        Voxel-space coordinates.
    eps : float
        Snap distance, voxels (:data:`glvox.tolerances.SNAP_EPS`); 0 snaps
        only coordinates already on a plane (returns them unchanged).

    Returns
    -------
    (..., 3) float64
        A new array; multiples of 1/2 below 2^23 are exact in float32 too.
    """
    p = np.asarray(points, dtype=np.float64)
    r = np.floor(2.0 * p + 0.5) * 0.5
    return np.where(np.abs(p - r) <= eps, r, p)


def _checked_bounds(bounds) -> np.ndarray:
    """``bounds`` as a finite float64 (2, 3) [min, max] with max >= min; GridError otherwise."""
    b = np.asarray(bounds, dtype=np.float64)
    if b.shape != (2, 3) or not np.all(np.isfinite(b)):
        raise GridError(f"bounds must be a finite (2, 3) array [min, max], got shape {b.shape}")
    if np.any(b[1] < b[0]):
        raise GridError(f"bounds max must be >= min on every axis, got min {b[0]} max {b[1]}")
    return b


def fit_grid(
    bounds: np.ndarray,
    resolution: int | None = None,
    *,
    dims: Sequence[int] | None = None,
    voxel_size: float | None = None,
    padding: int = 0,
    tight: bool = False,
) -> GridSpec:
    """Fit a grid around world-space ``bounds`` (2, 3).

    Default (the papers' fit): ``resolution=N`` gives h = max_extent / N and a
    cubic N^3 grid centered on the bounding box.

    Parameters
    ----------
    bounds : (2, 3) float
        Min and max corner to cover (the mesh's bounding box, or explicit
        bounds chosen by the user).
    resolution : int, optional
        Voxels along the longest axis (N).
    dims : (3,) int, optional
        Explicit, possibly non-cubic dims.  h is the smallest isotropic size
        for which the bounds fit, and the bounds are centered in the grid.
    voxel_size : float, optional
        Explicit h; dims = ceil(extent / h) per axis (at least 1), centered.
    padding : int
        Empty voxels kept between the bounds and the grid's faces on every
        side.  With ``resolution`` the dims stay N (the model shrinks:
        h = max_extent / (N - 2 padding)); with ``voxel_size`` the dims grow
        by 2 padding.
    tight : bool
        With ``resolution``: per-axis dims ceil(extent / h) instead of N^3.

    Returns
    -------
    GridSpec
    """
    b = _checked_bounds(bounds)
    padding = int(padding)
    if padding < 0:
        raise GridError(f"padding must be >= 0 voxels, got {padding}")
    given = [x is not None for x in (resolution, dims, voxel_size)]
    if sum(given) != 1:
        raise GridError("give exactly one of resolution, dims or voxel_size")
    extent = b[1] - b[0]
    center = 0.5 * (b[0] + b[1])
    max_extent = float(extent.max())

    if resolution is not None:
        n = int(resolution)
        if n != resolution or n < 1:
            raise GridError(f"resolution must be a positive integer, got {resolution!r}")
        inner = n - 2 * padding
        if inner < 1:
            raise GridError(f"padding {padding} leaves no voxel inside a grid of resolution {n}")
        if max_extent <= 0:
            raise GridError("the bounds have zero extent on every axis (a single point); "
                            "give voxel_size explicitly")
        h = max_extent / inner
        if tight:
            inner_dims = np.maximum(1, np.ceil(extent / h - FIT_CEIL_SLACK)).astype(int)
            d = tuple(int(x) + 2 * padding for x in inner_dims)
        else:
            d = (n, n, n)
    elif dims is not None:
        d = _as_dims(dims)
        inner = np.asarray(d) - 2 * padding
        if np.any(inner < 1):
            raise GridError(f"padding {padding} leaves no voxel inside dims {d}")
        with np.errstate(divide="ignore", invalid="ignore"):
            h = float(np.max(extent / inner))
        if not h > 0:
            raise GridError("the bounds have zero extent on every axis; give voxel_size explicitly")
    else:
        h = float(voxel_size)  # type: ignore[arg-type]
        if not (math.isfinite(h) and h > 0):
            raise GridError(f"voxel_size must be a finite positive number, got {voxel_size!r}")
        inner_dims = np.maximum(1, np.ceil(extent / h - FIT_CEIL_SLACK)).astype(int)
        d = tuple(int(x) + 2 * padding for x in inner_dims)
    origin = center - 0.5 * np.asarray(d, dtype=np.float64) * h
    return GridSpec(dims=_as_dims(d), origin=origin, voxel_size=h)


def grid_for(mesh, resolution: int | None = None, *, dims: Sequence[int] | None = None,
             voxel_size: float | None = None, bounds: Any = None, padding: int = 0,
             tight: bool = False) -> GridSpec:
    """The grid spec for ``mesh`` (a :class:`glvox.mesh.Mesh`; see :func:`fit_grid`).

    ``bounds`` (2, 3) replaces the mesh's bounding box as the region to cover.
    """
    b = mesh.bounds if bounds is None else np.asarray(bounds, dtype=np.float64)
    return fit_grid(b, resolution, dims=dims, voxel_size=voxel_size, padding=padding, tight=tight)


def binvox_grid(bounds: np.ndarray, n: int) -> GridSpec:
    """binvox's placement of an ``n``^3 grid around world-space ``bounds`` (2, 3).

    binvox moves the bounding box's minimum corner to the origin and scales its
    longest side to 1 (no centering of the shorter axes, no padding), then
    samples voxel centers at ``(i + 0.5) / n``: in world units the grid's
    minimum corner is the bounding box's (``origin = bounds[0]``, binvox's
    ``translate``) and ``h = max extent / n`` (``n h`` is binvox's ``scale``).

    Worked example: bounds [-1, 2] x [0, 1] x [0, 0.5] at n = 4 give
    origin (-1, 0, 0), h = 0.75, dims (4, 4, 4); the grid spans [-1, 2] along x
    and [0, 3] along y and z.

    Parameters
    ----------
    bounds : (2, 3) float
        Min and max corner (binvox: of every vertex of the file).
    n : int
        Voxels along every axis (binvox ``-d``).

    Returns
    -------
    GridSpec
    """
    b = _checked_bounds(bounds)
    if int(n) != n or n < 1:
        raise GridError(f"resolution must be a positive integer, got {n!r}")
    extent = float((b[1] - b[0]).max())
    if not extent > 0:
        raise GridError("the bounds have zero extent on every axis (a single point): binvox cannot scale them")
    return GridSpec((int(n),) * 3, b[0], extent / int(n))


# ---------------------------------------------------------------------------
# packing
# ---------------------------------------------------------------------------


def ldi_axes(axis: int) -> tuple[int, int]:
    """The pixel axes ``(p, q)`` of rays along ``axis``: the other two, in increasing order."""
    if axis not in (0, 1, 2):
        raise GridError(f"axis must be 0, 1 or 2, got {axis!r}")
    p, q = (a for a in range(3) if a != axis)
    return p, q


def popcount(words: np.ndarray) -> int:
    """Set bits in packed words (unsigned integers of any shape)."""
    return int(np.bitwise_count(words).sum(dtype=np.int64))


def pack_bits(dense: np.ndarray) -> np.ndarray:
    """Dense bool (nx, ny, nz) -> uint32 words (nz, ny, words_per_row), GPU layout.

    An array in Fortran order (x fastest, as :func:`unpack_bits` makes them) is
    packed along its rows as they lie.  Any other is packed plane by plane of x
    (each (y, z) plane shifted into its bit of the bytes of its 8 x) and only the
    packed bytes, an eighth of it, are transposed: transposing a C-order bool
    array itself took 0.5 s at 512^3 on 2 CPU cores (0.12 s so), and one in a
    binvox file's layout 1.3 s (0.2 s).
    """
    nx, ny, nz = dense.shape
    wpr = (nx + 31) // 32
    d = np.asarray(dense, dtype=bool)
    if not d.transpose(2, 1, 0).flags.c_contiguous:
        packed = np.zeros((wpr * 4, ny, nz), dtype=np.uint8)
        planes = d.view(np.uint8)
        for x in range(nx):
            packed[x >> 3] |= planes[x] << np.uint8(x & 7)
        return np.ascontiguousarray(packed.transpose(2, 1, 0)).view("<u4").reshape(nz, ny, wpr)
    t = d.transpose(2, 1, 0)
    if wpr * 32 != nx:
        t = np.concatenate([t, np.zeros((nz, ny, wpr * 32 - nx), dtype=bool)], axis=2)
    packed = np.packbits(t, axis=2, bitorder="little")
    return packed.view("<u4").reshape(nz, ny, wpr)


def host_threads() -> int:
    """Threads glvox's host-side array work may use (today: :func:`unpack_bits`).

    ``GLVOX_THREADS`` when set (a positive integer; ``glvox batch`` sets it per
    worker to the CPUs divided among the workers), else the CPUs this process
    may run on, at most :data:`MAX_HOST_THREADS`.
    """
    raw = os.environ.get("GLVOX_THREADS", "").strip()
    if raw:
        try:
            n = int(raw)
        except ValueError:
            n = 0
        if n < 1:
            raise GridError(f"GLVOX_THREADS must be a positive integer, got {raw!r}")
        return n
    try:
        cpus = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not Linux
        cpus = os.cpu_count() or 1
    return max(1, min(cpus, MAX_HOST_THREADS))


def unpack_bits(words: np.ndarray, dims: Sequence[int]) -> np.ndarray:
    """uint32 words (any shape with the right size) -> dense bool (nx, ny, nz).

    ``np.unpackbits`` into fresh memory, viewed as bool and transposed: no
    further copy (an ``astype(bool)`` copy doubled the time).  The result is a
    Fortran-ordered view (x fastest in memory, the GPU's layout).  From
    :data:`THREADED_UNPACK_BYTES` of output on, :func:`host_threads` threads each
    unpack a run of rows, :data:`UNPACK_CHUNK_BYTES` at a time, into one array
    allocated up front (docs/performance.md has the measurement).
    """
    nx, ny, nz = dims
    wpr = (nx + 31) // 32
    w = np.ascontiguousarray(np.asarray(words).reshape(-1).astype("<u4", copy=False))
    if w.size != wpr * ny * nz:
        raise GridError(f"expected {wpr * ny * nz} words for dims {tuple(dims)}, got {w.size}")
    rows = w.view(np.uint8).reshape(nz * ny, wpr * 4)
    threads = host_threads()  # read on every call: a bad GLVOX_THREADS fails alike on any grid
    threads = threads if rows.size * 8 >= THREADED_UNPACK_BYTES else 1
    if threads < 2 or rows.shape[0] < 2:
        bits = np.unpackbits(rows, axis=1, bitorder="little")
    else:
        bits = np.empty((nz * ny, wpr * 32), dtype=np.uint8)
        chunk = max(1, UNPACK_CHUNK_BYTES // (wpr * 32))  # rows per np.unpackbits call

        def unpack(r0: int, r1: int) -> None:
            for r in range(r0, r1, chunk):
                e = min(r + chunk, r1)
                bits[r:e] = np.unpackbits(rows[r:e], axis=1, bitorder="little")

        threads = min(threads, rows.shape[0])
        cuts = [rows.shape[0] * t // threads for t in range(threads + 1)]
        errors: list[BaseException] = []

        def run(r0: int, r1: int) -> None:
            try:
                unpack(r0, r1)
            except BaseException as exc:  # noqa: BLE001 - re-raised in the caller's thread
                errors.append(exc)

        helpers = [threading.Thread(target=run, args=(a, b), name=f"glvox-unpack-{t}", daemon=True)
                   for t, (a, b) in enumerate(zip(cuts[1:-1], cuts[2:]), start=1)]
        for h in helpers:
            h.start()
        run(cuts[0], cuts[1])  # the first run of rows in this thread
        for h in helpers:
            h.join()
        if errors:
            raise errors[0]
    return bits.reshape(nz, ny, wpr * 32)[:, :, :nx].view(bool).transpose(2, 1, 0)


def set_indices(words: np.ndarray, dims: Sequence[int]) -> np.ndarray:
    """(M, 3) int64 indices (i, j, k) of the set bits of packed ``words``, sorted by i, then j, then k.

    From the non-zero words only, then one sort of the C-order flat indices:
    ``np.argwhere`` of the dense array walks all nx * ny * nz voxels in a
    memory order against its Fortran layout.
    """
    nx, ny, nz = dims
    wpr = (nx + 31) // 32
    flat = np.ascontiguousarray(np.asarray(words).reshape(-1).astype("<u4", copy=False))
    nonzero = np.flatnonzero(flat)
    bits = np.unpackbits(flat[nonzero].view(np.uint8).reshape(-1, 4), axis=1, bitorder="little")
    row, bit = np.nonzero(bits)
    word = nonzero[row]
    i = (word % wpr) * 32 + bit
    jk = word // wpr  # k * ny + j
    key = (i * ny + jk % ny) * nz + jk // ny
    key.sort()
    out = np.empty((len(key), 3), dtype=np.int64)
    out[:, 0], rest = np.divmod(key, ny * nz)
    out[:, 1], out[:, 2] = np.divmod(rest, nz)
    return out
