"""npz: every result type in its own layout (:mod:`glvox.results.base`).

A sparse octree stores the octree itself, never a decoded grid, so a 4096^3
result stays a few hundred MiB; reading returns the type the file holds.
"""

from __future__ import annotations

from pathlib import Path

from ..results import Result, read_npz
from ..results.base import write_npz
from .common import ALL_ATTRIBUTES, Format


def write(result: Result, path: Path) -> None:
    """Write ``result``'s npz layout to ``path``."""
    write_npz(result, path)


def read(path: Path) -> Result:
    """The VoxelGrid, SparseOctree or LDI an npz file holds."""
    return read_npz(path)


FORMAT = Format("npz", (".npz",), write, read, sparse=True, ldi=True, attributes=ALL_ATTRIBUTES, sdf=True)
