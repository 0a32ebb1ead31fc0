"""The voxels' own colours for the exports that show them (.vox, coloured
points and cubes, pictures), and the palette quantizer of ``.vox``.

A result carries colours when a method ran with ``attributes=['color', ...]``:
``result.attributes['color']`` is (M, 4) uint8 RGBA, one row per set voxel
in the order of ``result.indices()`` (C order of the dense (nx, ny, nz)
array); alpha 0 means the voxel has no colour (an interior voxel with
``--fill-attributes none``, a mesh part without visuals).  Such voxels, and
every voxel of a result without colours, are shown in :data:`DEFAULT_COLOR`.
"""

from __future__ import annotations

import numpy as np

from ..errors import FormatError
from ..results import Result
from .common import as_grid, import_library

#: RGBA uint8 of voxels without a colour: the blue-grey of glvox's pictures
#: (``glvox.study.render``'s cube colour (0.55, 0.68, 0.86) in 8 bits).
DEFAULT_COLOR = (140, 173, 219, 255)


def has_colors(result: Result) -> bool:
    """Whether ``result`` carries a ``'color'`` attribute (without computing its voxels)."""
    return (getattr(result, "attributes", None) or {}).get("color") is not None


def voxel_colors(result: Result, fmt: str) -> tuple[np.ndarray, np.ndarray | None]:
    """The set voxels of ``result`` and their colours, if it has any.

    Parameters
    ----------
    result : Result
        A VoxelGrid (an octree is decoded, an LDI refused, by :func:`as_grid`).
    fmt : str
        The format's name, for messages.

    Returns
    -------
    indices : (M, 3) int64
        Voxel indices (i, j, k) in C order.
    colors : (M, 4) uint8 or None
        RGBA per voxel (alpha 0: no colour), or None when the result has no
        ``'color'`` attribute.

    Raises
    ------
    FormatError
        The colour array is not (M, 4) uint8 for the M set voxels.
    """
    grid = as_grid(result, fmt)
    indices = grid.indices()
    colors = (getattr(grid, "attributes", None) or {}).get("color")
    if colors is None:
        return indices, None
    colors = np.asarray(colors)
    if colors.dtype != np.uint8 or colors.shape != (len(indices), 4):
        raise FormatError(f"{fmt}: the 'color' attribute must be uint8 (M, 4) RGBA for the {len(indices)} set "
                          f"voxels, got {colors.dtype} {colors.shape}")
    return indices, colors


def filled(colors: np.ndarray | None, n: int) -> np.ndarray:
    """(n, 4) uint8 colours with :data:`DEFAULT_COLOR` where ``colors`` is None or alpha is 0."""
    out = np.empty((n, 4), np.uint8)
    out[:] = DEFAULT_COLOR
    if colors is not None:
        has = colors[:, 3] > 0
        out[has] = colors[has]
    return out


def pillow():
    """Pillow's module (the .vox quantizer), or a FormatError naming the extra."""
    return import_library("PIL.Image", "MagicaVoxel (.vox) palettes")


#: Voxels whose colours the median cut sees at most (an even stride over the
#: rest): the cut needs the colour distribution, not every voxel, and Pillow
#: holds the sample as an image of one column.
QUANTIZE_SAMPLE = 1 << 22


def quantize(colors: np.ndarray, max_colors: int = 255) -> tuple[np.ndarray, np.ndarray]:
    """A palette of at most ``max_colors`` RGBA colours and each colour's entry.

    Exact when the distinct colours are at most ``max_colors``.  Otherwise
    Pillow's median cut (``Image.quantize(method=MEDIANCUT)``, no dither)
    over the RGB of the voxels (so a colour weighs as many voxels as have
    it) proposes the palette; each distinct colour then goes to its nearest
    entry (Euclidean RGBA, a k-d tree), each entry becomes the voxel-weighted
    mean of its colours (one Lloyd step, which lowers the error) and the
    colours go to their nearest entry again, so every voxel's entry is the
    palette's nearest to its colour.  Alpha is averaged like R, G and B.

    Parameters
    ----------
    colors : (M, 4) uint8
        RGBA, one row per voxel.
    max_colors : int
        At most 255 for .vox.

    Returns
    -------
    palette : (P, 4) uint8, P <= max_colors
    index : (M,) intp
        Palette entry of each row of ``colors``.
    """
    colors = np.ascontiguousarray(colors, dtype=np.uint8).reshape(-1, 4)
    keys = colors.view("<u4").reshape(-1)
    distinct, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    dcolors = distinct.astype("<u4").view(np.uint8).reshape(-1, 4)
    if len(distinct) <= max_colors:
        return dcolors.copy(), inverse.reshape(-1)
    from scipy.spatial import cKDTree  # lazy: scipy.spatial takes 0.5 s to import, paid only here

    image = pillow()
    sample = colors[:: max(1, len(colors) // QUANTIZE_SAMPLE), :3]
    img = image.fromarray(np.ascontiguousarray(sample).reshape(-1, 1, 3), "RGB")
    q = img.quantize(colors=max_colors, method=image.Quantize.MEDIANCUT, dither=image.Dither.NONE)
    used = np.unique(np.asarray(q).reshape(-1))
    rgb = np.asarray(q.getpalette()[: 3 * max_colors], dtype=np.float64).reshape(-1, 3)[used]
    seed = np.concatenate([rgb, np.full((len(rgb), 1), 255.0)], axis=1)
    dfloat = dcolors.astype(np.float64)
    entry = cKDTree(seed).query(dfloat)[1]
    weight = counts.astype(np.float64)
    total = np.bincount(entry, weight, minlength=len(seed))
    keep = total > 0
    means = np.stack([np.bincount(entry, weight * dfloat[:, c], minlength=len(seed)) for c in range(4)], axis=1)
    palette = np.clip(np.rint(means[keep] / total[keep, None]), 0, 255).astype(np.uint8)
    entry = cKDTree(palette.astype(np.float64)).query(dfloat)[1]
    return palette, entry[inverse.reshape(-1)]
