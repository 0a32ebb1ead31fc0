"""Fast readers for the common mesh files: PLY, STL, OFF and plain OBJ straight into numpy.

:func:`read_fast` parses a file's bytes with whole-array numpy calls
(``np.frombuffer`` on a binary layout, one ``np.fromstring`` over a text body)
instead of trimesh's line-by-line Python, and returns exactly the vertices and
faces ``trimesh.load(path, process=False)`` returns for it: the same float
rounding path (a ``float`` PLY property is parsed to float64, rounded to
float32 and widened again, as trimesh does), the same vertex order, the same
unreferenced-vertex handling of OBJ.  ``tests/test_mesh.py`` checks the
equality array for array on every shared mesh and on generated variants.

It reads only the layouts it can read exactly and returns None for anything
else (quads, texture coordinates, materials, comments inside OFF, trailing
data, indices out of range, a malformed body...): glvox then loads the file
with trimesh as before, so every other file, and every error message, is
unchanged.

Measured against trimesh's reader and Open3D's on the shared meshes:
``python compare/bench_load.py`` (figures in README "Loading, readback, cold start, workers").
"""

from __future__ import annotations

import io
import re
import warnings
from typing import Optional

import numpy as np

#: (vertices (V, 3) float64, faces (F, 3) int64) as trimesh would return them.
Arrays = tuple[np.ndarray, np.ndarray]

#: The suffixes :func:`read_fast` tries (lower case, no dot).
FAST_SUFFIXES = ("ply", "stl", "off", "obj")

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def read_fast(suffix: str, data: bytes) -> Optional[Arrays]:
    """Vertices and faces of a mesh file's bytes, or None when the fast path does not apply.

    Parameters
    ----------
    suffix : str
        The file's suffix, lower case, without the dot (``'ply'``, ``'stl'``...).
    data : bytes
        The whole file.

    Returns
    -------
    (vertices, faces) or None
        vertices (V, 3) float64 world coordinates, faces (F, 3) int64, equal to
        what ``trimesh.load(..., process=False)`` gives; None: load with trimesh.
    """
    reader = dict(zip(FAST_SUFFIXES, (_ply, _stl, _off, _obj))).get(suffix)
    if reader is None or not data:
        return None
    try:
        with warnings.catch_warnings():
            # np.fromstring warns (and stops) at text it cannot parse: not our layout
            warnings.simplefilter("error")
            return reader(data)
    except (ValueError, TypeError, IndexError, UnicodeDecodeError, Warning):
        return None


def _numbers(text: bytes) -> np.ndarray:
    """Every whitespace-separated number of ``text`` as float64 (ValueError at anything else)."""
    return np.fromstring(text, dtype=np.float64, sep=" ")


def _table(lines, n_rows: int, n_cols: int) -> np.ndarray:
    """(n_rows, n_cols) float64 from text lines (a file-like object or a list of bytes).

    numpy's C table reader: 30-40% faster than :func:`_numbers` on the ASCII
    PLY and STL bodies (``python compare/bench_load.py``), correctly rounded
    like it; ValueError unless the lines are exactly that table (blank lines
    are skipped, so they make a table too short).
    """
    if n_rows == 0:
        return np.empty((0, n_cols))
    table = np.loadtxt(lines, dtype=np.float64, comments=None, ndmin=2)
    if table.shape != (n_rows, n_cols):
        raise ValueError(f"expected a {n_rows} x {n_cols} table, got {table.shape}")
    return table


def _triangles(counts: np.ndarray, idx: np.ndarray, n_vertices: int) -> Optional[np.ndarray]:
    """(F, 3) int64 faces when every face is a triangle with integral indices in range, else None."""
    if not np.all(counts == 3):
        return None
    f = idx.astype(np.int64)
    if f.size and (not np.array_equal(f, idx) or f.min() < 0 or f.max() >= n_vertices):
        return None
    return f.reshape(-1, 3)


# -- PLY -----------------------------------------------------------------------
def _ply_header(data: bytes):
    """(format, [(element, count, [(property, type or ('list', count type, item type))])], body start)."""
    end = data.find(b"end_header", 0, 1 << 16)
    if not data.startswith(b"ply") or end < 0:
        return None
    nl = data.find(b"\n", end)
    if nl < 0:
        return None
    lines = data[:end].decode("ascii").replace("\r", "").split("\n")
    fmt, elements = None, []
    for line in lines[1:]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) == 3:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3:
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements and len(words) == 3 and words[1] in _PLY_TYPES:
            elements[-1][2].append((words[2], _PLY_TYPES[words[1]]))
        elif (words[0] == "property" and elements and len(words) == 5 and words[1] == "list"
              and words[2] in _PLY_TYPES and words[3] in _PLY_TYPES):
            elements[-1][2].append((words[4], ("list", _PLY_TYPES[words[2]], _PLY_TYPES[words[3]])))
        else:
            return None
    return fmt, elements, nl + 1


def _ply(data: bytes) -> Optional[Arrays]:
    header = _ply_header(data)
    if header is None:
        return None
    fmt, elements, start = header
    if [e[0] for e in elements] != ["vertex", "face"]:
        return None
    (_, nv, vprops), (_, nf, fprops) = elements
    vnames = [p[0] for p in vprops]
    if any(isinstance(p[1], tuple) for p in vprops) or not {"x", "y", "z"} <= set(vnames):
        return None
    lists = [i for i, p in enumerate(fprops) if isinstance(p[1], tuple)]
    if len(lists) != 1 or fprops[lists[0]][0] not in ("vertex_indices", "vertex_index"):
        return None
    if fmt == "ascii":
        return _ply_ascii(data[start:], nv, vprops, nf, fprops)
    if fmt in ("binary_little_endian", "binary_big_endian"):
        return _ply_binary(data[start:], "<" if fmt == "binary_little_endian" else ">", nv, vprops, nf, fprops)
    return None


def _ply_vertices(columns: dict, vprops) -> np.ndarray:
    """x, y, z in the property's own type, then float64: trimesh's rounding path."""
    types = dict(vprops)
    return np.column_stack([np.asarray(columns[c]).astype(types[c]) for c in "xyz"]).astype(np.float64)


def _ply_ascii(body: bytes, nv, vprops, nf, fprops) -> Optional[Arrays]:
    """Vertex lines parsed as float64, face lines as int64 (integers parse ~3x faster)."""
    if len(fprops) != 1:
        return None  # scalar face properties beside the list: leave the layout to trimesh
    newlines = np.flatnonzero(np.frombuffer(body, np.uint8) == 10)
    if len(newlines) < nv:
        return None
    split = int(newlines[nv - 1]) + 1 if nv else 0
    verts = _table(io.BytesIO(body[:split]), nv, len(vprops))
    fdata = np.fromstring(body[split:], dtype=np.int64, sep=" ")
    if fdata.size != 4 * nf:
        return None  # not all triangles, blank lines, or more text than the header declares
    fdata = fdata.reshape(nf, 4)
    idx = fdata[:, 1:]
    if np.any(idx != idx.astype(fprops[0][1][2])):
        return None
    faces = _triangles(fdata[:, 0], idx, nv)
    if faces is None:
        return None
    names = [p[0] for p in vprops]
    return _ply_vertices({c: verts[:, names.index(c)] for c in "xyz"}, vprops), faces


def _ply_binary(body: bytes, order: str, nv, vprops, nf, fprops) -> Optional[Arrays]:
    vdtype = np.dtype([(name, order + t) for name, t in vprops])
    fields = []
    for name, t in fprops:
        if isinstance(t, tuple):
            fields += [("__count", order + t[1]), ("__idx", order + t[2], (3,))]
        else:
            fields.append((name, order + t))
    fdtype = np.dtype(fields)
    if len(body) != nv * vdtype.itemsize + nf * fdtype.itemsize:
        return None  # not all triangles (or trailing bytes): a variable layout
    v = np.frombuffer(body, vdtype, count=nv)
    f = np.frombuffer(body, fdtype, count=nf, offset=nv * vdtype.itemsize)
    faces = _triangles(f["__count"], f["__idx"], nv)
    if faces is None:
        return None
    return _ply_vertices({c: v[c] for c in "xyz"}, [(n, order + t) for n, t in vprops]), faces


# -- STL -----------------------------------------------------------------------
_STL_RECORD = np.dtype([("normals", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attributes", "<u2")])


def _stl(data: bytes) -> Optional[Arrays]:
    if len(data) >= 84:
        count = int.from_bytes(data[80:84], "little")
        if len(data) == 84 + count * _STL_RECORD.itemsize:  # trimesh's test for a binary STL
            if count == 0:
                return None
            rec = np.frombuffer(data, _STL_RECORD, count=count, offset=84)
            return (rec["vertices"].reshape(-1, 3).astype(np.float64),
                    np.arange(3 * count, dtype=np.int64).reshape(-1, 3))
    return _stl_ascii(data)


def _stl_ascii(data: bytes) -> Optional[Arrays]:
    """One ``solid``: the numbers after each ``vertex`` up to the end of its line, as trimesh reads them."""
    if not data.isascii():
        return None  # trimesh lower-cases decoded text; for ASCII that is bytes.lower()
    text = data.strip().lower()
    start, end = text.find(b"solid"), text.find(b"endsolid")
    if start < 0 or end < start or text.find(b"endsolid", end + 8) >= 0:
        return None  # several solids make a scene in trimesh
    rows = _STL_VERTEX.findall(text, start, end)
    if len(rows) < 3 or len(rows) % 3:
        return None
    return _table(rows, len(rows), 3), np.arange(len(rows), dtype=np.int64).reshape(-1, 3)


_STL_VERTEX = re.compile(rb"vertex([^\n]*)")


# -- OFF -----------------------------------------------------------------------
def _off(data: bytes) -> Optional[Arrays]:
    text = data.strip()
    if not text.startswith(b"OFF") or b"#" in text:
        return None
    lines = text[3:].lstrip().split(b"\n", 1)
    if len(lines) != 2:
        return None
    counts = lines[0].split()
    if len(counts) not in (2, 3):
        return None
    nv, nf = int(counts[0]), int(counts[1])
    nums = _numbers(lines[1])
    if nums.size != 3 * nv + 4 * nf:
        return None  # colors, polygons, or extra lines: trimesh's general reader
    fdata = nums[3 * nv:].reshape(nf, 4)
    faces = _triangles(fdata[:, 0], fdata[:, 1:], nv)
    if faces is None:
        return None
    return nums[:3 * nv].reshape(nv, 3), faces


# -- OBJ -----------------------------------------------------------------------
def _obj(data: bytes) -> Optional[Arrays]:
    """``v x y z`` lines, then ``f a b c`` lines (comments, blank lines, ``s`` and
    one ``o``/``g`` line allowed anywhere).

    Everything trimesh treats specially (texture coordinates, normals,
    slashes, polygons, materials, line continuations, several groups,
    interleaved blocks, relative indices) returns None.
    """
    if data.find(b"\\") >= 0 or data.find(b"\r") >= 0:
        return None  # continuation lines (even inside comments) and CRLF: trimesh's reader
    a = np.frombuffer(data, np.uint8)
    nl = np.flatnonzero(a == 10)
    starts = np.concatenate(([0], nl + 1))
    ends = np.concatenate((nl, [a.size]))
    space = a <= 32
    token = ~space
    token[1:] &= space[:-1]
    cum = np.concatenate(([0], np.cumsum(token, dtype=np.int32)))
    tokens = cum[ends] - cum[starts]
    padded = np.concatenate((a, np.full(2, 10, np.uint8)))
    first, sep = padded[starts], padded[starts + 1] == 32
    is_v = (first == ord("v")) & sep
    is_f = (first == ord("f")) & sep
    group = ((first == ord("o")) | (first == ord("g"))) & sep
    other = (tokens == 0) | (first == ord("#")) | group | ((first == ord("s")) & sep)
    if not np.all(((is_v | is_f) & (tokens == 4)) | (other & ~is_v & ~is_f)) or group.sum() > 1:
        return None
    blocks = [_obj_block(data, starts, ends, is_v, is_f, tokens),
              _obj_block(data, starts, ends, is_f, is_v, tokens)]
    if blocks[0] is None or blocks[1] is None:
        return None
    if blocks[1].find(b"/") >= 0:
        return None  # texture or normal indices
    v = _numbers(blocks[0].replace(b"v", b" "))
    f = np.fromstring(blocks[1].replace(b"f", b" "), dtype=np.int64, sep=" ")
    nv = v.size // 3
    if v.size != 3 * int(is_v.sum()) or f.size != 3 * int(is_f.sum()):
        return None
    faces = _triangles(np.full(f.size // 3, 3), f - 1, nv)
    if faces is None:
        return None
    v = v.reshape(nv, 3)
    # trimesh keeps only the referenced vertices, in file order
    used = np.zeros(nv, dtype=bool)
    used[faces] = True
    if used.all():
        return v, faces
    inverse = np.zeros(nv, dtype=np.int64)
    inverse[used] = np.arange(int(used.sum()))
    return v[used], inverse[faces]


def _obj_block(data: bytes, starts, ends, mine, theirs, tokens) -> Optional[bytes]:
    """The text of the lines ``mine`` (all ``v`` or all ``f`` lines), which must not
    interleave with the lines ``theirs``; None when they do (or there are none)."""
    lines = np.flatnonzero(mine)
    if lines.size == 0:
        return None
    lo, hi = int(lines[0]), int(lines[-1])
    if theirs[lo:hi + 1].any():
        return None  # interleaved v and f blocks (several objects): trimesh's reader
    if lines.size == hi - lo + 1 or not np.any(tokens[lo:hi + 1][~mine[lo:hi + 1]]):
        return data[starts[lo] + 1:ends[hi]]  # one block (blank lines inside parse as nothing)
    return b"\n".join(data[starts[i] + 1:ends[i]] for i in lines.tolist())


def obj_vertex_bounds(data: bytes) -> Optional[np.ndarray]:
    """(2, 3) float64 min and max of every ``v`` record of an OBJ file, or None when it has none.

    binvox fits its grid to these, vertices that no face uses included (ShapeNet
    files hold polyline-only vertices), where the loaded mesh keeps the
    referenced ones only.
    """
    rows = [line.split()[1:4] for line in data.splitlines() if line.startswith(b"v ") or line.startswith(b"v\t")]
    if not rows:
        return None
    try:
        v = np.array([[float(x) for x in r] for r in rows if len(r) == 3], dtype=np.float64)
    except ValueError:
        return None
    if v.size == 0 or not np.all(np.isfinite(v)):
        return None
    return np.stack([v.min(axis=0), v.max(axis=0)])
