"""Mesh input: load, validate, and hand triangles to the methods.

Accepted inputs: a path to anything trimesh loads, a ``trimesh.Trimesh``, or a
``(vertices, faces)`` pair of arrays.  Validation refuses, with a specific
exception and message: missing or unreadable files, meshes without
triangles, NaN or infinite vertices, face indices out of range.  Zero-area
triangles are dropped and counted (``Mesh.n_degenerate``); whether the mesh is
closed is reported (``Mesh.watertight``) and solid methods refuse open meshes
unless asked to go ahead (see :func:`glvox.voxelize`).
"""

from __future__ import annotations

import io
import os
import re
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, Sequence, Union

import numpy as np

from .errors import EmptyMeshError, FaceIndexError, LimitError, MeshError, MeshLoadError, NonFiniteVertexError
from .meshfiles import FAST_SUFFIXES, obj_vertex_bounds, read_fast
from .tolerances import DEGENERATE_AREA_RTOL, MERGE_DIGITS, SNAP_EPS

#: The largest float32, the type of vertices on the GPU.
FLOAT32_MAX = float(np.finfo(np.float32).max)

MeshLike = Union[str, os.PathLike, "Mesh", Any, tuple]


@dataclass(eq=False)
class Mesh:
    """A validated triangle mesh, float64 world coordinates.

    Attributes
    ----------
    vertices : (V, 3) float64
        World coordinates.
    faces : (F, 3) int64
        Vertex indices of the non-degenerate triangles.
    n_degenerate : int
        Zero-area triangles dropped from the input.
    watertight : bool
        Every edge shared by exactly two triangles (after merging duplicate
        vertex positions), as trimesh judges it: decided on first read (by a
        solid method, the batch manifest, ``inspect``...), once, so loading a
        mesh for a surface does not pay for it.
    name : str
        File name or a short description.
    source_faces : (F,) int64 or None
        Index of each kept face in the input's faces; None when none was dropped.
    visuals : glvox.visuals.Visuals or None
        Colours, textures, normals and parts per kept face, loaded only when
        attributes are asked for (:func:`glvox.visuals.load_visual_mesh`).
    """

    vertices: np.ndarray
    faces: np.ndarray
    n_degenerate: int = 0
    name: str = "<arrays>"
    source_faces: np.ndarray | None = None
    visuals: Any = None

    @property
    def n_triangles(self) -> int:
        return int(len(self.faces))

    @cached_property
    def watertight(self) -> bool:
        """Every edge shared by exactly two triangles (:func:`is_watertight`; computed once)."""
        return is_watertight(self.vertices, self.faces)

    @cached_property
    def bounds(self) -> np.ndarray:
        """(2, 3) float64 min and max corner of the referenced vertices (computed once, read-only)."""
        if len(self.faces):
            used = np.zeros(len(self.vertices), dtype=bool)
            used[self.faces.ravel()] = True  # O(V + F), where np.unique sorts the faces
            v = self.vertices[used]
        else:
            v = self.vertices
        b = np.stack([v.min(axis=0), v.max(axis=0)])
        b.setflags(write=False)
        return b

    @cached_property
    def anchor(self) -> np.ndarray:
        """(3,) float64 bounding-box center (computed once, read-only).

        GPU methods upload vertices relative to it, so float32 keeps its
        precision for models far from the world origin (1e6 offsets).
        """
        b = self.bounds
        a = 0.5 * (b[0] + b[1])
        a.setflags(write=False)
        return a

    def triangles(self) -> np.ndarray:
        """(F, 3, 3) float64 world coordinates of the triangles' vertices."""
        return self.vertices[self.faces]

    def triangles_voxel(self, spec, eps: float = SNAP_EPS) -> np.ndarray:
        """(F, 3, 3) float64 triangles in the voxel space of ``spec``, snapped to
        the lattice as every method sees them (:meth:`GridSpec.vertices_to_voxel`;
        ``eps``: the snap distance, voxels of ``spec``)."""
        return spec.vertices_to_voxel(self.triangles(), eps)

    def gpu_arrays(self, anchor: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(V, 3) float32 vertices relative to :attr:`anchor` (pass it when
        already computed), (F, 3) uint32 faces."""
        if anchor is None:
            anchor = self.anchor
        rel = self.vertices - anchor
        reach = float(np.abs(rel).max())
        if not reach < FLOAT32_MAX:  # a silent inf would give a wrong grid
            raise LimitError(f"{self.name}: coordinates reach {reach:.3g} from the mesh's center, beyond the "
                             f"float32 range of GPU vertices ({FLOAT32_MAX:.3g}); scale the mesh down or use a "
                             f"reference-* method (float64)")
        return rel.astype(np.float32), self.faces.astype(np.uint32)

    def __repr__(self) -> str:
        return (f"Mesh({self.name!r}, triangles={self.n_triangles}, "
                f"degenerate_dropped={self.n_degenerate}, watertight={self.watertight})")


def _load_file(path: Path):
    if not path.exists():
        raise MeshLoadError(f"mesh file not found: {path}")
    if path.is_dir():
        raise MeshLoadError(f"mesh path is a directory, not a file: {path}")
    if path.stat().st_size == 0:
        raise EmptyMeshError(f"mesh file is empty (0 bytes): {path}")
    suffix = path.suffix.lower().lstrip(".")
    if suffix == "stl":
        _check_binary_stl(path)
    fast = read_fast(suffix, path.read_bytes()) if suffix in FAST_SUFFIXES else None
    if fast is not None:
        return fast
    # trimesh is imported where it is used (here and below): it takes ~0.5 s to
    # import, which the fast readers and commands that load no file do not pay
    import trimesh

    try:
        # materials and textures are irrelevant to voxels (and would need Pillow)
        try:
            loaded = trimesh.load(str(path), process=False, skip_materials=True)
        except ImportError:
            # trimesh guesses the encoding of a text file that is not UTF-8 with
            # an optional package (chardet); without it, decode here, replacing
            # bad bytes, so the result does not depend on what else is installed
            text = path.read_bytes().decode("utf-8", errors="replace").encode("utf-8")
            loaded = trimesh.load(io.BytesIO(text), file_type=path.suffix.lstrip(".").lower(),
                                  process=False, skip_materials=True)
    except Exception as exc:  # noqa: BLE001 - trimesh raises many types; one clear error
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        out_of_range = re.match(r"index -?\d+ is out of bounds for axis 0 with size (\d+)", msg)
        if isinstance(exc, IndexError) and out_of_range:  # numpy's words for a face index past the vertices
            raise FaceIndexError(f"could not read mesh file {path}: a face refers to a vertex the file does not "
                                 f"have (it has {out_of_range.group(1)} vertices)") from None
        raise MeshLoadError(f"could not read mesh file {path}: {msg}") from None
    if isinstance(loaded, trimesh.Scene):
        return _scene_triangles(loaded, path)
    if not hasattr(loaded, "faces") or not hasattr(loaded, "vertices"):
        raise MeshLoadError(f"{path} holds no triangle mesh (got {type(loaded).__name__})")
    return loaded.vertices, loaded.faces


def _check_binary_stl(path: Path) -> None:
    """A binary STL whose size disagrees with its triangle count is truncated (or
    padded): one clear error, whatever the trimesh version makes of it (some read
    no triangles, some raise)."""
    size = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(84)
    if head[:5].lower() == b"solid" and b"\0" not in head[5:80]:
        return  # ASCII STL
    if len(head) < 84:
        raise MeshLoadError(f"binary STL is truncated: {path} has {size} bytes, less than its 84-byte header")
    count = int.from_bytes(head[80:84], "little")
    expected = 84 + 50 * count
    if size < expected:
        raise MeshLoadError(f"binary STL is truncated: {path} declares {count} triangles ({expected} bytes) "
                            f"but has {size} bytes")


def _scene_triangles(scene, path: Path):
    """Vertices and faces of every mesh in a scene, placed by the scene graph.

    Done here rather than by trimesh's scene concatenation, which copies the
    visuals (and needs Pillow for textured files) only to throw them away.
    """
    import trimesh

    verts, faces, offset = [], [], 0
    for node in scene.graph.nodes_geometry:
        transform, name = scene.graph[node]
        geom = scene.geometry.get(name)
        if geom is None or not hasattr(geom, "faces") or len(geom.faces) == 0:
            continue
        verts.append(trimesh.transform_points(np.asarray(geom.vertices, dtype=np.float64), transform))
        faces.append(np.asarray(geom.faces, dtype=np.int64) + offset)
        offset += len(geom.vertices)
    if not faces:
        raise EmptyMeshError(f"{path} holds no triangles")
    return np.concatenate(verts), np.concatenate(faces)


def binvox_bounds(source: Any, mesh: Mesh) -> np.ndarray:
    """The bounding box binvox fits its grid to: of every ``v`` record when ``source``
    is an OBJ file (:func:`glvox.meshfiles.obj_vertex_bounds`), else ``mesh.bounds``.

    Returns
    -------
    (2, 3) float64
        World units.
    """
    if isinstance(source, (str, os.PathLike)) and str(source).lower().endswith(".obj") and Path(source).is_file():
        b = obj_vertex_bounds(Path(source).read_bytes())
        if b is not None:
            return b
    return np.array(mesh.bounds)


def load_mesh(mesh: MeshLike, *, name: str | None = None) -> Mesh:
    """Load and validate a mesh.

    Parameters
    ----------
    mesh : str, PathLike, trimesh.Trimesh, (vertices, faces) or Mesh
        A file trimesh can load, ``"gen:NAME"`` for a generated mesh (see
        :func:`generated_mesh`), a trimesh mesh, or arrays: vertices (V, 3)
        float and faces (F, 3) int.  A :class:`Mesh` is returned as is.

    Returns
    -------
    Mesh

    Raises
    ------
    MeshLoadError, EmptyMeshError, NonFiniteVertexError, FaceIndexError
    """
    if isinstance(mesh, Mesh):
        return mesh
    if isinstance(mesh, str) and mesh.startswith("gen:"):
        return generated_mesh(mesh[4:])
    if isinstance(mesh, (str, os.PathLike)):
        path = Path(mesh)
        vertices, faces = _load_file(path)
        label = path.name
    elif isinstance(mesh, tuple) and len(mesh) == 2:
        vertices, faces, label = mesh[0], mesh[1], "<arrays>"
    elif hasattr(mesh, "vertices") and hasattr(mesh, "faces"):
        vertices, faces, label = mesh.vertices, mesh.faces, type(mesh).__name__
    else:
        raise MeshError(
            "mesh must be a file path, a trimesh.Trimesh or a (vertices, faces) pair, "
            f"got {type(mesh).__name__}"
        )
    return _validate(vertices, faces, name or label)


def _validate(vertices: Any, faces: Any, name: str) -> Mesh:
    try:
        v = np.asarray(vertices, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise MeshError(f"{name}: vertices must be numbers, shape (V, 3): {exc}") from None
    if v.ndim != 2 or v.shape[1] != 3:
        raise MeshError(f"{name}: vertices must have shape (V, 3), got {v.shape}")
    f = np.asarray(faces)
    if f.size == 0:
        raise EmptyMeshError(f"{name}: the mesh has no triangles")
    if f.ndim != 2 or f.shape[1] != 3:
        raise FaceIndexError(f"{name}: faces must have shape (F, 3) (triangles), got {f.shape}")
    if not np.issubdtype(f.dtype, np.integer):
        if not np.all(np.isfinite(f)) or np.any(f != np.round(f)):
            raise FaceIndexError(f"{name}: face indices must be integers, got dtype {f.dtype}")
    f = f.astype(np.int64, copy=False)
    if len(v) == 0:
        raise EmptyMeshError(f"{name}: the mesh has no vertices")
    if f.min() < 0 or f.max() >= len(v):
        bad = (f < 0) | (f >= len(v))
        first = int(np.argwhere(bad.any(axis=1))[0, 0])
        raise FaceIndexError(
            f"{name}: {int(bad.any(axis=1).sum())} faces index vertices outside [0, {len(v) - 1}] "
            f"(first: face {first} = {f[first].tolist()})"
        )
    used = np.zeros(len(v), dtype=bool)
    used[f] = True  # O(V + F), where np.unique sorts the faces
    bad_v = used & ~np.isfinite(v).all(axis=1)
    if bad_v.any():
        idx = np.flatnonzero(bad_v)
        raise NonFiniteVertexError(
            f"{name}: {len(idx)} vertices have NaN or infinite coordinates (first: vertex {int(idx[0])} "
            f"= {v[idx[0]].tolist()})"
        )
    cols = [np.ascontiguousarray(c) for c in v.T]  # x, y, z: contiguous gathers below
    referenced = cols if used.all() else [c[used] for c in cols]
    lo = np.array([c.min() for c in referenced])
    hi = np.array([c.max() for c in referenced])
    with np.errstate(over="ignore"):
        span = hi - lo
    if not np.all(np.isfinite(span)):
        raise NonFiniteVertexError(
            f"{name}: the coordinates span more than a float64 holds (from {lo.tolist()} to {hi.tolist()}); "
            f"scale the mesh down"
        )
    extent = float(span.max())
    # areas relative to the extent squared, computed on coordinates scaled by
    # the extent: the same test, without overflow for coordinates near 1e308
    scale = extent if extent > 0 else 1.0
    doubled_area = _doubled_areas([c / scale for c in cols], f)
    degenerate = doubled_area <= DEGENERATE_AREA_RTOL
    keep = f[~degenerate] if degenerate.any() else f
    if len(keep) == 0:
        raise EmptyMeshError(f"{name}: all {len(f)} triangles have zero area")
    return Mesh(vertices=v, faces=keep, n_degenerate=int(degenerate.sum()), name=name,
                source_faces=np.flatnonzero(~degenerate) if degenerate.any() else None)


def _doubled_areas(cols: Sequence[np.ndarray], f: np.ndarray) -> np.ndarray:
    """(F,) float64 |(b - a) x (c - a)| per triangle, from the (V,) x, y, z columns of the vertices.

    The operations of ``np.linalg.norm(np.cross(...), axis=1)`` in the same
    order (so the same bits), on contiguous (F,) coordinate columns instead
    of (F, 3, 3) gathers and strided temporaries: ~6x faster.
    """
    vx, vy, vz = cols
    f0, f1, f2 = (np.ascontiguousarray(c) for c in f.T)
    ax, ay, az = vx[f0], vy[f0], vz[f0]
    e1x, e1y, e1z = vx[f1] - ax, vy[f1] - ay, vz[f1] - az
    e2x, e2y, e2z = vx[f2] - ax, vy[f2] - ay, vz[f2] - az
    x = e1y * e2z - e1z * e2y
    y = e1z * e2x - e1x * e2z
    z = e1x * e2y - e1y * e2x
    return np.sqrt(x * x + y * y + z * z)


def is_watertight(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """Every edge shared by exactly two triangles after merging duplicate positions.

    The same answer as trimesh's ``Trimesh(vertices, faces, process=True).is_watertight``
    (``tests/test_mesh.py`` compares them on every shared mesh and on broken
    ones), in numpy: positions are merged as trimesh merges them (equal after
    rounding to :data:`~glvox.tolerances.MERGE_DIGITS` decimals, referenced
    vertices only), then each undirected edge must occur exactly twice.

    Parameters
    ----------
    vertices : (V, 3) float64
        World coordinates.
    faces : (F, 3) int64
        Indices into ``vertices``.
    """
    used = np.zeros(len(vertices), dtype=bool)
    used[faces] = True
    idx = np.flatnonzero(used)
    # coordinates beyond ~9e10 overflow int64 here (as in trimesh's own merge,
    # whose answer this reproduces); they are far from any shared edge anyway
    with np.errstate(over="ignore", invalid="ignore"):
        keys = (vertices[idx] * 10**MERGE_DIGITS).round().astype(np.int64)
    labels = _row_labels(keys)
    remap = np.zeros(len(vertices), dtype=np.int64)
    remap[idx] = labels
    f = remap[faces]
    a, b = f.ravel(), f[:, [1, 2, 0]].ravel()
    edges = np.minimum(a, b) * (int(labels.max()) + 1) + np.maximum(a, b)
    edges.sort()
    # sorted, every key exactly twice <=> pairs equal and no pair equal to the next one
    return bool(len(edges) % 2 == 0 and np.array_equal(edges[0::2], edges[1::2])
                and not np.any(edges[1:-1:2] == edges[2::2]))


def _row_labels(keys: np.ndarray) -> np.ndarray:
    """(n,) int64 labels of the (n, 3) int64 rows ``keys``, equal exactly for equal rows.

    Rows are sorted by a 64-bit hash (one simd sort, ~10x faster than
    ``np.lexsort`` over three columns), then checked against the first row
    of their hash group; a hash collision between different rows (never seen)
    falls back to the lexicographic sort.
    """
    u = keys.view(np.uint64)
    with np.errstate(over="ignore"):
        h = (u[:, 0] * np.uint64(0x9E3779B97F4A7C15)) ^ (u[:, 1] * np.uint64(0xC2B2AE3D27D4EB4F)) ^ u[:, 2]
    order = np.argsort(h)
    hs, ks = h[order], keys[order]
    new = np.empty(len(ks), dtype=bool)
    new[:1] = True
    np.not_equal(hs[1:], hs[:-1], out=new[1:])
    first = np.flatnonzero(new)
    group = np.cumsum(new) - 1
    if not np.array_equal(ks, ks[first[group]]):
        order = np.lexsort(keys.T)
        ks = keys[order]
        np.any(ks[1:] != ks[:-1], axis=1, out=new[1:])
        group = np.cumsum(new) - 1
    labels = np.empty(len(ks), dtype=np.int64)
    labels[order] = group
    return labels


#: Generated meshes with the defects of dataset meshes (ShapeNet and its kin), each made
#: from a clean closed one, its *clean twin*, whose solid is the defective mesh's true one:
#: ``double-sided-*`` holds every face twice, the copy reversed (signed volume 0: winding
#: numbers and parities cancel); ``flipped-half-*`` has the faces of its x > 0 half wound
#: inward (closed, inconsistently oriented).
DEFECTIVE = {"double-sided-torus": ("torus", "double-sided"),
             "double-sided-bunny-like": ("bunny-like", "double-sided"),
             "flipped-half-sphere": ("sphere", "flipped-half")}

#: Meshes that need no file, for the README's first command and quick tries:
#: ``gen:NAME`` wherever a mesh path is accepted.
GENERATED = ("torus", "sphere", "box", "bunny-like") + tuple(DEFECTIVE)


def clean_twin(name: str) -> str | None:
    """The clean closed mesh a defective generated mesh was made from (``'gen:torus'`` for
    ``'gen:double-sided-torus'``): its solid is the defective one's true solid.  None otherwise."""
    base = DEFECTIVE.get(name[4:]) if name.startswith("gen:") else None
    return f"gen:{base[0]}" if base else None


def generated_mesh(name: str) -> Mesh:
    """A mesh made by trimesh: ``torus``, ``sphere``, ``box`` or ``bunny-like`` (closed), or
    one of :data:`DEFECTIVE` (a clean one broken as dataset meshes are).

    ``bunny-like`` is a union-free blob (a subdivided, displaced icosphere)
    with concave parts, for methods that are wrong on concavities.
    """
    import trimesh

    if name in DEFECTIVE:
        base, defect = DEFECTIVE[name]
        clean = generated_mesh(base)
        v, f = clean.vertices, clean.faces
        if defect == "double-sided":
            f = np.vstack([f, f[:, ::-1]])
        else:  # flipped-half
            f = f.copy()
            half = v[f].mean(axis=1)[:, 0] > 0
            f[half] = f[half, ::-1]
        return _validate(v, f, f"gen:{name}")

    if name == "torus":
        m = trimesh.creation.torus(major_radius=1.0, minor_radius=0.35, major_sections=96,
                                   minor_sections=48)
    elif name == "sphere":
        m = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    elif name == "box":
        m = trimesh.creation.box(extents=(2.0, 1.2, 0.8))
    elif name == "bunny-like":
        m = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
        v = m.vertices
        bump = 1.0 + 0.35 * np.sin(3 * v[:, 0]) * np.cos(2 * v[:, 1]) + 0.2 * np.sin(4 * v[:, 2])
        m = trimesh.Trimesh(v * bump[:, None], m.faces, process=False)
    else:
        raise MeshLoadError(f"unknown generated mesh 'gen:{name}'; available: "
                            + ", ".join(f"gen:{g}" for g in GENERATED))
    return _validate(m.vertices, m.faces, f"gen:{name}")
