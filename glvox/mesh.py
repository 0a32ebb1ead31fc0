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

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Union

import numpy as np

from .errors import EmptyMeshError, FaceIndexError, MeshError, MeshLoadError, NonFiniteVertexError
from .tolerances import DEGENERATE_AREA_RTOL

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
        vertex positions), as trimesh judges it.
    name : str
        File name or a short description.
    """

    vertices: np.ndarray
    faces: np.ndarray
    n_degenerate: int = 0
    watertight: bool = False
    name: str = "<arrays>"

    @property
    def n_triangles(self) -> int:
        return int(len(self.faces))

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float64 min and max corner of the referenced vertices."""
        if len(self.faces):
            used = np.zeros(len(self.vertices), dtype=bool)
            used[self.faces.ravel()] = True  # O(V + F), where np.unique sorts the faces
            v = self.vertices[used]
        else:
            v = self.vertices
        return np.stack([v.min(axis=0), v.max(axis=0)])

    @property
    def anchor(self) -> np.ndarray:
        """(3,) float64 bounding-box center.

        GPU methods upload vertices relative to it, so float32 keeps its
        precision for models far from the world origin (1e6 offsets).
        """
        b = self.bounds
        return 0.5 * (b[0] + b[1])

    def triangles(self) -> np.ndarray:
        """(F, 3, 3) float64 world coordinates of the triangles' vertices."""
        return self.vertices[self.faces]

    def triangles_voxel(self, spec) -> np.ndarray:
        """(F, 3, 3) float64 triangles in the voxel space of ``spec``, snapped to
        the lattice as every method sees them (:meth:`GridSpec.vertices_to_voxel`)."""
        return spec.vertices_to_voxel(self.triangles())

    def gpu_arrays(self, anchor: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(V, 3) float32 vertices relative to :attr:`anchor` (pass it when
        already computed), (F, 3) uint32 faces."""
        if anchor is None:
            anchor = self.anchor
        return ((self.vertices - anchor).astype(np.float32),
                self.faces.astype(np.uint32))

    def __repr__(self) -> str:
        return (f"Mesh({self.name!r}, triangles={self.n_triangles}, "
                f"degenerate_dropped={self.n_degenerate}, watertight={self.watertight})")


def _load_file(path: Path):
    import trimesh

    if not path.exists():
        raise MeshLoadError(f"mesh file not found: {path}")
    if path.is_dir():
        raise MeshLoadError(f"mesh path is a directory, not a file: {path}")
    if path.stat().st_size == 0:
        raise EmptyMeshError(f"mesh file is empty (0 bytes): {path}")
    if path.suffix.lower() == ".stl":
        _check_binary_stl(path)
    try:
        # materials and textures are irrelevant to voxels (and would need Pillow)
        try:
            loaded = trimesh.load(str(path), process=False, skip_materials=True)
        except ImportError:
            # trimesh guesses the encoding of a text file that is not UTF-8 with
            # an optional package (chardet); without it, decode here, replacing
            # bad bytes, so the result does not depend on what else is installed
            import io

            text = path.read_bytes().decode("utf-8", errors="replace").encode("utf-8")
            loaded = trimesh.load(io.BytesIO(text), file_type=path.suffix.lstrip(".").lower(),
                                  process=False, skip_materials=True)
    except Exception as exc:  # noqa: BLE001 - trimesh raises many types; one clear error
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
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
    f = f.astype(np.int64)
    if len(v) == 0:
        raise EmptyMeshError(f"{name}: the mesh has no vertices")
    bad = (f < 0) | (f >= len(v))
    if bad.any():
        first = int(np.argwhere(bad.any(axis=1))[0, 0])
        raise FaceIndexError(
            f"{name}: {int(bad.any(axis=1).sum())} faces index vertices outside [0, {len(v) - 1}] "
            f"(first: face {first} = {f[first].tolist()})"
        )
    used = np.unique(f)
    finite = np.all(np.isfinite(v[used]), axis=1)
    if not finite.all():
        idx = used[~finite]
        raise NonFiniteVertexError(
            f"{name}: {len(idx)} vertices have NaN or infinite coordinates (first: vertex {int(idx[0])} "
            f"= {v[idx[0]].tolist()})"
        )
    tri = v[f]
    doubled_area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    extent = float(np.ptp(v[used], axis=0).max())
    degenerate = doubled_area <= DEGENERATE_AREA_RTOL * extent * extent
    keep = f[~degenerate]
    if len(keep) == 0:
        raise EmptyMeshError(f"{name}: all {len(f)} triangles have zero area")
    return Mesh(vertices=v, faces=keep, n_degenerate=int(degenerate.sum()),
                watertight=_is_watertight(v, keep), name=name)


def _is_watertight(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """Every edge shared by exactly two triangles, as trimesh judges it (after merging positions)."""
    import trimesh

    m = trimesh.Trimesh(vertices=vertices, faces=faces, process=True, validate=False)
    return bool(m.is_watertight)


#: Meshes that need no file, for the README's first command and quick tries:
#: ``gen:NAME`` wherever a mesh path is accepted.
GENERATED = ("torus", "sphere", "box", "bunny-like")


def generated_mesh(name: str) -> Mesh:
    """A closed mesh made by trimesh: ``torus``, ``sphere``, ``box`` or ``bunny-like``.

    ``bunny-like`` is a union-free blob (a subdivided, displaced icosphere)
    with concave parts, for methods that are wrong on concavities.
    """
    import trimesh

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
