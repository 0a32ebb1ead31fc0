"""What a mesh carries beside its geometry: colours, textures, normals, parts.

Loaded only when attributes are asked for (:func:`load_visual_mesh`); the
plain loading path of :mod:`glvox.mesh` skips materials and stays fast.
Everything is kept per face and corner of the *kept* faces of the
:class:`~glvox.mesh.Mesh` (degenerate ones dropped), so an attribute pass
indexes it by the same triangle index as the geometry:

* colour source per face (:data:`COLOR_NONE`, :data:`COLOR_FACE`,
  :data:`COLOR_VERTEX`, :data:`COLOR_TEXTURE`), as trimesh loads the part:
  face colours, vertex colours (interpolated barycentrically) or a
  base-colour texture through UVs;
* per-corner UVs, colours and vertex normals, per-face colours and part
  (material) index;
* textures: RGBA8 images (alpha kept; RGB files get alpha 255) with the
  filter and wrap to sample them with (bilinear and repeat unless the file
  says otherwise: trimesh keeps no sampler, so always the default here).

A scene with several geometries keeps each part's own visuals; a part's
material index is its position among the scene's geometry nodes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import MeshError, MeshLoadError
from .mesh import Mesh, load_mesh

COLOR_NONE, COLOR_FACE, COLOR_VERTEX, COLOR_TEXTURE = 0, 1, 2, 3


@dataclass(eq=False)
class Texture:
    """A base-colour image to sample through UVs.

    Attributes
    ----------
    image : (H, W, 4) uint8
        RGBA, row 0 at the *top* of the picture (as image files store it);
        UV (0, 0) is its bottom-left corner (the OBJ / glTF-through-trimesh
        convention).
    factor : (4,) float64
        Multiplied with the sample (a glTF baseColorFactor; ones otherwise).
    filter : {'linear', 'nearest'}
    wrap : {'repeat', 'clamp'}
    """

    image: np.ndarray
    factor: np.ndarray = field(default_factory=lambda: np.ones(4))
    filter: str = "linear"
    wrap: str = "repeat"


@dataclass(eq=False)
class Visuals:
    """Per kept face of a mesh: where its colour comes from, and the data for it.

    Attributes
    ----------
    color_source : (F,) uint8
        COLOR_NONE / COLOR_FACE / COLOR_VERTEX / COLOR_TEXTURE.
    face_color : (F, 4) uint8
        RGBA of COLOR_FACE faces (zeros elsewhere).
    corner_color : (F, 3, 4) uint8
        RGBA at the three corners of COLOR_VERTEX faces.
    corner_uv : (F, 3, 2) float64
        UVs of COLOR_TEXTURE faces.
    texture : (F,) int32
        Index into ``textures`` of COLOR_TEXTURE faces, -1 elsewhere.
    corner_normal : (F, 3, 3) float64
        Unit vertex normals (world) at the corners: the file's where it has
        them, trimesh's area-weighted ones otherwise.
    material : (F,) int32
        Part / material index.
    textures : list of Texture
    """

    color_source: np.ndarray
    face_color: np.ndarray
    corner_color: np.ndarray
    corner_uv: np.ndarray
    texture: np.ndarray
    corner_normal: np.ndarray
    material: np.ndarray
    textures: list[Texture]

    @property
    def has_color(self) -> bool:
        return bool(np.any(self.color_source != COLOR_NONE))

    def take(self, rows: np.ndarray) -> "Visuals":
        """The visuals of faces ``rows`` (e.g. the kept ones)."""
        return Visuals(self.color_source[rows], self.face_color[rows], self.corner_color[rows],
                       self.corner_uv[rows], self.texture[rows], self.corner_normal[rows],
                       self.material[rows], self.textures)


def _rgba(image) -> np.ndarray:
    """A PIL image as (H, W, 4) uint8 RGBA (alpha 255 where the file has none)."""
    return np.ascontiguousarray(np.asarray(image.convert("RGBA"), dtype=np.uint8))


def _part(geom, transform: np.ndarray, part: int, textures: list[Texture]) -> tuple[np.ndarray, ...]:
    """Vertices (world), faces and the per-face visual arrays of one trimesh geometry."""
    import trimesh  # lazy: heavy, only on this path

    faces = np.asarray(geom.faces, dtype=np.int64)
    verts = trimesh.transform_points(np.asarray(geom.vertices, dtype=np.float64), transform)
    f = len(faces)
    source = np.zeros(f, np.uint8)
    face_color = np.zeros((f, 4), np.uint8)
    corner_color = np.zeros((f, 3, 4), np.uint8)
    corner_uv = np.zeros((f, 3, 2), np.float64)
    tex = np.full(f, -1, np.int32)
    visual = getattr(geom, "visual", None)
    kind = getattr(visual, "kind", None)
    if kind == "texture":
        mat = visual.material
        image = getattr(mat, "baseColorTexture", None) or getattr(mat, "image", None)
        factor = getattr(mat, "baseColorFactor", None)
        factor = np.ones(4) if factor is None else np.asarray(factor, dtype=np.float64) / 255.0
        if image is not None and visual.uv is not None and len(visual.uv) == len(geom.vertices):
            textures.append(Texture(_rgba(image), factor))
            source[:] = COLOR_TEXTURE
            tex[:] = len(textures) - 1
            corner_uv = np.asarray(visual.uv, dtype=np.float64)[faces]
        else:  # a material without a usable image: its main colour on every face
            source[:] = COLOR_FACE
            face_color[:] = np.asarray(mat.main_color, dtype=np.uint8)
    elif kind == "vertex":
        source[:] = COLOR_VERTEX
        corner_color = np.asarray(visual.vertex_colors, dtype=np.uint8)[faces]
    elif kind == "face":
        source[:] = COLOR_FACE
        face_color = np.asarray(visual.face_colors, dtype=np.uint8).copy()
    # normals: rotate with the node's transform (inverse transpose), unit length
    vn = np.asarray(geom.vertex_normals, dtype=np.float64)
    lin = np.linalg.inv(transform[:3, :3]).T
    vn = vn @ lin.T
    vn /= np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-300)
    return (verts, faces, source, face_color, corner_color, corner_uv, tex, vn[faces],
            np.full(f, part, np.int32))


def visuals_from_trimesh(loaded) -> tuple[np.ndarray, np.ndarray, Visuals]:
    """World vertices (V, 3), faces (F, 3) and :class:`Visuals` of a trimesh Trimesh or Scene.

    A scene's geometries are placed by its graph and concatenated in node
    order; each is one part (its material index).
    """
    import trimesh  # lazy: heavy, only on this path

    if isinstance(loaded, trimesh.Scene):
        items = []
        for node in loaded.graph.nodes_geometry:
            transform, name = loaded.graph[node]
            geom = loaded.geometry.get(name)
            if geom is not None and hasattr(geom, "faces") and len(geom.faces):
                items.append((geom, np.asarray(transform, dtype=np.float64)))
    elif hasattr(loaded, "faces") and hasattr(loaded, "vertices"):
        items = [(loaded, np.eye(4))]
    else:
        raise MeshError(f"no triangle mesh in {type(loaded).__name__}")
    if not items:
        raise MeshError("the scene holds no triangles")
    textures: list[Texture] = []
    parts = [_part(g, t, n, textures) for n, (g, t) in enumerate(items)]
    offsets = np.cumsum([0] + [len(p[0]) for p in parts[:-1]])
    verts = np.concatenate([p[0] for p in parts])
    faces = np.concatenate([p[1] + o for p, o in zip(parts, offsets)])
    cols = [np.concatenate([p[i] for p in parts]) for i in range(2, 9)]
    return verts, faces, Visuals(*cols[:6], cols[6], textures)


def load_visual_mesh(mesh: Any, *, name: str | None = None):
    """A :class:`~glvox.mesh.Mesh` with its :class:`Visuals` (``mesh.visuals``).

    Parameters
    ----------
    mesh : path, trimesh.Trimesh or trimesh.Scene, or Mesh
        A file is loaded by trimesh with its materials (textures need
        Pillow: ``pip install 'glvox[attributes]'``); a Mesh is returned as is.

    Raises
    ------
    MeshLoadError
        The file cannot be read; it has a texture and Pillow is missing.
    """
    if isinstance(mesh, Mesh):  # as is: run_method names what its missing visuals cannot give
        return mesh
    if isinstance(mesh, (str, Path)) and str(mesh).startswith("gen:"):
        m = load_mesh(mesh)
        return _attach(m, None)
    import trimesh  # lazy: heavy, only on this path

    if isinstance(mesh, (str, Path)):
        path = Path(mesh)
        if not path.is_file():
            raise MeshLoadError(f"mesh file not found: {path}")
        try:
            loaded = trimesh.load(str(path), process=False)
        except Exception as exc:  # noqa: BLE001 - trimesh raises many types; one clear error
            raise MeshLoadError(f"could not read mesh file {path} with its materials: "
                                f"{str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__}"
                                ) from None
        label = path.name
    else:
        loaded, label = mesh, type(mesh).__name__
    _check_pillow(loaded, label)
    try:
        verts, faces, vis = visuals_from_trimesh(loaded)
    except MeshError as exc:
        raise MeshLoadError(f"{label}: {exc}") from None
    m = load_mesh((verts, faces), name=name or label)
    return _attach(m, vis)


def _check_pillow(loaded, label: str) -> None:
    """MeshLoadError when a part has texture UVs but trimesh could not read the image
    because Pillow is missing (it would silently lose the texture)."""
    try:
        import PIL  # noqa: F401 - only whether it is there
        return
    except ImportError:
        pass
    geoms = loaded.geometry.values() if hasattr(loaded, "geometry") else [loaded]
    if any(getattr(getattr(g, "visual", None), "kind", None) == "texture" for g in geoms):
        raise MeshLoadError(f"{label} has textures, and reading them needs Pillow: "
                            "pip install 'glvox[attributes]'")


def _attach(m, vis: Visuals | None):
    """``m`` with ``visuals`` set to ``vis`` restricted to its kept faces (none: no colour)."""
    f_in = len(m.faces) + m.n_degenerate
    if vis is None:
        vis = Visuals(np.zeros(f_in, np.uint8), np.zeros((f_in, 4), np.uint8), np.zeros((f_in, 3, 4), np.uint8),
                      np.zeros((f_in, 3, 2)), np.full(f_in, -1, np.int32), _corner_normals(m, f_in),
                      np.zeros(f_in, np.int32), [])
    m.visuals = vis if m.source_faces is None else vis.take(m.source_faces)
    return m


def _corner_normals(m, f_in: int) -> np.ndarray:
    """Area-weighted vertex normals of a generated mesh (no degenerate faces), per corner."""
    import trimesh  # lazy: heavy, only on this path

    tm = trimesh.Trimesh(m.vertices, m.faces, process=False)
    return np.asarray(tm.vertex_normals, dtype=np.float64)[m.faces]
