"""NRRD through pynrrd (``pip install 'glvox[formats]'``).

Written: ``type: uint8`` (1 = occupied; a signed distance field: ``type: float``,
its distances in world units, negative inside), axes in glvox's [i, j, k] order
(i fastest on disk), gzip encoding, ``centerings: cell cell cell``,
``space directions`` h along each world axis and ``space origin`` the
center of voxel (0, 0, 0), ``origin + h / 2``: in NRRD the space origin is
always the position of the first sample, whatever the centering.  A
``glvox_placement`` key/value pair states the convention in the header.

Space: ``right-anterior-superior``.  glvox's world is the mesh's frame and
has no anatomy; RAS is the frame NIfTI assumes, so a medical viewer (3D
Slicer) opens glvox's NRRD and NIfTI files at the same place, and a mesh
loaded in Slicer with the RAS coordinate system (its default for models is
LPS, which negates x and y) lands on the voxels.  Reading converts
``left-posterior-superior`` / ``left-anterior-superior`` files to RAS, so a
file resaved by Slicer in LPS reads back to the same world positions; other
spaces (``scanner-xyz``, ``3D-right-handed``, ...) are taken as they are.

Extra masks are not written (one array per file; a :class:`FormatWarning`
names them): use .vti, .vdb or .npz to keep them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import FormatError
from ..results import Result, SDFGrid, VoxelGrid
from .common import Format, as_grid, grid_from_matrix, import_library, warn_dropped, warn_sdf_masks

#: Sign of each world axis of a NRRD space relative to RAS (the frame glvox labels its world).
SPACE_TO_RAS = {
    "right-anterior-superior": (1, 1, 1), "ras": (1, 1, 1),
    "left-anterior-superior": (-1, 1, 1), "las": (-1, 1, 1),
    "left-posterior-superior": (-1, -1, 1), "lps": (-1, -1, 1),
}

PLACEMENT_NOTE = ("voxel (i, j, k) is the cell centered at space origin + (i, j, k) * space directions "
                  "(glvox: origin + (i, j, k) h + h/2, origin being the min corner of voxel 0)")


def _library():
    return import_library("nrrd", "NRRD (.nrrd)")


def write(result: Result, path: Path) -> None:
    """Write ``result`` (a VoxelGrid, or an octree decoded) as a gzip NRRD, uint8, RAS."""
    nrrd = _library()
    sdf = isinstance(result, SDFGrid)  # the distances as float32, world units
    grid = result if sdf else as_grid(result, "NRRD")
    h = grid.voxel_size
    header = {
        "type": "float" if sdf else "uint8", "encoding": "gzip", "space": "right-anterior-superior",
        "space directions": np.diag([h, h, h]), "space origin": grid.origin + 0.5 * h,
        "kinds": ["domain"] * 3, "centerings": ["cell"] * 3, "glvox_placement": PLACEMENT_NOTE,
    }
    if sdf:
        data = np.asarray(result.sdf, dtype=np.float32)
        warn_sdf_masks("NRRD")
    else:
        data = np.asarray(grid.dense(), dtype=np.uint8)
        warn_dropped(grid, "NRRD")
    # zlib level 6 (as npz and .vti): pynrrd's default 9 took 7x longer here for 20% smaller files
    nrrd.write(str(path), data, header, index_order="F", compression_level=6)


def read(path: Path) -> VoxelGrid:
    """A VoxelGrid from a 3D NRRD (nonzero = occupied) with space directions or spacings."""
    nrrd = _library()
    try:
        data, header = nrrd.read(str(path), index_order="F")
    except Exception as exc:  # noqa: BLE001 - pynrrd raises NRRDError, OSError, ValueError...
        raise FormatError(f"cannot read {path} as NRRD: {exc}") from None
    if data.ndim != 3:
        raise FormatError(f"{path}: glvox reads 3D NRRD volumes, got {data.ndim} axes {data.shape}")
    if "space directions" in header:
        steps = np.asarray(header["space directions"], dtype=np.float64).T
        first = np.asarray(header.get("space origin", np.zeros(3)), dtype=np.float64)
        if steps.shape != (3, 3) or first.shape != (3,):
            raise FormatError(f"{path}: glvox reads NRRD files in a 3D space, got space directions "
                              f"{header['space directions']!r}")
        sign = np.asarray(SPACE_TO_RAS.get(str(header.get("space", "")).lower(), (1, 1, 1)), dtype=np.float64)
        steps, first = steps * sign[:, None], first * sign
    elif "spacings" in header:
        spacing = np.asarray(header["spacings"], dtype=np.float64)
        mins = np.asarray(header.get("axis mins", np.zeros(3)), dtype=np.float64)
        cell = [c == "cell" for c in header.get("centerings", ["node"] * 3)]
        first = mins + np.where(cell, 0.5 * spacing, 0.0)  # a cell's axis min is its edge
        steps = np.diag(spacing)
    else:
        raise FormatError(f"{path}: the NRRD header has neither space directions nor spacings")
    return grid_from_matrix(data, steps, first, path)


FORMAT = Format("NRRD", (".nrrd",), write, read, library=_library, sdf=True)
