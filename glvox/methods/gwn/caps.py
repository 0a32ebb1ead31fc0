"""Caps over the boundary loops, so that most of an open mesh's voxels need
no field at all (``gwn-solid``'s cap bound).

Close every boundary loop ``w_0 .. w_{n-1}`` of a mesh ``M``
(:func:`.tree.boundary_loops`) with a fan ``K`` of triangles
``(w_{i+1}, w_i, a)`` around the loop's mean ``a``: each boundary edge
``w_i -> w_{i+1}`` then meets its reverse, and consecutive fan triangles share
``a -> w_i`` and its reverse, so ``M + K`` is closed.  Its winding number is
the signed crossing count ``C_{M+K} = C_M + C_K`` (an exact integer:
``gwn/events.comp`` counts the fans' crossings with the mesh's arithmetic, in
bit planes of their own), and winding numbers add over triangles:

    w_M(p) = C_M(p) + C_K(p) - w_K(p).

Where a bound of ``|w_K|`` over a brick stays below ``m``, the distance from
the threshold ``t`` to the nearest integer (less the tie tolerance), no voxel
of the brick has ``w_M`` on the other side of ``t`` from the integer
``C_{M+K}``: the brick is decided from the counts alone, without the tree
(``shaders/gwn/caps.glsl`` has the bound: the fans' areas over their squared
distances, or the solid angle at the brick's center plus a gradient bound).
A planar cap never subtends a half sphere, so on meshes with small, nearly
planar holes only the bricks close to a cap or to the boundary are left to
the field.

The fans are built once per mesh, in world coordinates, and appended to a
copy of it (:func:`capped_mesh`): the GPU transforms their apexes with the
mesh's vertices, so the crossings of ``M`` and ``K`` and the bound read the
same float32 voxel-space positions, and a boundary edge shared by a mesh
triangle and a fan triangle is counted once (ss/solid.glsl's fill rule).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from ...mesh import Mesh
from .tree import RADIUS_MARGIN, BoundaryLoops

#: vec4 records per loop in the Caps buffer: (apex, radius of the ball about
#: the apex that holds the fan), (the fan's area, the index of its first
#: triangle record, its triangle count, 0), voxel units (:func:`cap_records`).
CAP_VEC4 = 2


@dataclass
class CappedMesh:
    """A mesh with its boundary loops' fans appended.

    Attributes
    ----------
    mesh : Mesh
        ``vertices``: the original ones, then one apex per loop; ``faces``:
        the original ones (same order, so ``faces[:first]`` is the mesh), then
        the fans, loop by loop.
    first : int
        Index of the first fan triangle.
    loops : list of (n_i,) int64
        The loops (vertex indices), in the order of their fans.
    apexes : (L,) int64
        Vertex index of each loop's apex.
    """

    mesh: Mesh
    first: int
    loops: list
    apexes: np.ndarray

    @property
    def n_caps(self) -> int:
        return int(len(self.mesh.faces) - self.first)


_CAPPED: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def capped_mesh(mesh: Mesh, loops: BoundaryLoops) -> CappedMesh:
    """``mesh`` with a fan over each of its boundary loops appended (cached per mesh)."""
    hit = _CAPPED.get(mesh)
    if hit is not None:
        return hit
    nv, first = len(mesh.vertices), len(mesh.faces)
    apex = np.array([mesh.vertices[loop].mean(axis=0) for loop in loops.loops]).reshape(-1, 3)
    fans = [np.stack([np.roll(loop, -1), loop, np.full(len(loop), nv + i)], axis=1)
            for i, loop in enumerate(loops.loops)]
    faces = np.concatenate([mesh.faces] + fans).astype(mesh.faces.dtype) if fans else mesh.faces
    capped = Mesh(np.concatenate([mesh.vertices, apex]), faces, name=mesh.name + " (capped)")
    out = CappedMesh(capped, first, list(loops.loops), np.arange(nv, nv + len(apex), dtype=np.int64))
    _CAPPED[mesh] = out
    return out


def cap_records(capped: CappedMesh, vox64: np.ndarray) -> np.ndarray:
    """The Caps buffer (``shaders/gwn/caps.glsl``), (2 L + T, 4) float32.

    Per loop, :data:`CAP_VEC4` vec4: its apex and the radius of a ball about it
    that holds the fan; the fan's area, the index of its first triangle record
    and its triangle count (int32 bits).  Then per fan triangle its three vertex
    indices (uint32 bits), so the GPU reads the same voxel-space vertices as
    the crossings.  ``vox64``: the capped mesh's vertices in voxel space,
    float64.  Radius and area are rounded up: the GPU's float32 vertices
    (snapped within :data:`~glvox.tolerances.SNAP_EPS`) differ from ``vox64``
    by far less than :data:`~.tree.RADIUS_MARGIN`."""
    n_loops = len(capped.loops)
    rec = np.zeros((CAP_VEC4 * n_loops + capped.n_caps, 4), np.float32)
    bits = rec.view(np.int32)
    fans = capped.mesh.faces[capped.first:]
    bits[CAP_VEC4 * n_loops:, :3] = fans
    if not n_loops:
        return rec
    # every fan triangle (w_{i+1}, w_i, apex) at once, reduced per loop
    sizes = np.array([len(loop) for loop in capped.loops], np.int64)
    first = np.cumsum(sizes) - sizes
    a = vox64[fans[:, 2].astype(np.int64)]
    u, v = vox64[fans[:, 0].astype(np.int64)], vox64[fans[:, 1].astype(np.int64)]
    r = np.sqrt(np.maximum.reduceat(((v - a) ** 2).sum(axis=1), first)) + RADIUS_MARGIN
    area = np.add.reduceat(0.5 * np.sqrt((np.cross(v - u, a - u) ** 2).sum(axis=1)), first)
    head, head_bits = (x[:CAP_VEC4 * n_loops].reshape(n_loops, CAP_VEC4, 4) for x in (rec, bits))
    head[:, 0, :3] = vox64[capped.apexes]
    head[:, 0, 3] = r
    head[:, 1, 0] = area * 1.001 + 1e-3
    head_bits[:, 1, 1] = CAP_VEC4 * n_loops + first
    head_bits[:, 1, 2] = sizes
    return rec


def caps_ball(records: np.ndarray, n_loops: int) -> tuple[tuple[float, float, float, float], float]:
    """A ball holding every fan (center, radius) and the fans' total area, from
    :func:`cap_records` (rounded up as they are)."""
    balls = records[:CAP_VEC4 * n_loops:CAP_VEC4].astype(np.float64)
    lo, hi = (balls[:, :3] - balls[:, 3:]).min(axis=0), (balls[:, :3] + balls[:, 3:]).max(axis=0)
    c = 0.5 * (lo + hi)
    r = float((np.sqrt(((balls[:, :3] - c) ** 2).sum(axis=1)) + balls[:, 3]).max()) * 1.0001 + 1e-3
    area = float(records[1:CAP_VEC4 * n_loops:CAP_VEC4, 0].astype(np.float64).sum()) * 1.0001
    return (float(c[0]), float(c[1]), float(c[2]), r), area


@dataclass(frozen=True)
class RunCaps:
    """The caps of one ``gwn-solid`` run: their records on the GPU (``buf``,
    :func:`cap_records`), the loops, the bound's limit (turns), the fan
    triangles (``first``, ``count``) in the capped mesh, and a ball holding
    every fan with the fans' total area (:func:`caps_ball`)."""

    buf: object
    loops: int
    limit: float
    first: int
    count: int
    ball: tuple
    area: float

    @classmethod
    def of(cls, buf, capped: CappedMesh, records: np.ndarray, limit: float) -> "RunCaps":
        loops = len(capped.loops)
        return cls(buf, loops, limit, capped.first, capped.n_caps, *caps_ball(records, loops))

    def uniforms(self) -> dict:
        """The uniforms of ``shaders/gwn/caps.glsl``."""
        return {"u_loops": self.loops, "u_cap_limit": self.limit, "u_caps_ball": self.ball,
                "u_caps_area": self.area}


def cap_margin(threshold: float, tie: float) -> float:
    """The bound of ``|w_K|`` under which the counts decide a voxel: the distance
    from ``threshold`` to the nearest integer, less ``tie``; 0 or less when the
    caps cannot decide anything (an integer threshold)."""
    return float(min(threshold - np.floor(threshold), np.ceil(threshold) - threshold) - tie)
