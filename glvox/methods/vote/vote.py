"""Three-axis parity vote on the GPU: ``vote-solid``.

A voxel is solid when at least two of its three parities of crossings, along
x, y and z, say inside: the cheap fix for small holes of VoxSurf and Open3D's
``compute_occupancy(nsamples)``.  A hole lets a column's parity flip wrongly
only along the rays that pass through it, so a voxel is lost or streaked
only where two of the three axes see holes.  On a closed mesh the three
parities agree up to ties, so the vote equals ``reference-solid`` up to ties;
on any mesh it equals ``reference-vote`` (the vote of ``reference-solid``
along the three axes, :func:`glvox.reference.solid_vote`) up to ties, since
each parity is ``ss-solid``'s arithmetic along that axis.

Pipeline, on the GPU until the readback: the mesh is uploaded once and
``ss-solid``'s passes (:func:`glvox.methods.ss.solid.parity_on_gpu`) run
three times, the transform rotating the vertices so that the x-column
passes run along y (stages ``*_y``) and z (``*_z``) and put their crossing
bits straight into glvox's x-packed layout, where a running XOR down the
columns fills them; ``vote`` keeps the majority of the three grids word by
word, counted; ``readback`` reads the z slices of the mesh's rows.
"""

from __future__ import annotations

import numpy as np

from ...gl.shaders import compute_program
from ...gpu.buffers import buffer_pool, read_grid_words
from ...gpu.dispatch import barrier, bind, dispatch_1d, grid_uniforms, set_uniforms
from ...results.voxels import VoxelGrid
from ..base import Method, MethodInfo, Requirements, register
from ..ss.solid import COMPUTE as SOLID_COMPUTE, parity_on_gpu

_LOCAL = 64  # local_size_x of vote/vote.comp
_REQUIRES = Requirements(gl_version=430, extensions=("GL_ARB_gpu_shader_fp64",),
                         limits={"GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS": 9},
                         compute=(("vote/*.comp", {}),) + SOLID_COMPUTE)


@register
class VoteSolid(Method):
    info = MethodInfo(
        name="vote-solid", kind="solid", pipeline="compute",
        paper="majority of the parities along x, y and z (VoxSurf; Open3D compute_occupancy), each with "
              "Schwarz & Seidel 2010 Sec. 4.1's arithmetic (ss-solid in three rotated frames)",
        summary="robust solid for meshes with small holes: a voxel is inside when two of its three "
                "axis-parallel parities say so",
        reference="reference-vote", any_mesh=True,
        requires=_REQUIRES,
    )

    def run(self, mesh, spec, *, ctx, timer):
        pool = buffer_pool(ctx, self.info.name)
        x, y, z = (parity_on_gpu(ctx, mesh, spec, timer, pool, axis=a, tag=t)
                   for a, t in ((0, ""), (1, "_y"), (2, "_z")))
        count = pool.get("vote_count", 4)
        wpr = spec.words_per_row
        vec = 4 if wpr % 4 == 0 else 2 if wpr % 2 == 0 else 1
        # every parity is empty outside the mesh's rows, hence the vote: only
        # the z slices of those rows are voted, counted and read back
        k0, nk = x.rows[1], x.rows[3]
        per_slice = spec.dims[1] * wpr // vec
        prog = compute_program(ctx, "vote/vote.comp", {"VEC": vec})
        set_uniforms(prog, {**grid_uniforms(spec, np.zeros(3)), "u_first": k0 * per_slice,
                            "u_count": nk * per_slice})
        with timer.stage("vote"):
            bind(prog, X=x.grid, Y=y.grid, Z=z.grid, Count=count)
            dispatch_1d(ctx, prog, nk * per_slice, _LOCAL)
            barrier(ctx)
        with timer.stage("readback", gpu=False):
            words = read_grid_words(ctx, x.grid, spec, (k0, nk))
            voxels = int(np.frombuffer(count.read(size=4), dtype="<u4")[0])
        return VoxelGrid(words=words, spec=spec, count=voxels)
