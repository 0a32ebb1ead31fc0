"""Tiny hand-made meshes with the defects of dataset meshes, and their known traits.

Cubes of lattice-aligned corners (so their solids are known exactly: the
voxels whose centers lie inside), each broken the way ShapeNet-style models
are: every face twice with opposite winding, one face flipped, a part inside
out, a face missing.  Used by the traits, inspect, warning and per-method
tests (numpy only).

>>> v, f = cube()
>>> v.shape, f.shape
((8, 3), (12, 3))
"""

from __future__ import annotations

import numpy as np

__all__ = ["write_obj", "cube", "double_sided_cube", "flipped_face_cube", "two_cubes_one_inside_out", "open_box",
           "DEFECTS", "cube_solid"]

# the 12 triangles of the unit cube, outward (counter-clockwise seen from outside)
_FACES = np.array([[0, 2, 1], [0, 3, 2],      # z = 0 (normal -z)
                   [4, 5, 6], [4, 6, 7],      # z = 1
                   [0, 1, 5], [0, 5, 4],      # y = 0
                   [2, 3, 7], [2, 7, 6],      # y = 1
                   [1, 2, 6], [1, 6, 5],      # x = 1
                   [0, 4, 7], [0, 7, 3]])     # x = 0
_CORNERS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                     [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=np.float64)


def cube(lo=(0.0, 0.0, 0.0), size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(8, 3) float64 vertices and (12, 3) int64 outward faces of an axis-aligned cube."""
    return _CORNERS * size + np.asarray(lo, dtype=np.float64), _FACES.copy()


def double_sided_cube(**kw):
    """The cube with every face twice, the copy reversed (ShapeNet's double-sided faces): 24 faces."""
    v, f = cube(**kw)
    return v, np.vstack([f, f[:, ::-1]])


def flipped_face_cube(**kw):
    """The cube with its x = 1 side (two triangles) wound inward: closed, inconsistently oriented."""
    v, f = cube(**kw)
    f[8:10] = f[8:10, ::-1]
    return v, f


def two_cubes_one_inside_out():
    """Two disjoint unit cubes, the second one wound inward: signed volumes cancel."""
    v1, f1 = cube((0.0, 0.0, 0.0))
    v2, f2 = cube((2.0, 0.0, 0.0))
    return np.vstack([v1, v2]), np.vstack([f1, f2[:, ::-1] + 8])


def open_box(**kw):
    """The cube without its top (z = 1) side: 10 faces, 4 boundary edges."""
    v, f = cube(**kw)
    return v, np.delete(f, [2, 3], axis=0)


def write_obj(path, mesh: tuple[np.ndarray, np.ndarray]):
    """Write ``(vertices, faces)`` as a Wavefront OBJ file, faces as given (no merging); returns ``path``."""
    v, f = mesh
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(v, dtype=np.float64).tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in np.asarray(f).tolist()]
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    return path


#: name -> (builder, known traits as a dict of MeshTraits fields)
DEFECTS = {
    "cube": (cube, dict(triangles=12, opposite_pairs=0, opposite_share=0.0, duplicate_share=0.0, parts=1,
                        inconsistent_parts=0, inverted_parts=0, open_edges=0, signed_volume_ratio=1.0,
                        part_volume_ratio=1.0, watertight=True)),
    "double_sided_cube": (double_sided_cube, dict(triangles=24, opposite_pairs=12, opposite_share=1.0,
                                                  duplicate_share=0.0, parts=1, inconsistent_parts=0,
                                                  inverted_parts=0, open_edges=0, signed_volume_ratio=0.0,
                                                  watertight=False)),
    "flipped_face_cube": (flipped_face_cube, dict(triangles=12, opposite_pairs=0, opposite_share=0.0,
                                                  duplicate_share=0.0, parts=1, inconsistent_parts=1,
                                                  inverted_parts=0, open_edges=0, watertight=True)),
    "two_cubes_one_inside_out": (two_cubes_one_inside_out,
                                 dict(triangles=24, opposite_pairs=0, opposite_share=0.0, duplicate_share=0.0,
                                      parts=2, inconsistent_parts=0, inverted_parts=1, open_edges=0,
                                      signed_volume_ratio=0.0, part_volume_ratio=2 / 3, watertight=True)),
    "open_box": (open_box, dict(triangles=10, opposite_pairs=0, opposite_share=0.0, duplicate_share=0.0, parts=1,
                                inconsistent_parts=0, inverted_parts=0, open_edges=4, watertight=False)),
}


def cube_solid(spec, boxes=((0.0, 0.0, 0.0),), size: float = 1.0) -> np.ndarray:
    """(nx, ny, nz) bool: voxels of ``spec`` whose centers lie strictly inside the given cubes.

    ``spec`` is a :class:`~glvox.grid.GridSpec`; choose one whose voxel
    centers keep off the cube's faces (the known solid has no ties).
    """
    centers = [spec.origin[a] + (np.arange(spec.dims[a]) + 0.5) * spec.voxel_size for a in range(3)]
    out = np.zeros(spec.dims, dtype=bool)
    for lo in boxes:
        ins = [(c > lo[a]) & (c < lo[a] + size) for a, c in enumerate(centers)]
        out |= ins[0][:, None, None] & ins[1][None, :, None] & ins[2][None, None, :]
    return out
