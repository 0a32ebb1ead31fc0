"""``gwn-solid -O shell=true``: the conservative surface ORed into the solid on the GPU,
so that open sheets and thin parts the winding number leaves out still get voxels."""

from __future__ import annotations

from ...gl.shaders import compute_program
from ...gl.timing import StageTimer
from ...gpu.buffers import mesh_buffers
from ...gpu.dispatch import barrier, bind, dispatch_1d, set_uniforms
from ..carve.sweep import surface_slices
from ..ss.surface import surface_on_gpu


def add_shell(ctx, mesh, spec, pool, bits, count) -> None:
    """OR the conservative surface into ``bits`` on the GPU, adding the voxels it
    adds to ``count``: ss-conservative's passes (timed apart: the caller's
    ``shell`` stage holds them) into ``pool``, then ``gwn/shell.comp`` over the
    surface's slices."""
    surface, _ = surface_on_gpu(ctx, mesh, spec, StageTimer(ctx), pool, variant="specialized")
    k0, nk = surface_slices(spec, mesh_buffers(ctx, mesh))
    per_slice = spec.dims[1] * spec.words_per_row
    prog = compute_program(ctx, "gwn/shell.comp")
    set_uniforms(prog, {"u_first_word": k0 * per_slice, "u_words": nk * per_slice})
    bind(prog, Surface=surface, Bits=bits, Count=count)
    dispatch_1d(ctx, prog, nk * per_slice, 64)
    barrier(ctx)
