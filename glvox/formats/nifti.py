"""NIfTI-1 through nibabel (``pip install 'glvox[formats]'``): ``.nii`` and ``.nii.gz``.

Written: a uint8 volume (1 = occupied; a signed distance field: float32 distances in
world units, negative inside) indexed [i, j, k] and an affine that
maps voxel indices (i, j, k) to the world center of voxel (i, j, k),
``diag(h, h, h)`` and the translation ``origin + h / 2``; ``qform`` and
``sform`` both hold it (code 2, "aligned": the mesh's frame, not a
scanner's), so every reader, whichever of the two it trusts, places the
voxels alike.  NIfTI-1 keeps the affine in float32: placement survives to
float32 precision (about 1e-7 of the largest coordinate).  Units are left
unknown (``xyzt_units`` 0): the mesh's units carry over as they are; viewers
usually assume millimetres.

RAS or LPS: NIfTI defines its world as RAS+ (x to the right, y anterior,
z superior).  glvox writes the mesh's coordinates unchanged, so a medical
viewer takes the mesh's +x as right, +y as anterior and +z as superior; the
same voxels in a DICOM/ITK (LPS) tool appear with x and y negated, exactly
as the mesh would if loaded there as LPS.  glvox's NRRD files are labelled
RAS for the same reason (:mod:`glvox.formats.nrrd`).

Extra masks are not written (one array per file; a :class:`FormatWarning`
names them).  Reading takes nibabel's affine (the sform when its code is
set, else the qform) and accepts axes that are the world axes in any order
and sign, as scanners write them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import FormatError
from ..results import Result, SDFGrid, VoxelGrid
from .common import (Format, as_grid, center_matrix, grid_from_matrix, import_library, warn_dropped,
                     warn_sdf_masks)

#: NIfTI xform code written to qform and sform: 2 = aligned to another file or frame (the mesh's).
XFORM_CODE = 2


def _library():
    return import_library("nibabel", "NIfTI (.nii, .nii.gz)")


def write(result: Result, path: Path) -> None:
    """Write ``result`` (a VoxelGrid, or an octree decoded) as NIfTI-1, uint8, qform = sform."""
    nib = _library()
    sdf = isinstance(result, SDFGrid)  # the distances as float32, world units
    grid = result if sdf else as_grid(result, "NIfTI")
    affine = center_matrix(grid.spec)
    data = np.asarray(result.sdf, dtype=np.float32) if sdf else np.asarray(grid.dense(), dtype=np.uint8)
    img = nib.Nifti1Image(data, affine)
    img.set_qform(affine, code=XFORM_CODE)
    img.set_sform(affine, code=XFORM_CODE)
    img.header["descrip"] = (b"glvox signed distance, world units" if sdf else b"glvox occupancy") \
        + b"; affine: voxel index -> voxel center"
    if sdf:
        warn_sdf_masks("NIfTI")
    else:
        warn_dropped(grid, "NIfTI")
    nib.save(img, str(path))


def read(path: Path) -> VoxelGrid:
    """A VoxelGrid from a 3D NIfTI volume (nonzero = occupied) and its affine."""
    nib = _library()
    try:
        img = nib.load(str(path))
        data = np.asanyarray(img.dataobj)
        affine = np.asarray(img.affine, dtype=np.float64)
    except Exception as exc:  # noqa: BLE001 - nibabel raises ImageFileError, OSError, zlib errors...
        raise FormatError(f"cannot read {path} as NIfTI: {exc}") from None
    if data.ndim == 4 and data.shape[3] == 1:
        data = data[..., 0]
    if data.ndim != 3:
        raise FormatError(f"{path}: glvox reads 3D NIfTI volumes, got shape {data.shape}")
    return grid_from_matrix(data, affine[:3, :3], affine[:3, 3], path)


FORMAT = Format("NIfTI", (".nii", ".nii.gz"), write, read, library=_library, sdf=True)
