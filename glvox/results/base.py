"""One base for every result type: placement, how it was made, the npz file.

Every method returns a :class:`Result` of its kind: a
:class:`~glvox.results.voxels.VoxelGrid` (surface and solid methods), a
:class:`~glvox.results.octree.SparseOctree` (``sparse``) or an
:class:`~glvox.results.ldi.LDI` (``ldi``).  They share:

* placement: ``spec`` (a :class:`~glvox.grid.GridSpec`) and its ``dims``,
  ``shape``, ``origin`` and ``voxel_size``;
* ``run``: a :class:`RunInfo` (method, kind, grid, options, timings,
  statistics), set by :func:`glvox.methods.run_method` on the result it
  returns (None for results made by hand or loaded from a file);
* one npz layout: every file holds ``origin`` (float64[3], the world position
  of voxel (0, 0, 0)'s minimum corner), ``voxel_size`` (float64), ``method``
  (str, '' when unknown) and ``kind`` (str), plus the type's own arrays
  (:meth:`Result.npz_arrays`; each type's docstring lists them).
  :func:`read_npz` tells the type from the keys a file holds, so files
  written before this module existed read back the same.
"""

from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, ClassVar

import numpy as np

from ..errors import FormatError, GlvoxError
from ..grid import GridSpec


@dataclass
class RunInfo:
    """How a result was made: method, kind, placement, timings, statistics."""

    method: str
    kind: str
    spec: GridSpec
    timings: Any
    stats: dict[str, Any] = field(default_factory=dict)
    options: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"method": self.method, "kind": self.kind, "grid": self.spec.to_dict(),
                "options": dict(self.options), "stats": dict(self.stats),
                "timings": self.timings.to_dict() if self.timings is not None else None}


class Result:
    """Base of the result types: a grid placement, the run that made it, npz I/O.

    Subclasses call ``super().__init__(spec, run)``, implement
    :meth:`npz_arrays` and :meth:`from_npz`, and register with
    :func:`npz_type` so :func:`read_npz` finds them.
    """

    #: The ``kind`` written to npz files (None: the run's kind, '' without a run).
    file_kind: ClassVar[str | None] = None

    def __init__(self, spec: GridSpec, run: RunInfo | None = None):
        self.spec = spec
        self.run = run

    # -- placement ------------------------------------------------------------
    @property
    def dims(self) -> tuple[int, int, int]:
        return self.spec.dims

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.spec.dims

    @property
    def origin(self) -> np.ndarray:
        return self.spec.origin

    @property
    def voxel_size(self) -> float:
        return self.spec.voxel_size

    # -- npz ------------------------------------------------------------------
    def npz_arrays(self) -> dict[str, np.ndarray]:
        """The type's own npz arrays (beside origin, voxel_size, method and kind)."""
        raise NotImplementedError

    @classmethod
    def from_npz(cls, z, path: Path) -> "Result":
        """A result from an open npz file ``z`` (an ``np.load`` mapping) read from ``path``."""
        raise NotImplementedError

    def npz_members(self) -> dict[str, Any]:
        """The arrays :func:`write_npz` writes beside the common keys: :meth:`npz_arrays`,
        where a type may give an :class:`NpyStream` for an array it can write piece by piece."""
        return self.npz_arrays()

    def save(self, path: str | os.PathLike) -> Path:
        """Write this result to ``path`` as npz (the layout of the module docstring).

        For other formats (binvox) use :func:`glvox.save`, which picks by suffix.
        """
        path = Path(path)
        if path.suffix.lower() != ".npz":
            raise FormatError(f"{type(self).__name__}.save writes .npz, got {path}; "
                              "glvox.save(result, path) picks the format by suffix")
        return write_npz(self, path)


def write_npz(result: Result, path: Path) -> Path:
    """Write ``result``'s npz file: the common keys and its :meth:`Result.npz_arrays`."""
    run = result.run
    kind = result.file_kind if result.file_kind is not None else (run.kind if run is not None else "")
    arrays = {"origin": np.asarray(result.origin, dtype=np.float64), "voxel_size": np.float64(result.voxel_size),
              "method": np.str_(run.method if run is not None else ""), "kind": np.str_(kind),
              **result.npz_members()}
    # what np.savez_compressed writes, at NPZ_COMPRESSLEVEL instead of zlib's default 6
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=NPZ_COMPRESSLEVEL,
                         allowZip64=True) as zf:
        for key, value in arrays.items():
            with zf.open(f"{key}.npy", "w", force_zip64=True) as f:
                if isinstance(value, NpyStream):
                    np.lib.format.write_array_header_1_0(f, value.header)
                    for chunk in value.chunks():
                        f.write(chunk)
                else:
                    np.lib.format.write_array(f, np.asanyarray(value), allow_pickle=False)
    return path


@dataclass(frozen=True)
class NpyStream:
    """An npz member written piece by piece, never whole in memory.

    ``header``: the .npy header (``descr``, ``fortran_order``, ``shape``, as
    :func:`np.lib.format.header_data_from_array_1_0` gives it); ``chunks()``:
    the data bytes in that order, which together are exactly what
    :func:`np.lib.format.write_array` writes for the array, so the file reads
    back with ``np.load`` as the array itself.
    """

    header: dict[str, Any]
    chunks: Callable[[], Any]


#: zlib level of npz files.  Occupancy grids are long runs of zeros: level 1
#: wrote the bunny's 512^3 surface in 0.32 s instead of 0.65 s and reads it
#: back in 0.13 s instead of 0.67 s, for a file of 1.5 MB instead of 0.78 MB
#: (134 MB of bool before compression).
NPZ_COMPRESSLEVEL = 1


#: (marker key, type) pairs, tried in order by :func:`read_npz`; the last one
#: registered with marker None is the fallback.
_NPZ_TYPES: list[tuple[str | None, type[Result]]] = []


def npz_type(marker: str | None) -> Callable[[type[Result]], type[Result]]:
    """Class decorator: files holding the key ``marker`` are read by this type
    (``None``: every file no other type claims)."""

    def register(cls: type[Result]) -> type[Result]:
        _NPZ_TYPES.append((marker, cls))
        return cls

    return register


def read_npz(path: str | os.PathLike, expect: type[Result] | None = None) -> Result:
    """Read a result written by :meth:`Result.save` (or any conforming npz).

    ``expect``: the type the caller needs; a file of another type is a FormatError.
    """
    path = Path(path)
    if not path.is_file():
        raise FormatError(f"voxel file not found: {path}")
    try:
        with np.load(path, allow_pickle=False) as z:
            files = set(z.files)
            cls = next((c for m, c in _NPZ_TYPES if m is not None and m in files),
                       next((c for m, c in _NPZ_TYPES if m is None), None))
            if expect is not None and cls is not expect:
                raise FormatError(f"{path} holds a {cls.__name__ if cls else 'file of unknown type'}, "
                                  f"not a {expect.__name__}")
            return cls.from_npz(z, path)
    except GlvoxError:
        raise
    except Exception as exc:  # noqa: BLE001 - zip/pickle errors vary
        raise FormatError(f"cannot read {path} as npz: {exc}") from None


def require_keys(z, path: Path, keys: set[str], what: str = "") -> None:
    """FormatError naming the keys of ``keys`` that the npz ``z`` lacks (``what``: the
    type, e.g. ``'LDI '``, for the message)."""
    missing = keys - set(z.files)
    if missing:
        raise FormatError(f"{path} lacks the {what}npz keys {sorted(missing)}")
