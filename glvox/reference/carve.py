"""Exact CPU carved solid (docs/design.md, "Carved solid"): binvox-style exterior carving.

A voxel is outside when a 6-connected path of voxels not in the blocker
joins it to the grid's boundary; everything else, the blocker included, is
solid.  The blocker is the conservative surface (:func:`conservative_surface`),
optionally closed first (:func:`close`) so that gaps of up to K empty voxels
between surface voxels are sealed.  ``carve-solid`` does the same on the GPU;
this module is its reference.

All arrays are dense bool (nx, ny, nz), indexed [i, j, k].
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from scipy import ndimage

from ..tolerances import TIE_EPS
from .surface import conservative_surface
from .ties import surface_ties

#: Largest ``close`` (gap width in voxels): the GPU closing shifts packed words
#: by at most 16 bits each way, one neighbouring word.
MAX_CLOSE = 32

_SIX = ndimage.generate_binary_structure(3, 1)


def close_window(k: int) -> tuple[int, int]:
    """The dilation window ``[-lo, hi]`` of a closing over gaps of ``k`` voxels: lo + hi = k.

    A gap of ``g`` empty voxels between two set voxels along an axis is
    covered by the dilation iff ``g <= lo + hi``; for odd ``k`` the window
    reaches one voxel further up than down.
    """
    return k // 2, k - k // 2


def _shifted(a: np.ndarray, axis: int, d: int, fill: bool) -> np.ndarray:
    """``out[p] = a[p + d e_axis]``, ``fill`` where ``p + d`` leaves the grid."""
    out = np.full_like(a, fill)
    n = a.shape[axis]
    if abs(d) >= n:
        return out
    src = [slice(None)] * 3
    dst = [slice(None)] * 3
    if d >= 0:
        src[axis], dst[axis] = slice(d, n), slice(0, n - d)
    else:
        src[axis], dst[axis] = slice(0, n + d), slice(-d, n)
    out[tuple(dst)] = a[tuple(src)]
    return out


def close(surface: np.ndarray, k: int) -> np.ndarray:
    """Morphological closing of ``surface`` by a box of side ``k + 1`` (separable, axis by axis).

    Dilation: ``D[p] = OR of S[p + d]`` over d in ``[-lo, hi]^3``
    (:func:`close_window`); erosion: ``C[p] = AND of D[p + d]`` over d in
    ``[-hi, lo]^3`` (the reflected window), so ``C`` contains ``S``.  Both as
    if the grid went on for ever, empty beyond its border (geometry beyond it
    is clipped): the border neither seals a gap nor opens one.  Seals every
    gap of at most ``k`` empty voxels between surface voxels (and concave
    notches as narrow).

    Parameters
    ----------
    surface : (nx, ny, nz) bool
    k : int
        0 (returns a copy) to :data:`MAX_CLOSE`.

    Returns
    -------
    (nx, ny, nz) bool
    """
    if not 0 <= k <= MAX_CLOSE:
        raise ValueError(f"close must be in [0, {MAX_CLOSE}] voxels, got {k!r}")
    if k == 0:
        return np.array(surface, dtype=bool)
    lo, hi = close_window(k)
    # D reaches lo beyond the upper border and hi below the lower one, where the
    # erosion of a voxel in the grid reads it: a margin of hi (>= lo) holds all of it
    out = np.pad(np.asarray(surface, dtype=bool), hi)
    for axis in range(3):
        grown = np.zeros_like(out)
        for d in range(-lo, hi + 1):
            grown |= _shifted(out, axis, d, False)
        out = grown
    for axis in range(3):
        kept = np.ones_like(out)
        for d in range(-hi, lo + 1):
            kept &= _shifted(out, axis, d, True)
        out = kept
    return out[hi:-hi, hi:-hi, hi:-hi]


def exterior(blocker: np.ndarray) -> np.ndarray:
    """Voxels joined to the grid's boundary by a 6-connected path outside ``blocker``.

    Parameters
    ----------
    blocker : (nx, ny, nz) bool

    Returns
    -------
    (nx, ny, nz) bool
    """
    free = ~np.asarray(blocker, bool)
    labels, _ = ndimage.label(free, structure=_SIX)
    faces = np.concatenate([labels[[0, -1], :, :].ravel(), labels[:, [0, -1], :].ravel(),
                            labels[:, :, [0, -1]].ravel()])
    outside = np.unique(faces[faces > 0])
    return np.isin(labels, outside)


def carve(surface: np.ndarray, k: int = 0) -> np.ndarray:
    """The carved solid of a surface: ``~exterior(close(surface, k))``."""
    return ~exterior(close(surface, k))


def carved_solid(tris: np.ndarray, dims: Sequence[int], close: int = 0) -> np.ndarray:
    """Exact carved solid of voxel-space triangles (``reference-carve``).

    Parameters
    ----------
    tris : (T, 3, 3) float64
        Triangle vertices in voxel space (any mesh: open, multi-part, soup).
    dims : (3,) int
    close : int
        Seal gaps of up to this many empty voxels between surface voxels first.

    Returns
    -------
    (nx, ny, nz) bool
    """
    return carve(conservative_surface(tris, dims), close)


def carve_ties(tris: np.ndarray, dims: Sequence[int], close: int = 0, eps: float = TIE_EPS) -> np.ndarray:
    """Voxels whose carved verdict can change with a proven tie of the surface.

    Carving is monotone in its surface (a larger surface blocks more and is
    itself solid), and closing is monotone too; a GPU surface differs from
    the reference surface ``S`` only on the surface tie set ``T``
    (:func:`surface_ties`), so it lies between ``S - T`` and ``S | T`` and
    its carved solid between theirs: the voxels where those two differ are
    the ties.  One missing tie voxel can open a wall, so on thin walls the
    set may be large; it is exact, not a percentage.

    Returns
    -------
    (nx, ny, nz) bool
    """
    surface = conservative_surface(tris, dims)
    t = surface_ties(tris, dims, "conservative", eps)
    return carve(surface | t, close) & ~carve(surface & ~t, close)
