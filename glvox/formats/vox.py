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

Read (:func:`read`): the models composed by the scene graph (translations;
rotated instances refused), colours from the palette; glvox's own files
come back on their grid.
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FormatError
from ..grid import MAX_VOXELS, GridSpec
from ..results import Result, VoxelGrid
from .colors import DEFAULT_COLOR, pillow, quantize, voxel_colors
from .common import Format, warn_dropped

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
    warn_dropped(result, ".vox", keeps="the voxels and their colours", keeps_attributes=("color",))
    path.write_bytes(data)


# -- reading ------------------------------------------------------------------------------------------

def _children(data: bytes, start: int, end: int, path: Path):
    """(id, content) of each chunk in ``data[start:end]``, descending into every chunk's children."""
    at = start
    while at < end:
        if at + 12 > end:
            raise FormatError(f"{path}: a .vox chunk header runs past the end of its parent at byte {at}")
        cid = data[at:at + 4]
        n, m = struct.unpack_from("<ii", data, at + 4)
        if n < 0 or m < 0 or at + 12 + n + m > end:
            raise FormatError(f"{path}: the .vox chunk {cid!r} at byte {at} runs past the end of its parent")
        yield cid, data[at + 12:at + 12 + n]
        yield from _children(data, at + 12 + n, at + 12 + n + m, path)
        at += 12 + n + m


class _Reader:
    """A cursor over one chunk's content: ints, STRINGs and DICTs as the format defines them."""

    def __init__(self, content: bytes):
        self.content, self.at = content, 0

    def int(self) -> int:
        (v,) = struct.unpack_from("<i", self.content, self.at)
        self.at += 4
        return v

    def string(self) -> str:
        n = self.int()
        s = self.content[self.at:self.at + n].decode("utf-8", "replace")
        self.at += n
        return s

    def dict(self) -> dict[str, str]:
        return {self.string(): self.string() for _ in range(self.int())}


def _scene(chunks: list[tuple[bytes, bytes]], n_models: int, path: Path):
    """(model id, translation (3,) int64) of every shape instance, and the root's attributes."""
    nodes: dict[int, tuple[bytes, Any]] = {}
    for cid, content in chunks:
        if cid not in (b"nTRN", b"nGRP", b"nSHP"):
            continue
        r = _Reader(content)
        node = r.int()
        attrs = r.dict()
        if cid == b"nTRN":
            child, _reserved, _layer, frames = r.int(), r.int(), r.int(), r.int()
            frame = r.dict() if frames > 0 else {}
            if frame.get("_r", "4") != "4":              # 4: the identity (rows x, y, z, all positive)
                raise FormatError(f"{path}: glvox reads .vox models that are translated, not rotated "
                                  f"(node {node} has rotation {frame['_r']})")
            t = np.array([int(v) for v in frame.get("_t", "0 0 0").split()], dtype=np.int64)
            nodes[node] = (cid, (child, t, attrs))
        elif cid == b"nGRP":
            nodes[node] = (cid, [r.int() for _ in range(r.int())])
        else:
            models = []
            for _ in range(r.int()):
                models.append(r.int())
                r.dict()                                 # the model's attributes (frame index)
            nodes[node] = (cid, models)
    if not nodes:                                        # no scene graph (older files): models at the origin
        return [(m, np.zeros(3, np.int64)) for m in range(n_models)], {}
    out, stack, seen = [], [(0, np.zeros(3, np.int64))], set()
    while stack:
        node, t = stack.pop()
        if node in seen:
            raise FormatError(f"{path}: the .vox scene graph visits node {node} twice")
        seen.add(node)
        if node not in nodes:
            raise FormatError(f"{path}: the .vox scene graph names node {node}, which the file lacks")
        cid, data = nodes[node]
        if cid == b"nTRN":
            stack.append((data[0], t + data[1]))
        elif cid == b"nGRP":
            stack.extend((c, t) for c in data)
        else:
            out.extend((m, t) for m in data)
    return out, nodes[0][1][2] if nodes.get(0, (None,))[0] == b"nTRN" else {}


def _placement(root: dict[str, str], path: Path):
    """glvox's (dims, origin, voxel size, up) from the root node's attributes, or None."""
    try:
        dims = np.array([int(v) for v in root["glvox_dims"].split()], dtype=np.int64)
        origin = np.array([float(v) for v in root["glvox_origin"].split()])
        h, up = float(root["glvox_voxel_size"]), root.get("glvox_up", "z")
    except (KeyError, ValueError):
        return None
    if dims.shape != (3,) or origin.shape != (3,) or up not in UPS:
        raise FormatError(f"{path}: the glvox placement of this .vox file is malformed: {root}")
    return dims, origin, h, up


def read(path: Path) -> VoxelGrid:
    """A VoxelGrid with a ``'color'`` attribute from a .vox file (models composed by the scene graph).

    Files glvox wrote come back on their grid (origin, voxel size, dims and
    axes from the root node's attributes).  Other files: voxel size 1 and
    the scene's own coordinates (voxel p of the scene is the box [p, p + 1]),
    the grid the voxels' bounding box.  Colours from the ``RGBA`` palette
    (entry c - 1 for index c); a file without one (MagicaVoxel's default
    palette, which glvox does not carry) reads without colours.  Rotated
    instances are refused.
    """
    data = path.read_bytes()
    try:
        return _read(data, path)
    except FormatError:
        raise
    except (struct.error, ValueError, UnicodeError) as exc:  # a truncated chunk, a malformed number
        raise FormatError(f"{path}: a broken .vox file ({exc})") from None


def _read(data: bytes, path: Path) -> VoxelGrid:
    """:func:`read` of the file's bytes (struct.error / ValueError where a chunk is cut short)."""
    if len(data) < 20 or data[:4] != b"VOX " or data[8:12] != b"MAIN":
        raise FormatError(f"{path}: not a MagicaVoxel .vox file (no 'VOX ' header and MAIN chunk)")
    n, m = struct.unpack_from("<ii", data, 12)
    chunks = list(_children(data, 20 + n, min(len(data), 20 + n + m), path))
    sizes = [np.array(struct.unpack_from("<3i", c), np.int64) for cid, c in chunks if cid == b"SIZE"]
    xyzi = [np.frombuffer(c, np.uint8, 4 * struct.unpack_from("<i", c)[0], 4).reshape(-1, 4)
            for cid, c in chunks if cid == b"XYZI"]
    if not sizes or len(sizes) != len(xyzi):
        raise FormatError(f"{path}: a .vox file needs SIZE and XYZI chunks in pairs, "
                          f"got {len(sizes)} and {len(xyzi)}")
    rgba = next((np.frombuffer(c, np.uint8, 1024).reshape(256, 4) for cid, c in chunks if cid == b"RGBA"), None)
    instances, root = _scene(chunks, len(sizes), path)
    pos, index = [np.zeros((0, 3), np.int64)], [np.zeros(0, np.uint8)]
    for model, t in instances:
        if not 0 <= model < len(sizes):
            raise FormatError(f"{path}: the .vox scene graph names model {model} of {len(sizes)}")
        v = xyzi[model][xyzi[model][:, 3] > 0]           # index 0 is empty (writers may list such cells)
        pos.append(t + v[:, :3].astype(np.int64) - sizes[model] // 2)
        index.append(v[:, 3])
    pos, index = np.concatenate(pos), np.concatenate(index)
    placement = _placement(root, path)
    if placement is not None:
        dims, origin, h, up = placement
        p = pos + (dims[[0, 2, 1]] if up == "y" else dims) // 2
        ijk = p if up == "z" else np.stack([p[:, 0], p[:, 2], dims[2] - 1 - p[:, 1]], axis=1)
    else:
        lo = pos.min(axis=0) if len(pos) else np.zeros(3, np.int64)
        ijk = pos - lo
        dims = ijk.max(axis=0) + 1 if len(pos) else sizes[0]
        origin, h = lo.astype(np.float64), 1.0
    if len(ijk) and (ijk.min() < 0 or np.any(ijk >= dims)):
        raise FormatError(f"{path}: voxels lie outside the grid {tuple(dims)} its glvox placement gives")
    spec = GridSpec(tuple(int(d) for d in dims), origin, h)
    if spec.n_voxels > MAX_VOXELS:
        raise FormatError(f"{path}: its voxels span {spec.dims}, more than the {MAX_VOXELS} voxels glvox keeps dense")
    lin = np.ravel_multi_index(ijk.T, spec.dims) if len(ijk) else np.zeros(0, np.int64)
    lin, last = np.unique(lin[::-1], return_index=True)  # overlapping instances: the last one listed wins
    occ = np.zeros(spec.dims, bool)
    occ.reshape(-1)[lin] = True
    # one colour row per voxel of indices(), in C order = sorted lin
    colors = None if rgba is None else {"color": rgba[index[::-1][last].astype(np.int64) - 1].copy()}
    return VoxelGrid(occ, spec, attributes=colors)


FORMAT = Format("MagicaVoxel", (".vox",), write, read, library=pillow, options=("up",), attributes=("color",))
