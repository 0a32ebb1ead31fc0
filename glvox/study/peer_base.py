"""What every peer voxelizer shares (:mod:`glvox.study.peers` lists them): the
:class:`Peer` protocol, its result on glvox's grid (:class:`PeerGrid`) and
the conversions of set voxels onto that grid."""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from glvox.grid import GridSpec
from glvox.results.voxels import VoxelGrid


@dataclass
class PeerGrid:
    """A peer's result on glvox's grid.

    Attributes
    ----------
    grid : VoxelGrid
        Occupancy on the benchmark's GridSpec.
    outside : int
        Voxels the peer set outside that grid (dropped): peers that do not
        clip, such as Open3D and trimesh, can set voxels one layer past the
        grid where the mesh touches the grid's faces.
    stats : dict
        What the peer reports beside its grid (JSON-able), put in the bench
        row as ``peer_stats`` (cuda_voxelizer: its own kernel time, its grid
        against glvox's on its own placement).
    """

    grid: VoxelGrid
    outside: int
    stats: dict[str, Any] = field(default_factory=dict)


def _from_indices(ijk: np.ndarray, spec: GridSpec) -> PeerGrid:
    """Set voxels (M, 3) int -> PeerGrid, indices outside ``spec.dims`` dropped and counted."""
    ijk = np.asarray(ijk, dtype=np.int64).reshape(-1, 3)
    inside = np.all((ijk >= 0) & (ijk < np.asarray(spec.dims)), axis=1)
    dense = np.zeros(spec.dims, dtype=bool)
    dense[tuple(ijk[inside].T)] = True
    return PeerGrid(VoxelGrid(dense, spec), int(np.count_nonzero(~inside)))


def _from_zyx(mask: np.ndarray, spec: GridSpec) -> PeerGrid:
    """Occupancy (nz, ny, nx), x fastest (VTK's point order), -> PeerGrid.

    Packs straight into glvox's word layout (x bits of a row in consecutive
    words), without the (nx, ny, nz) transpose of a dense grid: at 1024^3 that
    copy alone takes seconds.
    """
    nx, ny, nz = spec.dims
    m = np.asarray(mask).reshape(nz, ny, nx).astype(bool, copy=False)
    pad = spec.words_per_row * 32 - nx
    if pad:
        m = np.concatenate([m, np.zeros((nz, ny, pad), dtype=bool)], axis=2)
    words = np.packbits(m, axis=2, bitorder="little").view("<u4").reshape(nz, ny, spec.words_per_row)
    return PeerGrid(VoxelGrid(words=words, spec=spec), 0)


class Peer:
    """One library's voxelizer.

    Attributes
    ----------
    name : str
        Key of the peer in tables and on the command line.
    kind : {'surface', 'solid'}
        What it computes; its ratios are taken against glvox methods of that kind.
    module : str
        The Python module it imports.
    package : str
        The pip package that provides it (named in the skip message).
    reference : str
        The glvox exact reference its agreement is reported against.
    call : str
        The library call that is timed, for tables.
    max_n : int or None
        Largest grid resolution the benchmark runs it at unless told
        otherwise (``--peer-max``): beyond it the run would take minutes per
        repetition or more memory than a small machine has (see each peer).
    """

    name: str = ""
    kind: str = ""
    module: str = ""
    package: str = ""
    reference: str = ""
    call: str = ""
    max_n: int | None = None

    def missing(self) -> str | None:
        """None when the library imports; else why not and what to install."""
        try:
            importlib.import_module(self.module)
        except Exception as exc:  # ImportError, or a shared library the wheel needs (OSError)
            return (f"{self.name} skipped: `import {self.module}` failed ({type(exc).__name__}: {exc}); "
                    f"install it with `pip install {self.package}` or `pip install 'glvox[peers]'`")
        return None

    def version(self) -> str:
        mod = importlib.import_module(self.module)
        return str(getattr(mod, "__version__", "?"))

    def prepare(self, mesh, spec: GridSpec) -> Any:
        """The mesh and grid in the peer's own types (not timed).

        Parameters
        ----------
        mesh : glvox.mesh.Mesh
            Validated mesh, world coordinates (float64 vertices, int faces).
        spec : GridSpec
        """
        raise NotImplementedError

    def run(self, prepared: Any) -> Any:
        """The timed library call; returns the peer's native result."""
        raise NotImplementedError

    def to_grid(self, native: Any, spec: GridSpec) -> PeerGrid:
        """The native result on glvox's grid."""
        raise NotImplementedError


