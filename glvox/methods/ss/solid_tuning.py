"""The measured choices of how ``ss-solid`` lays out its work on llvmpipe.

* :func:`fill_defines`, :func:`fill_rows`: word width and rows per invocation
  of the fill pass (``shaders/ss/solid_fill.comp``);
* :func:`voxelize_faces`: the order in which the voxelize pass takes the
  triangles (:func:`row_order` on large grids).

None of them changes a bit of the result: the fill variants compute the same
prefix XOR, and any order of the triangles gives the same crossings (XOR
commutes).  Figures: README "Solid voxelization".
"""

from __future__ import annotations

import numpy as np

from ...gpu.dispatch import LOOP_BUDGET

#: Most rows per invocation of ``ss/solid_fill.comp`` (:func:`fill_rows`).
#: More rows per invocation took less time, to a plateau from 32-64 rows on:
#: timing the pass alone on the bunny's and the armadillo's crossings at
#: 512^3 and 1024^3, 64 rows took 0.4-0.5 of the time of 4 (end to end:
#: README "Solid voxelization").
FILL_ROWS = 64

#: Work groups (of 64 invocations) the fill keeps at least, where the rows
#: allow, so that every llvmpipe thread gets some: at 64^3 a single group of
#: 64 rows each ran on one thread and took 1.1x the time of 4 rows each.
FILL_MIN_GROUPS = 16

#: The extension that lets ``ss/solid_fill.comp`` load 64-bit words.
INT64 = "GL_ARB_gpu_shader_int64"


def fill_defines(ctx, words_per_row: int) -> dict[str, int]:
    """The defines of ``ss/solid_fill.comp`` for rows of ``words_per_row`` 32-bit
    words: 64-bit words (``WORD64``) where the context has :data:`INT64` and the
    rows hold whole pairs, and the widest vector (``VEC`` 4, 2 or 1) that divides
    the row.  llvmpipe loads and stores a buffer lane by lane and component by
    component, so wider words mean fewer of those: timing the fill alone at
    1024^3, 64-bit words took 0.85 of the time of 32-bit ones.
    """
    w64 = words_per_row % 2 == 0 and INT64 in ctx.mgl.extensions
    n = words_per_row // 2 if w64 else words_per_row
    vec = 4 if n % 4 == 0 else 2 if n % 2 == 0 else 1
    return {"VEC": vec, "WORD64": int(w64)}


def fill_rows(defines: dict[str, int], words_per_row: int, n_rows: int, local_size: int) -> int:
    """Rows per invocation of the fill (``u_rows_per``) over ``n_rows`` rows, with
    :func:`fill_defines`'s ``defines``: :data:`FILL_ROWS`, fewer where that would
    leave under :data:`FILL_MIN_GROUPS` work groups of ``local_size``, or where an
    invocation's loop iterations (its rows and each row's loads) would pass half
    of LOOP_BUDGET; at least one."""
    loads = words_per_row // (2 if defines["WORD64"] else 1) // defines["VEC"]
    spread = n_rows // (FILL_MIN_GROUPS * local_size)
    return max(1, min(FILL_ROWS, spread, (LOOP_BUDGET // 2) // (loads + 1)))


#: Slabs of the mesh's z extent that :func:`row_order` sorts triangles into.
ORDER_SLABS = 64

#: Bit grids of at least this many bytes get their crossings flipped in
#: :func:`row_order` (see there; below it the grid stays in the CPU's caches
#: and the order did not pay for its sort).
ORDER_MIN_BYTES = 1 << 25


def row_order(mesh) -> np.ndarray:
    """The order in which ss-solid's voxelize pass takes the triangles of ``mesh``
    on large grids: by slab of 1 / :data:`ORDER_SLABS` of the mesh's z extent,
    then by y, each triangle at its first vertex; (F,) int64 triangle indices.

    Consecutive invocations then flip bits in nearby rows, which stay in the
    CPU's caches; in the mesh file's order they jump across the grid (at
    1024^3 the voxelize stage took 0.6-0.75 of its time on the bunny and the
    armadillo, 0.8-0.9 on the dragon; end to end: README "Solid
    voxelization").  Any order gives the same crossings, so the same grid:
    XOR commutes.  The order depends on the mesh only, so it is made once per
    mesh.
    """
    p = mesh.vertices[mesh.faces[:, 0]]
    lo, span = p.min(0), np.ptp(p, axis=0)
    inv = np.divide(1.0, span, out=np.zeros(3), where=span > 0)  # a flat extent: one slab
    slab = np.minimum((p[:, 2] - lo[2]) * (inv[2] * ORDER_SLABS), ORDER_SLABS - 1).astype(np.int64)
    y = np.minimum((p[:, 1] - lo[1]) * (inv[1] * 2.0**31), 2**31 - 1).astype(np.int64)
    return np.argsort((slab << 31) | y, kind="stable")


def row_ordered_faces(ctx, mesh, bufs):
    """The faces of ``mesh`` in :func:`row_order`, uploaded once and kept with
    its buffers ``bufs`` (a :class:`~glvox.gpu.buffers.MeshBuffers`)."""
    buf = bufs.derived.get("faces_in_row_order")
    if buf is None:
        faces = mesh.faces.astype(np.uint32)[row_order(mesh)]
        buf = bufs.derived["faces_in_row_order"] = ctx.mgl.buffer(faces.tobytes())
    return buf


def voxelize_faces(ctx, mesh, spec, bufs):
    """The faces buffer ss-solid's voxelize pass reads for ``mesh`` on ``spec``:
    :func:`row_ordered_faces` where the bit grid has at least
    :data:`ORDER_MIN_BYTES`, the uploaded faces (``bufs.faces``) below."""
    return row_ordered_faces(ctx, mesh, bufs) if spec.n_words * 4 >= ORDER_MIN_BYTES else bufs.faces
