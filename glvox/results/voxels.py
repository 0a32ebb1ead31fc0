"""The binary voxel grid: the result of every surface and solid method.

npz layout (beside the common keys of :mod:`glvox.results.base`):
``occupancy`` (bool, (nx, ny, nz), indexed [i, j, k]), one ``extra_<name>``
(bool, (nx, ny, nz)) per mask in ``grid.extras`` and one ``field_<name>``
(float32, (nx, ny, nz)) per array in ``grid.fields``, one ``attr_<name>``
per array in ``grid.attributes`` (one row per set voxel, in the order of
:meth:`VoxelGrid.indices`; see :data:`ATTRIBUTE_DTYPES`); ``kind`` is the
run's kind (``'surface'`` or ``'solid'``).  Files without ``attr_`` keys
(every file written before attributes existed) read back with no attributes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from ..errors import FormatError, GridError
from ..grid import GridSpec, pack_bits, popcount, set_indices, unpack_bits
from .base import NpyStream, Result, npz_type, require_keys

#: Voxels per slab of :meth:`VoxelGrid.x_slabs` and :meth:`VoxelGrid.z_slabs`
#: (4 Mi: 4 MiB of bool), so a writer streaming a 1024^3 grid holds tens of
#: MiB beside the packed bits instead of the 1 GiB dense grid and its copies.
SLAB_VOXELS = 1 << 22

#: Per-voxel attributes a grid may carry: name -> (dtype, trailing shape, the
#: value of a voxel without one).  One row per set voxel, in C order of the
#: dense (nx, ny, nz) array (``np.argwhere(grid.dense())``), so memory scales
#: with the set voxels, not the grid.  ``triangle``: the source triangle's
#: index in the input faces; ``color``: RGBA8, alpha 0 where none;
#: ``normal``: unit world-space normal, zeros where none; ``material``: the
#: index of the part / material, -1 where none (glvox/grid.py has the rule).
ATTRIBUTE_DTYPES: dict[str, tuple[np.dtype, tuple[int, ...], Any]] = {
    "triangle": (np.dtype(np.int32), (), -1),
    "color": (np.dtype(np.uint8), (4,), 0),
    "normal": (np.dtype(np.float32), (3,), 0.0),
    "material": (np.dtype(np.int32), (), -1),
}


def c_order(dense: np.ndarray) -> np.ndarray:
    """A C-ordered copy of a Fortran-ordered (nx, ny, nz) bool array, one y plane at a time.

    ``np.ascontiguousarray`` of the transposed GPU layout strides across the
    whole array for every voxel (2.0 s at 512^3 here); a 2D transpose per
    y plane stays in cache (0.59 s).  trimesh keeps C-ordered arrays as they
    are, and copies any other.
    """
    if dense.flags.c_contiguous:
        return dense
    src = dense.transpose(2, 1, 0)  # (nz, ny, nx), C-contiguous when dense is the GPU layout
    out = np.empty(dense.shape, dtype=dense.dtype)
    for j in range(dense.shape[1]):
        out[:, j, :] = src[:, j, :].T
    return out


@dataclass
class Comparison:
    """Differences of a grid against a reference on the same placement.

    ``missing`` are voxels the reference sets and the grid does not,
    ``extra`` the reverse; both (M, 3) int64 voxel indices.
    """

    missing: np.ndarray
    extra: np.ndarray
    count: int
    reference_count: int
    iou: float

    @property
    def n_missing(self) -> int:
        return int(len(self.missing))

    @property
    def n_extra(self) -> int:
        return int(len(self.extra))

    @property
    def equal(self) -> bool:
        return self.n_missing == 0 and self.n_extra == 0

    def to_dict(self) -> dict[str, Any]:
        return {"missing": self.n_missing, "extra": self.n_extra, "count": self.count,
                "reference_count": self.reference_count, "iou": self.iou}


class DeviceWords:
    """A grid's packed words held in GPU memory: uint32 (nz, ny, words_per_row), the
    layout of :meth:`VoxelGrid.words`.  Implemented by a device sink
    (:mod:`glvox.gpu.cuda`); a :class:`VoxelGrid` made from one reads it back only
    when host data is first asked for.

    It is a DLPack producer (``__dlpack__``, ``__dlpack_device__``): ``torch.from_dlpack``,
    ``cupy.from_dlpack`` and ``jax.dlpack.from_dlpack`` take it without a copy.
    """

    #: (nz, ny, words_per_row)
    shape: tuple[int, int, int]

    def to_host(self) -> np.ndarray:
        """The words copied into host memory, uint32 of :attr:`shape`."""
        raise NotImplementedError

    def __dlpack__(self, **kwargs: Any) -> Any:
        raise NotImplementedError

    def __dlpack_device__(self) -> tuple[int, int]:
        raise NotImplementedError


@npz_type(None)
class VoxelGrid(Result):
    """A binary voxel grid on a :class:`GridSpec`.

    Built from a dense bool array indexed [i, j, k] (i along x) or from the
    bit-packed words the GPU methods write; either form is made from the
    other on demand.

    Attributes
    ----------
    spec : GridSpec
    run : RunInfo or None
        Method name, kind, timings and statistics of the run that made it.
    extras : dict of str to VoxelGrid
        Named masks a method returns beside its result on the same spec
        (e.g. ``'unclassifiable'`` of passalis-stencil); saved in npz as
        ``extra_<name>``.
    fields : dict of str to ndarray
        Named float32 arrays (nx, ny, nz), indexed [i, j, k] like
        :meth:`dense`, that a method returns per voxel (e.g. ``'winding'``,
        the generalized winding number at the centers, of reference-gwn and
        gwn-solid); saved in npz as ``field_<name>``.
    attributes : dict of str to ndarray
        Per-voxel data taken from the mesh (``triangle``, ``color``,
        ``normal``, ``material``; :data:`ATTRIBUTE_DTYPES`), one row per set
        voxel in the order of :meth:`indices`; empty when none were asked
        for.  Saved in npz as ``attr_<name>``; :meth:`attribute_grid` gives
        the dense form.

    The constructor's ``count`` is the number of set voxels as the GPU
    method that wrote ``words`` counted them (fused into a pass it runs
    anyway); without it :attr:`count` popcounts on the CPU when first asked.
    :attr:`counted_on` says which.

    ``words`` may be :class:`DeviceWords` (a run with ``device='cuda'``): the grid
    then keeps them on the GPU (:attr:`device_words`) and copies them to the host
    only when host data (:meth:`words`, :meth:`dense`, a file, an uncounted
    :attr:`count`) is first asked for.
    """

    def __init__(self, occupancy: np.ndarray | None = None, spec: GridSpec | None = None, *,
                 words: np.ndarray | None = None, run: Any = None,
                 extras: dict[str, "VoxelGrid"] | None = None, count: int | None = None,
                 fields: dict[str, np.ndarray] | None = None,
                 attributes: dict[str, np.ndarray] | None = None):
        if spec is None:
            raise GridError("a VoxelGrid needs its GridSpec")
        if (occupancy is None) == (words is None):
            raise GridError("give exactly one of occupancy (dense bool) or words (bit-packed)")
        super().__init__(spec, run)
        self.extras: dict[str, VoxelGrid] = {}
        for name, g in (extras or {}).items():
            if not name.isidentifier():
                raise GridError(f"extra mask names must be identifiers, got {name!r}")
            if not isinstance(g, VoxelGrid) or not g.spec.same_placement(spec):
                raise GridError(f"extra mask {name!r} must be a VoxelGrid on {spec}")
            self.extras[name] = g
        self.fields: dict[str, np.ndarray] = {}
        for name, arr in (fields or {}).items():
            a = np.asarray(arr)
            if not name.isidentifier():
                raise GridError(f"field names must be identifiers, got {name!r}")
            if a.shape != spec.dims or a.dtype != np.float32:
                raise GridError(f"field {name!r} must be float32 of shape {spec.dims} (nx, ny, nz), "
                                f"got {a.dtype} {a.shape}")
            self.fields[name] = a
        self._dense: np.ndarray | None = None
        self._host_words: np.ndarray | None = None
        self._device_words: DeviceWords | None = None
        self._count = None if count is None else int(count)
        self._gpu_count = count is not None
        self._indices: np.ndarray | None = None
        if occupancy is not None:
            occ = np.asarray(occupancy)
            if occ.shape != spec.dims:
                raise GridError(f"occupancy must have shape {spec.dims} (nx, ny, nz), got {occ.shape}")
            if occ.dtype != bool:
                raise GridError(f"occupancy must be a bool array, got dtype {occ.dtype}")
            self._dense = occ
        elif isinstance(words, DeviceWords):
            shape = (spec.dims[2], spec.dims[1], spec.words_per_row)
            if tuple(words.shape) != shape:
                raise GridError(f"expected device words of shape {shape} for dims {spec.dims}, got {words.shape}")
            self._device_words = words
        else:
            w = np.asarray(words)
            if w.size != spec.n_words:
                raise GridError(f"expected {spec.n_words} packed words for dims {spec.dims}, got {w.size}")
            self._words = w.reshape(spec.dims[2], spec.dims[1], spec.words_per_row).astype("<u4", copy=False)
        self.attributes: dict[str, np.ndarray] = {}
        for name, arr in (attributes or {}).items():
            self.attributes[name] = self._check_attribute(name, arr)

    def set_attributes(self, attributes: dict[str, np.ndarray]) -> None:
        """Add or replace attributes (checked like the constructor's)."""
        for name, arr in attributes.items():
            self.attributes[name] = self._check_attribute(name, arr)

    def _check_attribute(self, name: str, arr) -> np.ndarray:
        """``arr`` as attribute ``name``: a known name, its dtype, one row per set voxel."""
        if name not in ATTRIBUTE_DTYPES:
            raise GridError(f"unknown attribute {name!r}; known: {', '.join(ATTRIBUTE_DTYPES)}")
        dtype, tail, _ = ATTRIBUTE_DTYPES[name]
        a = np.asarray(arr)
        if a.dtype != dtype or a.shape != (self.count, *tail):
            raise GridError(f"attribute {name!r} must be {dtype} of shape {(self.count, *tail)} "
                            f"(one row per set voxel), got {a.dtype} {a.shape}")
        return a

    # -- data ---------------------------------------------------------------
    @property
    def _words(self) -> np.ndarray | None:
        """The host words: read back from :attr:`device_words` on first use."""
        if self._host_words is None and self._device_words is not None:
            shape = self._device_words.shape
            self._host_words = np.asarray(self._device_words.to_host()).view("<u4").reshape(shape)
        return self._host_words

    @_words.setter
    def _words(self, words: np.ndarray) -> None:
        self._host_words = words

    @property
    def device_words(self) -> DeviceWords | None:
        """The packed words in GPU memory (a DLPack producer), for a grid made on the
        GPU with ``device='cuda'``; None for a host result."""
        return self._device_words

    def dense(self) -> np.ndarray:
        """Occupancy as bool (nx, ny, nz), indexed [i, j, k]; read-only view."""
        if self._dense is None:
            self._dense = unpack_bits(self._words, self.spec.dims)
        v = self._dense.view()
        v.setflags(write=False)
        return v

    def words(self) -> np.ndarray:
        """Bit-packed occupancy, uint32 (nz, ny, words_per_row), GPU layout; read-only view."""
        if self._words is None:
            self._words = pack_bits(self._dense)
        v = self._words.view()
        v.setflags(write=False)
        return v

    def x_slabs(self, max_voxels: int | None = None) -> Iterator[tuple[int, np.ndarray]]:
        """The occupancy in slabs along x, in order, for writers that stream.

        Yields ``(i0, slab)``: ``slab`` bool (n, ny, nz), indexed [i - i0, j, k],
        a view with any strides; the slabs cover i = 0 .. nx - 1.  From the
        dense array when the grid holds one, else unpacked from the packed
        words 8 x at a time (one byte of each row): no dense grid is made or
        kept.  A slab holds at most ``max(max_voxels, 8 ny nz)`` voxels
        (default :data:`SLAB_VOXELS`).
        """
        nx, ny, nz = self.spec.dims
        max_voxels = SLAB_VOXELS if max_voxels is None else max_voxels
        if self._dense is not None:
            step = max(1, max_voxels // (ny * nz))
            for i0 in range(0, nx, step):
                yield i0, self._dense[i0:i0 + step]
            return
        rows = np.ascontiguousarray(self._words).view(np.uint8)  # (nz, ny, 4 words_per_row), x = 8 b + bit
        step = max(1, max_voxels // (8 * ny * nz))
        for b0 in range(0, (nx + 7) // 8, step):
            bits = np.unpackbits(rows[:, :, b0:b0 + step], axis=2, bitorder="little")
            i0 = 8 * b0
            yield i0, bits[:, :, :nx - i0].view(bool).transpose(2, 1, 0)

    def z_slabs(self, max_voxels: int | None = None) -> Iterator[tuple[int, np.ndarray]]:
        """The occupancy in slabs along z, in order: ``(k0, slab)``, ``slab`` bool
        (nx, ny, n) indexed [i, j, k - k0], from the dense array when the grid holds
        one, else unpacked from the packed words (a Fortran-ordered view, x fastest);
        at most ``max(max_voxels, nx ny)`` voxels each."""
        nx, ny, nz = self.spec.dims
        step = max(1, (SLAB_VOXELS if max_voxels is None else max_voxels) // (nx * ny))
        for k0 in range(0, nz, step):
            if self._dense is not None:
                yield k0, self._dense[:, :, k0:k0 + step]
            else:
                part = self._words[k0:k0 + step]
                yield k0, unpack_bits(part, (nx, ny, part.shape[0]))

    @property
    def count(self) -> int:
        """Number of set voxels (counted once; GPU methods may give it, counted on the GPU)."""
        if self._count is None:
            if self._words is not None:
                self._count = popcount(self._words)
            else:
                self._count = int(np.count_nonzero(self._dense))
        return self._count

    @property
    def counted_on(self) -> str:
        """``'gpu'`` when the method that made the grid gave its count (counted on
        the GPU), else ``'cpu'`` (:attr:`count` popcounts the bits when first asked)."""
        return "gpu" if self._gpu_count else "cpu"

    def __len__(self) -> int:
        return self.count

    def indices(self) -> np.ndarray:
        """(M, 3) int64 indices of the set voxels, sorted by i, then j, then k (as ``np.argwhere``);
        read-only view."""
        idx = self._indices if self._indices is not None else set_indices(self.words(), self.spec.dims)
        v = idx.view()
        v.setflags(write=False)
        return v

    def cache_indices(self, indices: np.ndarray) -> None:
        """Keep :meth:`indices` (the attribute pass has them at hand): (M, 3) int64, C order."""
        idx = np.asarray(indices)
        if idx.shape != (self.count, 3) or idx.dtype != np.int64:
            raise GridError(f"indices must be int64 of shape {(self.count, 3)}, got {idx.dtype} {idx.shape}")
        self._indices = idx

    def attribute_grid(self, name: str) -> np.ndarray:
        """The dense form of attribute ``name``: (nx, ny, nz, ...) of its dtype, indexed
        [i, j, k] like :meth:`dense`; voxels without a value (unset ones included)
        hold the attribute's empty value (-1, alpha 0 or zeros; :data:`ATTRIBUTE_DTYPES`)."""
        if name not in self.attributes:
            have = ", ".join(self.attributes) or "none"
            raise GridError(f"this grid has no attribute {name!r} (it has: {have}); "
                            "voxelize with attributes=[...] (--attributes)")
        dtype, tail, empty = ATTRIBUTE_DTYPES[name]
        out = np.full((*self.spec.dims, *tail), empty, dtype=dtype)
        idx = self.indices()
        out[idx[:, 0], idx[:, 1], idx[:, 2]] = self.attributes[name]
        return out

    def points(self) -> np.ndarray:
        """(M, 3) float64 world centers of the set voxels."""
        return self.spec.centers(self.indices())

    def to_trimesh(self):
        """A ``trimesh.voxel.VoxelGrid`` with the same occupancy and placement.

        trimesh's transform maps voxel indices to voxel *centers*, so it is
        scale h and translation origin + h/2.
        """
        import trimesh  # lazy: a heavy optional import, only for this conversion

        h = self.voxel_size
        transform = np.eye(4)
        transform[:3, :3] *= h
        transform[:3, 3] = self.origin + 0.5 * h
        return trimesh.voxel.VoxelGrid(c_order(self.dense()), transform=transform)

    # -- npz ----------------------------------------------------------------
    def npz_arrays(self) -> dict[str, np.ndarray]:
        return {"occupancy": np.asarray(self.dense(), dtype=bool),
                **{f"extra_{k}": np.asarray(g.dense(), dtype=bool) for k, g in self.extras.items()},
                **{f"field_{k}": np.ascontiguousarray(a) for k, a in self.fields.items()},
                **{f"attr_{k}": np.ascontiguousarray(a) for k, a in self.attributes.items()}}

    def npz_members(self) -> dict[str, Any]:
        """:meth:`npz_arrays`, with the occupancy and masks of a grid held as packed words
        streamed (:class:`~glvox.results.base.NpyStream`): the file's bytes are those of
        the dense arrays, but no dense grid is made."""
        return {"occupancy": _bool_member(self),
                **{f"extra_{k}": _bool_member(g) for k, g in self.extras.items()},
                **{f"field_{k}": np.ascontiguousarray(a) for k, a in self.fields.items()},
                **{f"attr_{k}": np.ascontiguousarray(a) for k, a in self.attributes.items()}}

    @classmethod
    def from_npz(cls, z, path: Path) -> "VoxelGrid":
        require_keys(z, path, {"occupancy", "origin", "voxel_size"})
        occ = np.asarray(z["occupancy"])
        if occ.ndim != 3:
            raise FormatError(f"{path}: occupancy must be 3D (nx, ny, nz), got shape {occ.shape}")
        spec = GridSpec(occ.shape, np.asarray(z["origin"], dtype=np.float64), float(z["voxel_size"]))
        extras, fields = {}, {}
        for key in z.files:
            if key.startswith(("extra_", "field_")):
                e = np.asarray(z[key])
                if e.shape != occ.shape:
                    raise FormatError(f"{path}: {key} must have the occupancy's shape {occ.shape}, "
                                      f"got {e.shape}")
                if key.startswith("extra_"):
                    extras[key[len("extra_"):]] = cls(e.astype(bool), spec)
                else:
                    fields[key[len("field_"):]] = e.astype(np.float32)
        attributes = {key[len("attr_"):]: np.asarray(z[key]) for key in z.files if key.startswith("attr_")}
        try:
            return cls(occ.astype(bool), spec, extras=extras, fields=fields, attributes=attributes)
        except GridError as exc:
            raise FormatError(f"{path}: {exc}") from None

    # -- comparison ---------------------------------------------------------
    def _check_same(self, other: "VoxelGrid") -> None:
        if not self.spec.same_placement(other.spec):
            raise GridError(f"cannot compare grids on different placements: {self.spec} vs {other.spec}")

    def equal(self, other: "VoxelGrid") -> bool:
        self._check_same(other)
        return bool(np.array_equal(self.words(), other.words()))

    def compare(self, reference: "VoxelGrid") -> Comparison:
        """Missing and extra voxels against ``reference``, and IoU.

        On the packed words, with any bits past the grid's x extent masked off:
        no dense array is made (at 512^3 the dense comparison took 3 s on 2 CPU
        cores, most of it ``np.argwhere`` over every voxel; the words hold 1/8
        of the bytes and the differences are listed from their non-zero words).
        """
        self._check_same(reference)
        mask = _row_mask(self.spec.dims[0])
        a, b = self.words() & mask, reference.words() & mask
        inter = popcount(a & b)
        union = popcount(a | b)
        return Comparison(
            missing=set_indices(b & ~a, self.spec.dims),
            extra=set_indices(a & ~b, self.spec.dims),
            count=popcount(a),
            reference_count=popcount(b),
            iou=1.0 if union == 0 else inter / union,
        )

    def iou(self, other: "VoxelGrid") -> float:
        return self.compare(other).iou

    def __repr__(self) -> str:
        m = f", method={self.run.method!r}" if self.run is not None else ""
        return f"VoxelGrid(dims={self.dims}, count={self.count}, voxel_size={self.voxel_size:.6g}{m})"


def _row_mask(nx: int) -> np.ndarray:
    """uint32 (words_per_row,): the bits of a row's words that hold voxels 0 .. nx - 1."""
    mask = np.full((nx + 31) // 32, 0xFFFFFFFF, dtype=np.uint32)
    if nx % 32:
        mask[-1] = (1 << (nx % 32)) - 1
    return mask


def _bool_member(grid: VoxelGrid) -> np.ndarray | NpyStream:
    """``grid``'s occupancy as an npz member: its dense array when it holds one, else a
    stream of the bytes :func:`np.lib.format.write_array` writes for :meth:`VoxelGrid.dense`.

    The dense array :func:`~glvox.grid.unpack_bits` makes is Fortran-ordered (x
    fastest) when nx is a multiple of 32 and otherwise neither C- nor
    Fortran-contiguous, which numpy writes in C order; the stream keeps that
    order (so files stay byte for byte what they were): z slabs straight from
    the words, or x slabs transposed.
    """
    if grid._dense is not None:
        return np.asarray(grid._dense, dtype=bool)
    nx, ny, nz = grid.spec.dims
    fortran = nx % 32 == 0 and (ny > 1 or nz > 1)

    def chunks() -> Iterator[bytes]:
        if fortran:
            for _, slab in grid.z_slabs():
                yield slab.T.tobytes()  # (n, ny, nx) C order: the slab's Fortran order
        else:
            for _, slab in grid.x_slabs():
                yield slab.tobytes()    # C order
    return NpyStream({"descr": np.lib.format.dtype_to_descr(np.dtype(bool)), "fortran_order": fortran,
                      "shape": grid.spec.dims}, chunks)
