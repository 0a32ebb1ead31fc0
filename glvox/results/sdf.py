"""Signed distance fields on a grid (:func:`glvox.sdf`, ``glvox sdf``).

npz layout (beside the common keys of :mod:`glvox.results.base`; ``kind`` is
``'sdf'``): ``sdf`` (float32, (nx, ny, nz), indexed [i, j, k], world units,
negative inside), ``band`` (bool, (nx, ny, nz): the distance there is exact),
``uncertain`` (bool, (nx, ny, nz): the sign there is uncertain),
``band_width`` (float64, voxels; ``inf`` when every voxel is exact) and
``truncation`` (float64, world units; ``nan`` when not truncated).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import FormatError, GridError
from ..grid import GridSpec
from .base import Result, npz_type, require_keys


@npz_type("sdf")
class SDFGrid(Result):
    """A signed distance field sampled at the voxel centers of a :class:`GridSpec`.

    Attributes
    ----------
    sdf : (nx, ny, nz) float32
        Signed distance from the voxel center to the mesh, world units,
        negative inside (the sign method's occupancy).  Outside the band the
        value is ``+-band_width * voxel_size`` (clamped, not exact); with a
        truncation every value is clamped to ``+-truncation``.
    band : (nx, ny, nz) bool
        Where the distance is exact (within ``band_width`` voxels of the surface).
    uncertain : (nx, ny, nz) bool
        Where the sign is uncertain (generalized winding number near 0.5).
    band_width : float
        Voxels; ``inf`` when computed everywhere (``band='all'``).
    truncation : float or None
        World units.
    """

    file_kind = "sdf"

    def __init__(self, sdf: np.ndarray, spec: GridSpec, band: np.ndarray, *, uncertain: np.ndarray | None = None,
                 band_width: float = math.inf, truncation: float | None = None, run=None):
        super().__init__(spec, run)
        sdf = np.asarray(sdf)
        if sdf.shape != spec.dims or sdf.dtype != np.float32:
            raise GridError(f"sdf must be float32 of shape {spec.dims} (nx, ny, nz), got {sdf.dtype} {sdf.shape}")
        masks = {"band": band, "uncertain": np.zeros(spec.dims, bool) if uncertain is None else uncertain}
        for name, m in masks.items():
            m = np.asarray(m)
            if m.shape != spec.dims or m.dtype != bool:
                raise GridError(f"{name} must be bool of shape {spec.dims}, got {m.dtype} {m.shape}")
        self.sdf = sdf
        self.band = np.asarray(masks["band"])
        self.uncertain = np.asarray(masks["uncertain"])
        self.band_width = float(band_width)
        self.truncation = None if truncation is None else float(truncation)

    @property
    def n_uncertain(self) -> int:
        """Voxels whose sign is uncertain."""
        return int(np.count_nonzero(self.uncertain))

    def inside(self) -> np.ndarray:
        """bool (nx, ny, nz): the voxel centers with a negative distance."""
        return self.sdf < 0

    def npz_arrays(self) -> dict[str, np.ndarray]:
        return {"sdf": np.ascontiguousarray(self.sdf), "band": self.band, "uncertain": self.uncertain,
                "band_width": np.float64(self.band_width),
                "truncation": np.float64(math.nan if self.truncation is None else self.truncation)}

    @classmethod
    def from_npz(cls, z, path: Path) -> "SDFGrid":
        require_keys(z, path, {"sdf", "band", "origin", "voxel_size"}, "SDF ")
        sdf = np.asarray(z["sdf"], dtype=np.float32)
        if sdf.ndim != 3:
            raise FormatError(f"{path}: sdf must be 3D (nx, ny, nz), got shape {sdf.shape}")
        spec = GridSpec(sdf.shape, np.asarray(z["origin"], dtype=np.float64), float(z["voxel_size"]))
        trunc = float(z["truncation"]) if "truncation" in z.files else math.nan
        try:
            return cls(sdf, spec, np.asarray(z["band"]).astype(bool),
                       uncertain=np.asarray(z["uncertain"]).astype(bool) if "uncertain" in z.files else None,
                       band_width=float(z["band_width"]) if "band_width" in z.files else math.inf,
                       truncation=None if math.isnan(trunc) else trunc)
        except GridError as exc:
            raise FormatError(f"{path}: {exc}") from None

    def __repr__(self) -> str:
        return (f"SDFGrid(dims={self.dims}, voxel_size={self.voxel_size:.6g}, band={self.band_width:g} voxels, "
                f"exact={int(self.band.sum())}, uncertain={self.n_uncertain})")
