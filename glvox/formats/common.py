"""What the format modules share: the :class:`Format` entry, library imports
that fail with one line, dense grids from any result, and placement read back
from an index-to-world matrix."""

from __future__ import annotations

import importlib
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..errors import FormatError, FormatWarning, LimitError
from ..grid import GridSpec
from ..results import LDI, Result, SDFGrid, SparseOctree, VoxelGrid
from ..tolerances import FORMAT_AXIS_RTOL

#: The optional extra that installs the PyPI libraries of the formats.
EXTRA_HINT = "pip install 'glvox[formats]'"


#: :attr:`Format.attributes` of a format that writes every per-voxel attribute.
ALL_ATTRIBUTES = ("*",)


@dataclass(frozen=True)
class Format:
    """One file format: suffixes, its reader and writer, the library it needs.

    Attributes
    ----------
    name : str
        Short name used in messages (``'NRRD'``).
    suffixes : tuple of str
        Lower-case suffixes with the dot (``'.nii.gz'`` counts as one).
    write : callable
        ``write(result, path, **options)``; writes the file.
    read : callable or None
        ``read(path, **options) -> Result``; None for a format glvox only writes.
    library : callable or None
        Imports and returns the format's library, raising :class:`FormatError`
        with the way to install it; None when none is needed.
    options : tuple of str
        Keyword options ``write`` takes beyond the result and the path.
    read_options : tuple of str
        Keyword options ``read`` takes beyond the path.
    sparse : bool
        Writes a :class:`SparseOctree` without decoding it.
    ldi : bool
        Holds an :class:`LDI`.
    check_dims : callable or None
        ``check_dims(dims)`` raises FormatError for dims the format cannot hold.
    attributes : tuple of str
        The per-voxel attributes (``grid.attributes``) it writes; :data:`ALL_ATTRIBUTES`
        for every one.
    sdf : bool
        Holds an :class:`~glvox.results.SDFGrid` as a float32 field (world units).
    """

    name: str
    suffixes: tuple[str, ...]
    write: Callable[..., Any]
    read: Callable[..., Result] | None
    library: Callable[[], Any] | None = None
    options: tuple[str, ...] = ()
    read_options: tuple[str, ...] = ()
    sparse: bool = False
    ldi: bool = False
    check_dims: Callable[[tuple[int, int, int]], None] | None = None
    attributes: tuple[str, ...] = ()
    sdf: bool = False

    def drops(self, names) -> list[str]:
        """Those of the attribute ``names`` this format does not write."""
        return [] if self.attributes == ALL_ATTRIBUTES else [n for n in names if n not in self.attributes]

    def require(self) -> Any:
        """The format's library (imported), or a FormatError saying how to get it."""
        return self.library() if self.library is not None else None


def import_library(module: str, what: str, install: str = EXTRA_HINT) -> Any:
    """``import module`` or a one-line FormatError: '<what> needs <module>: <install>'."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise FormatError(f"{what} needs the Python package {module!r} ({exc}): {install}") from None


def as_grid(result: Result, fmt: str) -> VoxelGrid:
    """The dense VoxelGrid a dense format stores: the result itself, or an octree decoded.

    Raises
    ------
    FormatError
        ``result`` is an LDI, or an octree too large to decode.
    """
    if isinstance(result, LDI):
        raise FormatError(f"an LDI is saved as .npz (depths per ray), not {fmt}")
    if isinstance(result, SparseOctree):
        try:
            return result.to_grid()
        except LimitError as exc:
            raise FormatError(f"{fmt} stores dense grids: {exc}; save the octree as .npz or .vdb") from None
    if not isinstance(result, VoxelGrid):
        raise FormatError(f"{fmt} stores voxel grids, got a {type(result).__name__}")
    return result


def sdf_as_grid(result: SDFGrid) -> VoxelGrid:
    """An SDF as the VoxelGrid that .vti stores: occupancy ``sdf < 0``, the masks ``band`` and
    ``uncertain`` as extra masks and the distances as the float field ``sdf`` (world units)."""
    spec = result.spec
    return VoxelGrid(result.sdf < 0, spec, extras={"band": VoxelGrid(result.band, spec),
                                                   "uncertain": VoxelGrid(result.uncertain, spec)},
                     fields={"sdf": result.sdf})


def warn_sdf_masks(fmt: str) -> None:
    """The :class:`FormatWarning` of a format that keeps an SDF's distances but not its masks."""
    warnings.warn(FormatWarning(f"{fmt} keeps the signed distances only; the band and uncertain masks are not "
                                "written (.npz and .vti keep them)"), stacklevel=3)


def warn_dropped(grid, fmt: str, *, keeps: str = "the occupancy only", keeps_masks: bool = False,
                 keeps_attributes: tuple[str, ...] = ()) -> None:
    """A :class:`FormatWarning` naming the extra masks, float fields (``gwn-solid``'s
    winding numbers) and per-voxel attributes of ``grid`` that format ``fmt`` does not
    write; ``keeps`` says what it does write, ``keeps_masks`` that the masks are among it,
    ``keeps_attributes`` the attributes it writes."""
    extras, fields = getattr(grid, "extras", None) or {}, getattr(grid, "fields", None) or {}
    attributes = [k for k in (getattr(grid, "attributes", None) or {}) if k not in keeps_attributes]
    dropped = [] if keeps_masks else [f"the extra masks {sorted(extras)}"] * bool(extras)
    dropped += [f"the float fields {sorted(fields)}"] * bool(fields)
    dropped += [f"the attributes {sorted(attributes)}"] * bool(attributes)
    if dropped:
        warnings.warn(FormatWarning(f"{fmt} keeps {keeps}; {' and '.join(dropped)} are not written (.npz and "
                                    f".vti keep them all{'' if keeps_masks else ', .vdb the masks'})"), stacklevel=3)


def grid_from_matrix(data: np.ndarray, steps: np.ndarray, first_center: np.ndarray, path: Path,
                     extras: dict[str, np.ndarray] | None = None,
                     fields: dict[str, np.ndarray] | None = None) -> VoxelGrid:
    """A VoxelGrid from an array and the index-to-world placement of a file.

    Parameters
    ----------
    data : (n0, n1, n2) array
        Samples indexed by the file's index axes; nonzero is occupied.
    steps : (3, 3) float64
        ``steps[:, a]`` is the world step of index axis ``a`` (world units).
    first_center : (3,) float64
        World center of sample (0, 0, 0).
    path : Path
        For messages.
    extras : dict of str to (n0, n1, n2) array, optional
        Masks on the same samples (reoriented the same way).
    fields : dict of str to (n0, n1, n2) array, optional
        Float fields on the same samples (reoriented the same way; float32).

    Returns
    -------
    VoxelGrid
        Index axes reordered and flipped so that axis a runs along world axis
        a in the positive direction (a file whose axes are the world axes in
        another order or sign, as medical tools write, reads to the same
        voxels in the world); origin is the min corner of the lowest voxel.

    Raises
    ------
    FormatError
        The axes are not the world axes up to order and sign, or the spacing
        differs between axes (glvox grids have one voxel size), within
        :data:`~glvox.tolerances.FORMAT_AXIS_RTOL`.
    """
    steps = np.asarray(steps, dtype=np.float64).reshape(3, 3)
    lengths = np.linalg.norm(steps, axis=0)
    h = float(lengths.mean())
    if not np.all(np.isfinite(steps)) or not h > 0:
        raise FormatError(f"{path}: the voxel axes {steps.T.tolist()} are not a valid placement")
    world = np.argmax(np.abs(steps), axis=0)                 # world axis of each index axis
    off = steps.copy()
    off[world, np.arange(3)] = 0.0
    if (sorted(world.tolist()) != [0, 1, 2] or np.abs(off).max() > FORMAT_AXIS_RTOL * h
            or np.abs(lengths - h).max() > FORMAT_AXIS_RTOL * h):
        raise FormatError(f"{path}: glvox reads grids whose axes are the world axes with one voxel size; "
                          f"this file's voxel axes are {np.round(steps.T, 9).tolist()} (world units)")
    sign = np.sign(steps[world, np.arange(3)])
    order = np.argsort(world)                                # index axis along world axis w
    arrays = {"": np.asarray(data), **(extras or {}), **{"field " + k: a for k, a in (fields or {}).items()}}
    for key, a in arrays.items():
        a = np.transpose(a, order)
        flips = tuple(w for w in range(3) if sign[order[w]] < 0)
        arrays[key] = np.flip(a, axis=flips) if flips else a
    dims = arrays[""].shape
    c0 = np.asarray(first_center, dtype=np.float64).reshape(3)
    lowest = np.array([c0[w] if sign[order[w]] > 0 else c0[w] - h * (dims[w] - 1) for w in range(3)])
    spec = GridSpec(dims, lowest - 0.5 * h, h)
    # no C-contiguous copy: the files' x-fastest (Fortran) order is the one the bit packing reads
    extra_grids = {k: VoxelGrid(a != 0, spec) for k, a in arrays.items() if k and not k.startswith("field ")}
    float_fields = {k[len("field "):]: a for k, a in arrays.items() if k.startswith("field ")}
    return VoxelGrid(arrays[""] != 0, spec, extras=extra_grids, fields=float_fields)


def center_matrix(spec: GridSpec) -> np.ndarray:
    """(4, 4) float64: voxel indices (i, j, k, 1) to world centers, ``origin + (ijk + 1/2) h``."""
    h = spec.voxel_size
    m = np.diag([h, h, h, 1.0])
    m[:3, 3] = spec.origin + 0.5 * h
    return m
