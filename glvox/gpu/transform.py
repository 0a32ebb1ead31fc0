"""The shared vertex transform of every GPU method (S&S Sec. 6).

``shaders/common/snap.glsl`` holds the one world -> voxel transform with the
plane snap (the GLSL side of :func:`glvox.grid.snap_to_planes`), used by
``shaders/common/transform.comp`` (:func:`transform_vertices`: the compute
methods) and by the raster and scanline shaders that transform vertices
themselves; :func:`gpu_vertices_voxel` repeats it in numpy, bit for bit.
"""

from __future__ import annotations

import numpy as np

from ..gl.shaders import compute_program
from ..grid import snap_to_planes
from ..tolerances import SNAP_EPS
from .buffers import mesh_buffers
from .dispatch import barrier, bind, dispatch_1d, set_uniforms

#: Defines of every program that includes ``common/snap.glsl`` (it refuses
#: to compile without them): the snap distance named once in glvox.tolerances.
SNAP_DEFINES = {"SNAP_EPS": float(SNAP_EPS)}


def snap_defines(eps: float = SNAP_EPS) -> dict:
    """:data:`SNAP_DEFINES` with another snap distance (binvox-solid's finer grid)."""
    return {"SNAP_EPS": float(eps)}
#: The ``(shader, defines)`` :func:`transform_vertices` compiles, for ``Requirements(compute=...)``.
SHADERS = (("common/transform.comp", {"VOX_DOUBLE": 0, **SNAP_DEFINES}),)


def transform_vertices(ctx, mesh, spec, timer, pool, *, double: bool = False, stretch=(1.0, 1.0, 1.0),
                       shift=(0.0, 0.0, 0.0), name: str | None = None, stage: str = "transform", axes=(0, 1, 2),
                       motion=None, fixed: tuple[int, int] | None = None):
    """Stage ``transform`` (S&S Sec. 6): the mesh's vertices in voxel space,
    ``snap((v - origin) / h) * stretch - shift`` computed in double
    (``common/transform.comp``; ``snap`` is :func:`glvox.grid.snap_to_planes`).

    ``stretch`` rescales axes after the snap (the LDI's LOD-C cells along its
    rays); ``double`` keeps the result in double instead of rounding it to
    float32 once.  ``axes``: output coordinate c is voxel-space coordinate
    ``axes[c]``, so ``(1, 2, 0)`` gives the mesh in a frame whose x is the
    grid's y (``spec`` stays the unpermuted grid; snap, stretch and shift
    apply before the permutation).  ``motion``: a buffer of one float32 per
    vertex that receives how far the plane snap moved it (its largest
    coordinate move, voxels, rounded up), or None.  ``fixed``: ``(axis, bits)``, with
    ``double``: the output coordinates other than ``axis`` rounded to multiples of
    ``2^-bits`` voxel (ties to even), the fixed point of ``eisemann/column.glsl``.
    Returns ``(bufs, vox)``: the mesh's
    :class:`MeshBuffers` and a pooled buffer (``name``) of x, y, z per
    vertex, ready for the next stage.
    """
    bufs = mesh_buffers(ctx, mesh)
    size = 8 if double else 4
    vox = pool.get(name or ("vox_vertices_d" if double else "vox_vertices"), bufs.n_vertices * 3 * size,
                   what="voxel-space vertices" + (" (double)" if double else ""), clear=False)
    if fixed is not None and not double:
        raise ValueError("the fixed point rounds double coordinates: pass double=True")
    prog = compute_program(ctx, "common/transform.comp",
                           {"VOX_DOUBLE": int(double), "VOX_MOTION": int(motion is not None),
                            "VOX_FIX_AXIS": -1 if fixed is None else int(fixed[0]), **SNAP_DEFINES})
    if fixed is not None:
        set_uniforms(prog, {"u_fix_bits": int(fixed[1])})
    set_uniforms(prog, {"u_origin_d": tuple(float(x) for x in spec.origin - bufs.anchor),
                        "u_inv_h_d": 1.0 / spec.voxel_size,
                        "u_stretch_d": tuple(float(x) for x in stretch), "u_shift_d": tuple(float(x) for x in shift),
                        "u_vertices": bufs.n_vertices, "u_axes": tuple(int(a) for a in axes)})
    with timer.stage(stage):
        bind(prog, Verts=bufs.vertices, VoxVerts=vox)
        if motion is not None:
            bind(prog, Motion=motion)
        dispatch_1d(ctx, prog, bufs.n_vertices, 256)
        barrier(ctx)
    return bufs, vox


def gpu_vertices_voxel(mesh, spec, eps: float = SNAP_EPS, *, double: bool = False) -> np.ndarray:
    """The mesh's vertices in voxel space exactly as the GPU methods see them, (V, 3) float32
    (float64 with ``double``: what ``transform_vertices(..., double=True)`` writes).

    ``vertex_to_voxel`` of ``shaders/common/snap.glsl`` in numpy: the float32
    upload relative to the anchor (:meth:`glvox.mesh.Mesh.gpu_arrays`),
    ``(v - (origin - anchor)) * (1 / h)`` in float64, the plane snap, one
    rounding to float32.  What :func:`transform_vertices` writes (``double=False``),
    bit for bit (``tests/test_ties.py`` checks it).  ``eps``: the snap distance
    (what ``SNAP_EPS`` the shader was given).
    """
    v32, _ = mesh.gpu_arrays()
    origin = np.asarray(spec.origin, dtype=np.float64) - mesh.anchor
    vox = snap_to_planes((v32.astype(np.float64) - origin) * (1.0 / spec.voxel_size), eps)
    return vox if double else vox.astype(np.float32)


def gpu_triangles_voxel(mesh, spec) -> np.ndarray:
    """The triangles in voxel space exactly as the GPU methods compute them, (T, 3, 3)
    float64 holding the float32 values of :func:`gpu_vertices_voxel`."""
    return gpu_vertices_voxel(mesh, spec)[mesh.faces].astype(np.float64)
