"""The file formats glvox reads and writes, one module each, picked by suffix.

==========  ====================  ==========================  ========================================
format      suffixes              library (extra)             holds
==========  ====================  ==========================  ========================================
npz         ``.npz``              numpy                       every result type in its own layout
binvox      ``.binvox``           none                        cubic occupancy (trimesh's placement)
NRRD        ``.nrrd``             pynrrd (``formats``)        occupancy, uint8, cell-centered
NIfTI-1     ``.nii``, ``.nii.gz`` nibabel (``formats``)       occupancy, uint8, qform = sform
VTK image   ``.vti``              none (glvox writes XML)     occupancy + extra masks, uint8 cell data
OpenVDB     ``.vdb``              OpenVDB's Python module     BoolGrids (+ octree coverage FloatGrid),
                                                              sparse: octrees never become dense
MagicaVoxel ``.vox``              Pillow (``formats``)        voxels in a <= 255-colour palette, models
                                                              of <= 256 per axis by the scene graph
points      ``.points.ply/.glb``  trimesh                     voxel centers in their colours (write only)
cubes       ``.cubes.ply/.glb``   trimesh                     exposed cube faces in the voxels' colours
                                                              (write only)
==========  ====================  ==========================  ========================================

Placement is the same in every format: the world position of voxel
(i, j, k)'s center is ``origin + (i, j, k) * h + h / 2`` (each module says
how its header encodes it).  :func:`format_for` finds the format of a path;
:func:`check_writable` and :func:`check_readable` refuse, before any work,
an unknown suffix, a missing library (one line naming the extra or how to
install it), a result the format cannot hold, or an output folder that is
missing or read-only.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

from ..errors import FormatError
from ..grid import MAX_VOXELS
from . import binvox, colored, nifti, npz, nrrd, vdb, vox, vti
from .common import Format

#: Every format, in the order error messages list them.
FORMATS: tuple[Format, ...] = (npz.FORMAT, binvox.FORMAT, nrrd.FORMAT, nifti.FORMAT, vti.FORMAT, vdb.FORMAT,
                              vox.FORMAT, colored.POINTS, colored.CUBES)

#: Result kinds :func:`check_writable` knows: a dense grid, a sparse octree, an LDI, a signed distance field.
KINDS = ("surface", "solid", "sparse", "ldi", "sdf")


def suffixes() -> list[str]:
    """Every suffix glvox reads or writes (lower case, with the dot)."""
    return [s for f in FORMATS for s in f.suffixes]


def format_for(path: str | os.PathLike) -> Format:
    """The format of ``path`` by its suffix (case-insensitive; ``.nii.gz`` counts as one)."""
    name = Path(path).name.lower()
    best = max(((s, f) for f in FORMATS for s in f.suffixes if name.endswith(s) and len(name) > len(s)),
               key=lambda sf: len(sf[0]), default=None)
    if best is None:
        raise FormatError(f"unknown voxel file suffix {Path(path).suffix!r} for {path}: use "
                          + ", ".join(suffixes()))
    return best[1]


def check_writable(path: str | os.PathLike, kind: str | None = None,
                   dims: Sequence[int] | None = None) -> Format:
    """Refuse, before any work, an output ``path`` that :func:`glvox.save` would refuse.

    Parameters
    ----------
    path : path-like
        The output file; its suffix picks the format.
    kind : {'surface', 'solid', 'sparse', 'ldi', 'sdf'}, optional
        The kind of result that will be written (a method's ``info.kind``).
    dims : (3,) int, optional
        The grid's dims, when known (binvox takes cubic grids only; formats
        that store dense grids refuse an octree too large to decode).

    Returns
    -------
    Format
        The output's format, its library imported.

    Raises
    ------
    FormatError
        Unknown suffix; the format's library is missing (the message names
        the extra or how to install it); the format cannot hold this kind or
        these dims; the folder is missing or not writable, or ``path`` is a folder.
    """
    path = Path(path)
    fmt = format_for(path)
    if kind is not None and kind not in KINDS:
        raise FormatError(f"result kind must be one of {KINDS}, got {kind!r}")
    if kind == "ldi" and not fmt.ldi:
        raise FormatError(f"an LDI is saved as .npz (depths per ray), not {fmt.name}: {path}")
    if kind == "sdf" and not fmt.sdf:
        raise FormatError(f"a signed distance field is saved as .npz, .nrrd, .nii(.gz), .vti or .vdb, not {fmt.name}: "
                          f"{path}")
    if dims is not None:
        check_dims(path, kind, dims)
    fmt.require()
    folder = path.parent
    if path.is_dir():
        raise FormatError(f"output {path} is a folder, not a file")
    if not folder.is_dir():
        raise FormatError(f"output folder {folder} does not exist (for {path})")
    if not os.access(folder, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise FormatError(f"cannot write {path}: permission denied")
    return fmt


def check_dims(path: str | os.PathLike, kind: str | None, dims: Sequence[int]) -> None:
    """FormatError unless ``path``'s format holds a result of ``kind`` on a grid of ``dims``
    (binvox: cubic grids only; dense formats: an octree small enough to decode).  The part of
    :func:`check_writable` that needs the grid, for when the grid is known only later."""
    fmt = format_for(Path(path))
    dims = tuple(int(d) for d in dims)
    if fmt.check_dims is not None:
        fmt.check_dims(dims)
    n = dims[0] * dims[1] * dims[2]
    if kind == "sparse" and not fmt.sparse and n > MAX_VOXELS:
        raise FormatError(f"{fmt.name} stores dense grids and an octree on {dims} ({n} voxels) has more "
                          f"than the {MAX_VOXELS} glvox keeps dense: save it as .npz or .vdb")


def check_readable(path: str | os.PathLike) -> Format:
    """Refuse, before any work, an input ``path`` that :func:`glvox.load` would refuse
    for its suffix, its format's missing library or its absence; returns its format."""
    path = Path(path)
    fmt = format_for(path)
    if fmt.read is None:
        raise FormatError(f"glvox writes {fmt.name} but does not read it: {path}")
    fmt.require()
    if not path.is_file():
        raise FormatError(f"voxel file not found: {path}")
    return fmt


__all__ = ["FORMATS", "Format", "KINDS", "check_dims", "check_readable", "check_writable", "format_for", "suffixes"]
