"""MagicaVoxel ``.vox``: the voxels in a palette of at most 255 colours.

Written (version 150, as MagicaVoxel writes it): one ``SIZE`` + ``XYZI``
pair per model, the scene graph (a root ``nTRN`` -> ``nGRP`` -> one
``nTRN`` -> ``nSHP`` per model), one ``LAYR`` and the ``RGBA`` palette.

Models.  A model holds at most 256 voxels per axis (``XYZI`` stores each
coordinate in one byte).  A grid of dims (nx, ny, nz) is cut into
``k_a = ceil(n_a / 256)`` blocks along each axis, all of the same size
``ceil(n_a / k_a)`` (so no block is a sliver; the last one's ``SIZE`` is
padded), and each block that holds a voxel becomes a model placed by its
``nTRN`` translation ``_t``.  MagicaVoxel puts a model's voxel ``v`` at
``_t + v - floor(SIZE / 2)``; glvox sets ``_t = offset + floor(SIZE / 2) -
floor(dims / 2)`` so that voxel (i, j, k) of the grid lands at
``(i, j, k) - floor(dims / 2)`` in MagicaVoxel's scene: the grid centered
on the scene's origin, as one model of that size would be.

Axes.  MagicaVoxel's z is up.  ``up='z'`` (default) writes glvox's (i, j, k)
as (x, y, z) unchanged; ``up='y'`` (meshes from OBJ / glTF, whose +y is up)
turns the grid by +90 degrees about x, (x, y, z) = (i, nz - 1 - k, j), so
the mesh stands upright in MagicaVoxel.

Colours.  Voxels take their ``'color'`` attribute
(:func:`glvox.formats.colors.voxel_colors`); the palette is exact when
there are at most 255 distinct colours, else quantized
(:func:`glvox.formats.colors.quantize`: Pillow's median cut, then each
voxel to its nearest entry).  Voxels without a colour (alpha 0) and every
voxel of a result without colours take :data:`~glvox.formats.colors.DEFAULT_COLOR`
(one palette entry, the last).  Palette index c in ``XYZI`` is the
(c - 1)-th colour of ``RGBA``, as the format's specification says.

Placement.  .vox has no world units: the root ``nTRN``'s attributes keep
glvox's ``glvox_origin`` (world, min corner of voxel 0), ``glvox_voxel_size``,
``glvox_dims`` and ``glvox_up`` as text (other readers ignore them).  The
other attributes (triangle, normal, material) and extra masks are not written.
"""

from __future__ import annotations

import struct
import warnings
from pathlib import Path

import numpy as np

from ..errors import FormatError, FormatWarning
from ..results import Result
from .colors import DEFAULT_COLOR, pillow, quantize, voxel_colors
from .common import Format

#: Voxels per axis of one model (``XYZI`` keeps each coordinate in a byte).
MAX_MODEL = 256

#: Palette entries a voxel can use (index 0 means empty).
MAX_COLORS = 255

#: The file version glvox writes (MagicaVoxel's readers take 150 and 200).
VERSION = 150

UPS = ("z", "y")


def _chunk(cid: bytes, content: bytes, children: bytes = b"") -> bytes:
    """A chunk: id, content size, children size, content, children."""
    if len(content) >= 1 << 31 or len(children) >= 1 << 31:
        raise FormatError(f".vox chunks hold less than 2 GiB (int32 sizes); this grid's {cid.decode()} "
                          f"needs {max(len(content), len(children))} bytes: save it as .npz or .vdb")
    return cid + struct.pack("<ii", len(content), len(children)) + content + children


def _string(s: str) -> bytes:
    b = s.encode("utf-8")
    return struct.pack("<i", len(b)) + b


def _dict(d: dict[str, str]) -> bytes:
    return struct.pack("<i", len(d)) + b"".join(_string(k) + _string(v) for k, v in d.items())


def model_layout(dims) -> tuple[np.ndarray, np.ndarray]:
    """Blocks per axis and the common model size of a grid of ``dims``.

    Returns
    -------
    blocks : (3,) int64
        ``ceil(n / 256)`` per axis.
    size : (3,) int64
        ``ceil(n / blocks)`` per axis, at most 256: every model's ``SIZE``.
    """
    n = np.asarray(dims, dtype=np.int64)
    blocks = -(-n // MAX_MODEL)
    return blocks, -(-n // blocks)


def _axes(indices: np.ndarray, dims, up: str) -> tuple[np.ndarray, np.ndarray]:
    """Voxel indices and dims in MagicaVoxel's axes for ``up``."""
    dims = np.asarray(dims, dtype=np.int64)
    if up == "z":
        return indices, dims
    i, j, k = indices.T
    return np.stack([i, dims[2] - 1 - k, j], axis=1), dims[[0, 2, 1]]


def _palette(colors: np.ndarray | None, m: int) -> tuple[np.ndarray, np.ndarray]:
    """(P, 4) uint8 palette and (m,) uint8 index 1..P of each voxel."""
    if colors is None:
        return np.array([DEFAULT_COLOR], np.uint8), np.ones(m, np.uint8)
    has = colors[:, 3] > 0
    bare = not bool(has.all())
    palette, entry = quantize(colors[has], MAX_COLORS - int(bare))
    index = np.empty(m, np.uint8)
    index[has] = entry + 1
    if bare:                                             # DEFAULT_COLOR: the last entry
        palette = np.concatenate([palette, np.array([DEFAULT_COLOR], np.uint8)])
        index[~has] = len(palette)
    return palette, index


def vox_bytes(result: Result, *, up: str = "z") -> bytes:
    """The .vox encoding of ``result`` (a VoxelGrid; an octree decoded) with its colours.

    Parameters
    ----------
    result : Result
    up : {'z', 'y'}
        The glvox axis that becomes MagicaVoxel's up (z); see the module docstring.

    Returns
    -------
    bytes
    """
    if up not in UPS:
        raise FormatError(f".vox: up must be one of {UPS}, got {up!r}")
    grid_indices, colors = voxel_colors(result, ".vox")
    indices, dims = _axes(grid_indices, result.dims, up)
    palette, index = _palette(colors, len(indices))
    blocks, size = model_layout(dims)
    block = indices // size
    model_of = np.ravel_multi_index(block.T, blocks) if len(indices) else np.zeros(0, np.int64)
    order = np.argsort(model_of, kind="stable")
    ids, starts = np.unique(model_of[order], return_index=True)
    if len(ids) == 0:                                    # an empty grid: one empty model
        ids, starts = np.zeros(1, np.int64), np.zeros(1, np.int64)
    ends = np.append(starts[1:], len(order))
    local = (indices - block * size).astype(np.uint8)
    xyzi = np.concatenate([local, index[:, None]], axis=1)[order]
    models = b"".join(
        _chunk(b"SIZE", struct.pack("<3i", *size.tolist()))
        + _chunk(b"XYZI", struct.pack("<i", int(e - s)) + xyzi[s:e].tobytes())
        for s, e in zip(starts, ends))
    h = float(result.voxel_size)
    root_attrs = {"_name": "glvox", "glvox_origin": " ".join(repr(float(v)) for v in result.origin),
                  "glvox_voxel_size": repr(h), "glvox_dims": " ".join(str(int(d)) for d in result.dims),
                  "glvox_up": up}
    scene = _chunk(b"nTRN", struct.pack("<i", 0) + _dict(root_attrs) + struct.pack("<4i", 1, -1, -1, 1) + _dict({}))
    scene += _chunk(b"nGRP", struct.pack("<i", 1) + _dict({}) + struct.pack("<i", len(ids))
                    + struct.pack(f"<{len(ids)}i", *[2 + 2 * m for m in range(len(ids))]))
    half, centre = size // 2, dims // 2
    for m, mid in enumerate(ids.tolist()):
        offset = np.array(np.unravel_index(mid, blocks)) * size
        t = offset + half - centre
        frame = {"_t": " ".join(str(int(v)) for v in t)}
        scene += _chunk(b"nTRN", struct.pack("<i", 2 + 2 * m) + _dict({})
                        + struct.pack("<4i", 3 + 2 * m, -1, 0, 1) + _dict(frame))
        scene += _chunk(b"nSHP", struct.pack("<i", 3 + 2 * m) + _dict({}) + struct.pack("<ii", 1, m) + _dict({}))
    scene += _chunk(b"LAYR", struct.pack("<i", 0) + _dict({}) + struct.pack("<i", -1))
    rgba = np.zeros((256, 4), np.uint8)
    rgba[: len(palette)] = palette
    body = models + scene + _chunk(b"RGBA", rgba.tobytes())
    return b"VOX " + struct.pack("<i", VERSION) + _chunk(b"MAIN", b"", body)


def write(result: Result, path: Path, *, up: str = "z") -> None:
    """Write ``result`` as MagicaVoxel .vox (see the module docstring)."""
    data = vox_bytes(result, up=up)
    extras = getattr(result, "extras", None)
    if extras:
        warnings.warn(FormatWarning(f".vox keeps the voxels and their colours; the extra masks {sorted(extras)} "
                                    "are not written (.npz, .vti and .vdb keep them)"), stacklevel=3)
    path.write_bytes(data)


FORMAT = Format("MagicaVoxel", (".vox",), write, None, library=pillow, options=("up",))
