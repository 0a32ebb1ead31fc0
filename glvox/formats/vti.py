"""VTK image data (``.vti``, VTK's XML format; ParaView, PyVista and VTK open it).

glvox writes and reads these files itself, with the standard library: the
only library that reads them is VTK (a wheel of several hundred MiB), too
heavy for a core dependency; meshio handles unstructured meshes, not image
data, and pyevtk writes uncompressed files only and reads none.  The tests
read glvox's files with VTK's own reader (test extra) and read with glvox
the files VTK writes in each of its encodings.

Written: ``WholeExtent 0 nx 0 ny 0 nz`` (points), ``Origin`` the grid's min
corner, ``Spacing h h h``, ``Direction`` the identity, and one uint8 **cell**
array ``occupancy`` (1 = occupied) plus one ``extra_<name>`` per extra mask,
one Float32 ``field_<name>`` per float field (``gwn-solid``'s winding numbers; a
signed distance field: ``field_sdf``, world units, with ``occupancy`` = inside and
the masks ``extra_band`` and ``extra_uncertain``)
and one ``attr_<name>`` per per-voxel attribute (``grid.attributes``:
Int32 ``triangle`` / ``material``, 4-component UInt8 ``color``, 3-component
Float32 ``normal``; unset voxels hold the empty values of
:meth:`VoxelGrid.attribute_grid`), zlib-compressed in appended raw binary
(UInt64 headers).  Cell data, not
point data: the image's cells are glvox's voxels, so cell (i, j, k) is the
box ``origin + [i, i+1] x [j, j+1] x [k, k+1] * h`` and its center
``origin + (i, j, k) h + h/2``, the image's bounds are the grid's, and
ParaView's Threshold shows each voxel as its box; point data would put
samples at the voxel centers and interpolate between them.

Read: ImageData with one piece; cell or point arrays (a point array's
samples are the voxel centers); encodings ascii, binary (base64) and
appended (raw or base64); no compression, zlib or LZMA; UInt32 or UInt64
headers; either byte order.  The cell array ``occupancy`` is the occupancy
(else the cell scalars, else the first cell array, else the point data's);
cell arrays ``extra_<name>`` become extra masks, ``field_<name>`` float
fields and ``attr_<name>`` the attributes of the occupied voxels (files whose
axes are the world axes in glvox's order and sign, as glvox writes them).
"""

from __future__ import annotations

import base64
import lzma
import re
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path

import numpy as np

from ..errors import FormatError, GridError
from ..results import Result, SDFGrid, VoxelGrid
from .common import ALL_ATTRIBUTES, Format, as_grid, grid_from_matrix, sdf_as_grid

#: Uncompressed bytes per zlib block (VTK's own default is 32 KiB; bigger
#: blocks mean fewer header entries at the same ratio).
BLOCK = 1 << 20

_TYPES = {"Int8": "i1", "UInt8": "u1", "Int16": "i2", "UInt16": "u2", "Int32": "i4", "UInt32": "u4",
          "Int64": "i8", "UInt64": "u8", "Float32": "f4", "Float64": "f8"}


def _compress(raw: bytes) -> bytes:
    """VTK's compressed-data layout: UInt64 header (blocks, block size, last
    block size or 0 when full, compressed sizes) and the zlib blocks."""
    blocks = [raw[i:i + BLOCK] for i in range(0, len(raw), BLOCK)] or [b""]
    packed = [zlib.compress(b, 6) for b in blocks]
    header = np.array([len(blocks), BLOCK, len(raw) % BLOCK] + [len(p) for p in packed], dtype="<u8")
    return header.tobytes() + b"".join(packed)


def _f(x: float) -> str:
    return repr(float(x))


def write(result: Result, path: Path) -> None:
    """Write ``result`` (a VoxelGrid, or an octree decoded) as VTK image data with uint8 cell arrays."""
    grid = sdf_as_grid(result) if isinstance(result, SDFGrid) else as_grid(result, "VTK image data")
    nx, ny, nz = grid.dims
    arrays = {"occupancy": grid.dense(), **{f"extra_{k}": g.dense() for k, g in grid.extras.items()},
              **{f"field_{k}": a for k, a in grid.fields.items()}}
    payloads, entries, offset = [], [], 0
    for name, a in arrays.items():
        # cell (i, j, k) is value i + nx (j + ny k): x fastest, Fortran order of [i, j, k]
        floats = name.startswith("field_")
        a = np.asarray(a, dtype="<f4" if floats else np.uint8)
        blob = _compress(a.tobytes(order="F"))
        lo, hi = (_f(a.min()), _f(a.max())) if floats and a.size else ("0", "1")
        entries.append(f'        <DataArray type="{"Float32" if floats else "UInt8"}" Name="{name}" '
                       f'format="appended" RangeMin="{lo}" RangeMax="{hi}" offset="{offset}"/>')
        payloads.append(blob)
        offset += len(blob)
    for name in grid.attributes:
        dense = grid.attribute_grid(name)
        comps = dense.shape[3] if dense.ndim == 4 else 1
        # x fastest, the components of a cell together: C order of (k, j, i, component)
        values = np.ascontiguousarray(dense.reshape(nx, ny, nz, comps).transpose(2, 1, 0, 3))
        vtk_type = next(t for t, code in _TYPES.items() if np.dtype(code) == values.dtype)
        blob = _compress(values.astype(values.dtype.newbyteorder("<"), copy=False).tobytes())
        entries.append(f'        <DataArray type="{vtk_type}" Name="attr_{name}" NumberOfComponents="{comps}" '
                       f'format="appended" offset="{offset}"/>')
        payloads.append(blob)
        offset += len(blob)
    extent = f"0 {nx} 0 {ny} 0 {nz}"
    h = _f(grid.voxel_size)
    head = "\n".join([
        '<?xml version="1.0"?>',
        '<VTKFile type="ImageData" version="1.0" byte_order="LittleEndian" header_type="UInt64" '
        'compressor="vtkZLibDataCompressor">',
        f'  <ImageData WholeExtent="{extent}" Origin="{" ".join(_f(x) for x in grid.origin)}" '
        f'Spacing="{h} {h} {h}" Direction="1 0 0 0 1 0 0 0 1">',
        f'    <Piece Extent="{extent}">',
        '      <PointData>',
        '      </PointData>',
        '      <CellData Scalars="occupancy">',
        *entries,
        '      </CellData>',
        '    </Piece>',
        '  </ImageData>',
        '  <AppendedData encoding="raw">',
        '   _'])
    with open(path, "wb") as f:
        f.write(head.encode("ascii"))
        for p in payloads:
            f.write(p)
        f.write(b"\n  </AppendedData>\n</VTKFile>\n")


class _Decoder:
    """Decodes the DataArrays of one file (its header type, compressor and byte order)."""

    def __init__(self, root: ET.Element, appended: bytes, appended_encoding: str, path: Path):
        self.path = path
        order = "<" if root.get("byte_order", "LittleEndian") == "LittleEndian" else ">"
        self.order = order
        self.uint = np.dtype(order + ("u8" if root.get("header_type", "UInt32") == "UInt64" else "u4"))
        comp = root.get("compressor", "")
        if comp in ("", None):
            self.decompress = None
        elif comp == "vtkZLibDataCompressor":
            self.decompress = zlib.decompress
        elif comp == "vtkLZMADataCompressor":
            self.decompress = lzma.decompress
        else:
            raise FormatError(f"{path}: glvox reads VTK files compressed with zlib or LZMA, not {comp}; "
                              "resave it with another compressor")
        self.appended, self.appended_encoding = appended, appended_encoding

    def _raw(self, take) -> bytes:
        """The array's bytes; ``take(n)`` returns the next n decoded bytes of the stream."""
        w = self.uint.itemsize
        if self.decompress is None:
            n = int(np.frombuffer(take(w), self.uint)[0])
            return take(n)
        nb = int(np.frombuffer(take(w), self.uint)[0])
        sizes = np.frombuffer(take(w * (2 + nb)), self.uint).astype(np.int64)
        return b"".join(self.decompress(take(int(c))) for c in sizes[2:])

    def array(self, el: ET.Element, count: int, components: bool = False) -> np.ndarray:
        """The values (count,) of DataArray ``el``, in its own dtype (``components``:
        (count, n) for an array of n components)."""
        t = el.get("type", "")
        if t not in _TYPES:
            raise FormatError(f"{self.path}: unsupported VTK array type {t!r} of {el.get('Name')!r}")
        comps = int(el.get("NumberOfComponents", "1"))
        if comps != 1 and not components:
            raise FormatError(f"{self.path}: array {el.get('Name')!r} has several components; glvox reads scalars")
        if components:
            return self.array_values(el, count * comps, t).reshape(count, comps)
        return self.array_values(el, count, t)

    def array_values(self, el: ET.Element, count: int, t: str) -> np.ndarray:
        """The first ``count`` values of DataArray ``el`` of VTK type ``t``."""
        dtype = np.dtype(self.order + _TYPES[t])
        fmt = el.get("format", "ascii")
        if fmt == "ascii":
            values = np.array((el.text or "").split(), dtype=dtype.newbyteorder("="))
        elif fmt == "binary":
            values = np.frombuffer(self._base64(re.sub(rb"\s", b"", (el.text or "").encode("ascii"))), dtype)
        elif fmt == "appended":
            start = int(el.get("offset", "0"))
            if self.appended_encoding == "base64":
                values = np.frombuffer(self._base64(self.appended[start:]), dtype)
            else:
                pos = [start]

                def take(n):
                    b = self.appended[pos[0]:pos[0] + n]
                    pos[0] += n
                    return b

                values = np.frombuffer(self._raw(take), dtype)
        else:
            raise FormatError(f"{self.path}: unknown DataArray format {fmt!r}")
        if values.size < count:
            raise FormatError(f"{self.path}: array {el.get('Name')!r} holds {values.size} values, "
                              f"the extent needs {count}")
        return values[:count]

    def _base64(self, text: bytes) -> bytes:
        """Base64 data as VTK writes it: uncompressed, the byte count and the data in
        one stream; compressed, the block header encoded on its own, then the blocks."""
        w = self.uint.itemsize
        first = base64.b64decode(text[:_b64_chars(w)])
        if self.decompress is None:
            n = int(np.frombuffer(first[:w], self.uint)[0])
            return base64.b64decode(text[:_b64_chars(w + n)])[w:w + n]
        nb = int(np.frombuffer(first[:w], self.uint)[0])
        hlen = _b64_chars(w * (3 + nb))
        sizes = np.frombuffer(base64.b64decode(text[:hlen])[:w * (3 + nb)], self.uint).astype(np.int64)[3:]
        body = base64.b64decode(text[hlen:hlen + _b64_chars(int(sizes.sum()))])
        ends = np.cumsum(sizes)
        return b"".join(self.decompress(body[e - c:e]) for c, e in zip(sizes, ends))


def _b64_chars(n: int) -> int:
    """Characters of ``n`` bytes in padded base64."""
    return -(-n // 3) * 4


def _fortran(a: np.ndarray, dims: tuple[int, int, int]) -> np.ndarray:
    """A flat VTK array (x fastest) as [i, j, k]."""
    return a.reshape(dims, order="F")


def _parse(path: Path) -> tuple[ET.Element, bytes, str]:
    """The XML tree (appended data cut off) and the appended bytes after '_'."""
    data = path.read_bytes()
    at = data.find(b"<AppendedData")
    try:
        if at < 0:
            return ET.fromstring(data), b"", "raw"
        tag_end = data.index(b">", at)
        encoding = re.search(rb'encoding="(\w+)"', data[at:tag_end]).group(1).decode()
        start = data.index(b"_", tag_end) + 1
        root = ET.fromstring(data[:at] + b"</VTKFile>")
        end = data.rfind(b"</AppendedData>")
        return root, data[start:end if end > start else len(data)], encoding
    except (ET.ParseError, ValueError, AttributeError) as exc:
        raise FormatError(f"{path} is not a valid VTK XML file ({exc})") from None


def read(path: Path) -> VoxelGrid:
    """A VoxelGrid from a VTK ImageData file (nonzero = occupied)."""
    root, appended, encoding = _parse(path)
    image = root.find("ImageData")
    pieces = image.findall("Piece") if image is not None else []
    if root.get("type") != "ImageData" or image is None or len(pieces) != 1:
        raise FormatError(f"{path}: glvox reads VTK ImageData files with one piece")
    piece = pieces[0]
    try:
        ext = np.array(piece.get("Extent", image.get("WholeExtent")).split(), dtype=np.int64).reshape(3, 2)
        origin = np.array(image.get("Origin", "0 0 0").split(), dtype=np.float64)
        spacing = np.array(image.get("Spacing", "1 1 1").split(), dtype=np.float64)
        direction = np.array(image.get("Direction", "1 0 0 0 1 0 0 0 1").split(), dtype=np.float64).reshape(3, 3)
    except (ValueError, AttributeError) as exc:
        raise FormatError(f"{path}: bad ImageData extent, origin, spacing or direction ({exc})") from None
    dec = _Decoder(root, appended, encoding, path)
    steps = direction * spacing[None, :]
    points = ext[:, 1] - ext[:, 0] + 1
    cells = {el.get("Name"): el for el in piece.findall("CellData/DataArray")}
    scalars = piece.find("CellData").get("Scalars") if piece.find("CellData") is not None else None
    name = next((n for n in ("occupancy", scalars) if n in cells), next(iter(cells), None))
    if name is not None:
        dims, first = tuple(int(n) for n in np.maximum(points - 1, 1)), origin + steps @ (ext[:, 0] + 0.5)
        source = cells[name]
    else:
        pts = piece.findall("PointData/DataArray")
        if not pts:
            raise FormatError(f"{path}: the image holds no cell or point data array")
        dims, first, source = tuple(int(n) for n in points), origin + steps @ ext[:, 0], pts[0]
    n = dims[0] * dims[1] * dims[2]
    extras = {} if name is None else {k[len("extra_"):]: _fortran(dec.array(el, n), dims)
                                      for k, el in cells.items() if k.startswith("extra_") and k != name}
    fields = {} if name is None else {k[len("field_"):]: _fortran(dec.array(el, n), dims).astype(np.float32)
                                      for k, el in cells.items() if k.startswith("field_") and k != name}
    grid = grid_from_matrix(_fortran(dec.array(source, n), dims), steps, first, path, extras=extras,
                            fields=fields)
    attrs = {k[len("attr_"):]: el for k, el in cells.items() if k.startswith("attr_") and k != name}
    if attrs and name is not None:
        _read_attributes(grid, attrs, dec, dims, steps, path)
    return grid


def _read_attributes(grid: VoxelGrid, attrs: dict, dec, dims, steps, path: Path) -> None:
    """The ``attr_<name>`` cell arrays as ``grid.attributes`` (rows of the occupied voxels)."""
    if not (grid.dims == dims and np.all(np.diag(steps) > 0)):
        raise FormatError(f"{path}: per-voxel attributes are read from files in glvox's axis order and sign only")
    idx = grid.indices()
    n = dims[0] * dims[1] * dims[2]
    out = {}
    for key, el in attrs.items():
        values = dec.array(el, n, components=True)  # (n, comps), x fastest
        dense = values.reshape(dims[2], dims[1], dims[0], -1).transpose(2, 1, 0, 3)
        rows = dense[idx[:, 0], idx[:, 1], idx[:, 2]]
        out[key] = rows[:, 0] if rows.shape[1] == 1 else rows
    try:
        grid.set_attributes({k: v.astype(v.dtype.newbyteorder("="), copy=False) for k, v in out.items()})
    except GridError as exc:
        raise FormatError(f"{path}: {exc}") from None


FORMAT = Format("VTK image data", (".vti",), write, read, attributes=ALL_ATTRIBUTES, sdf=True)
