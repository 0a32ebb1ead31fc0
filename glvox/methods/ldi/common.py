"""What the LDI methods share: the rays of a grid, the ``axis`` option, the
open-mesh warning, and depth buffers read back in chunks.

Used by ``leung-wang-ldi`` (:mod:`glvox.methods.ldi.leung_wang`), ``peel-ldi``
(:mod:`glvox.methods.ldi.peel`) and ``reference-ldi``
(:mod:`glvox.methods.reference.registered`).  The result type is
:class:`glvox.results.ldi.LDI`: rays along ``axis`` through the pixel
centers of the grid's other two axes.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import NotWatertightWarning
from ...grid import ldi_axes
from ..base import Option

#: The ``axis`` option of every LDI method.
AXIS_OPTION = Option(2, "ray direction (0=x, 1=y, 2=z); pixels are the other two axes in increasing order",
                     (0, 1, 2))


def warn_open(mesh, name: str) -> None:
    """Warn that method ``name`` pairs crossings by parity on a mesh that is not watertight.

    run_method refuses open meshes for the solid kinds only; an LDI pairs
    crossings by parity just the same, so say what the result means.
    Called from a method's ``run`` (the warning points at its caller).
    """
    if not mesh.watertight:
        warnings.warn(
            f"{mesh.name} is not watertight: {name!r} pairs the crossings of each ray by parity, which "
            "bounds a solid only where the rays cross a closed part of the surface; a ray left inside "
            "is closed at the grid's far face", NotWatertightWarning, stacklevel=3)


@dataclass(frozen=True)
class Rays:
    """The rays of an LDI of ``spec`` along ``axis``: one per voxel column."""

    spec: Any
    axis: int

    @property
    def n_u(self) -> int:
        """Pixels along ``(axis + 1) % 3``."""
        return self.spec.dims[(self.axis + 1) % 3]

    @property
    def n_v(self) -> int:
        """Pixels along ``(axis + 2) % 3``."""
        return self.spec.dims[(self.axis + 2) % 3]

    @property
    def n_a(self) -> int:
        """Voxels along the rays."""
        return self.spec.dims[self.axis]

    @property
    def n_rays(self) -> int:
        return self.n_u * self.n_v

    def out_shape(self) -> tuple[int, int]:
        """(n_p, n_q): the LDI's pixel grid, its axes in increasing order (:func:`glvox.grid.ldi_axes`)."""
        p, q = ldi_axes(self.axis)
        return self.spec.dims[p], self.spec.dims[q]


def read_chunks(bufs_and_chunks, n_rays: int, n_layers: int, shape: tuple[int, int]) -> np.ndarray:
    """The depths held in chunks of layers, as one array.

    Parameters
    ----------
    bufs_and_chunks : iterable of (moderngl.Buffer, (first layer, layers))
        Each buffer holds ``layers`` float32 per ray, ray after ray.
    n_rays, n_layers : int
        Layers past ``n_layers`` are dropped.
    shape : (n_p, n_q)
        The pixel grid (:meth:`Rays.out_shape`).

    Returns
    -------
    (n_p, n_q, n_layers) float32
    """
    parts = []
    for buf, (lo, n) in bufs_and_chunks:
        a = np.frombuffer(buf.read(size=n_rays * n * 4), dtype="<f4").reshape(n_rays, n)
        parts.append(a[:, : max(0, min(n, n_layers - lo))])
    if not parts:
        return np.zeros(shape + (0,), dtype=np.float32)
    return np.concatenate(parts, axis=1).reshape(*shape, n_layers)
