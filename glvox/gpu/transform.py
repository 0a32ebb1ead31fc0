"""The shared vertex transform of every compute method (S&S Sec. 6):
``shaders/common/transform.comp``."""

from __future__ import annotations

from ..gl.shaders import compute_program
from .buffers import mesh_buffers
from .dispatch import barrier, dispatch_1d, set_uniforms


def transform_vertices(ctx, mesh, spec, timer, pool, *, double: bool = False, scale=None, shift=(0.0, 0.0, 0.0),
                       name: str | None = None, stage: str = "transform", axes=(0, 1, 2), snap: float = 0.0):
    """Stage ``transform`` (S&S Sec. 6): the mesh's vertices in voxel space,
    ``(v - origin) * scale - shift`` computed in double (``common/transform.comp``).

    ``scale`` defaults to ``1 / h`` on every axis; ``double`` keeps the result
    in double instead of rounding it to float32 once.  ``axes``: output
    coordinate c is voxel-space coordinate ``axes[c]``, so ``(1, 2, 0)`` gives
    the mesh in a frame whose x is the grid's y (``spec`` stays the
    unpermuted grid; scale and shift apply before the permutation).  ``snap``
    (voxels, > 0): coordinates that far or less outside the grid's box
    ``[0, dims]`` move onto its faces (before the permutation).  Returns ``(bufs, vox)``:
    the mesh's :class:`MeshBuffers` and a pooled buffer (``name``) of x, y, z
    per vertex, ready for the next stage.
    """
    bufs = mesh_buffers(ctx, mesh)
    size = 8 if double else 4
    vox = pool.get(name or ("vox_vertices_d" if double else "vox_vertices"), bufs.n_vertices * 3 * size,
                   what="voxel-space vertices" + (" (double)" if double else ""), clear=False)
    if scale is None:
        scale = (1.0 / spec.voxel_size,) * 3
    prog = compute_program(ctx, "common/transform.comp", {"VOX_DOUBLE": int(double)})
    set_uniforms(prog, {"u_origin_d": tuple(float(x) for x in spec.origin - bufs.anchor),
                        "u_scale_d": tuple(float(x) for x in scale), "u_shift_d": tuple(float(x) for x in shift),
                        "u_vertices": bufs.n_vertices, "u_axes": tuple(int(a) for a in axes),
                        "u_snap": float(snap), "u_snap_dims": tuple(float(d) for d in spec.dims)})
    with timer.stage(stage):
        bufs.vertices.bind_to_storage_buffer(0)
        vox.bind_to_storage_buffer(1)
        dispatch_1d(ctx, prog, bufs.n_vertices, 256)
        barrier(ctx)
    return bufs, vox
