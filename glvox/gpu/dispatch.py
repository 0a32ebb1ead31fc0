"""Dispatching GPU work: loop budget, uniforms, storage buffers by block name, 1D dispatch,
barriers."""

from __future__ import annotations

from typing import Any

import moderngl
import numpy as np

from ..errors import ShaderError
from ..gl.shaders import program_source

#: Loop iterations one shader invocation may run, all loops together, on the
#: software renderer.  Mesa's llvmpipe (gallivm's loop limiter,
#: LP_MAX_TGSI_LOOP_ITERATIONS) silently ends an invocation's loops after
#: 65535 iterations in total, which would drop work without any error; every
#: glvox shader splits its work so that one invocation stays well below this
#: (tests/test_context.py measures it).
LOOP_BUDGET = 65535


def grid_uniforms(spec, anchor: np.ndarray) -> dict[str, Any]:
    """Uniforms of ``common/voxel_space.glsl`` for ``spec``, vertices relative to ``anchor``."""
    origin = tuple(float(x) for x in (spec.origin - anchor))
    return {
        "u_origin": origin,
        "u_inv_h": 1.0 / spec.voxel_size,
        "u_origin_d": origin,  # the same in double, for transforms done in double
        "u_inv_h_d": 1.0 / spec.voxel_size,
        "u_dims": tuple(int(d) for d in spec.dims),
    }


def set_uniforms(prog, values: dict[str, Any]) -> None:
    """Set the uniforms the program uses; ones optimized out of it are skipped."""
    for name, value in values.items():
        # get(), not ``name in prog``: moderngl programs have no __contains__, and
        # ``in`` walks every member (a call's CPU time grew with the programs' sizes)
        member = prog.get(name, None)
        if member is not None:
            member.value = value


def bind(prog, /, **buffers) -> None:
    """Bind each buffer to the binding of ``prog``'s storage block of that name.

    ``bind(prog, Verts=vertices, Grid=grid)`` binds ``vertices`` where the
    shader declares ``layout(std430, binding = N) buffer Verts {...}``: the
    binding numbers live in the GLSL alone.  Bindings are context state, not
    program state, so bind right before each program's dispatch or draw (it
    is a cheap call and moves no data).

    Parameters
    ----------
    prog : moderngl.ComputeShader or moderngl.Program
        Built by :func:`glvox.gl.shaders.compute_program` or
        :func:`~glvox.gl.shaders.render_program` (which record the storage
        blocks each source declares).
    **buffers : moderngl.Buffer
        Storage block name -> buffer.

    Raises
    ------
    ShaderError
        A name that no source of the program declares (a typo or a stale
        name: a programming error, named with the shader file), or a name
        that is not a storage block.  A block the source declares but the
        compiler optimized out (it is legal for a driver to drop a block the
        shader does not use) is skipped silently, like an inactive uniform in
        :func:`set_uniforms`.
    """
    src = program_source(prog)
    if src is None:
        raise ShaderError("bind() needs a program built by glvox.gl.shaders "
                          "(compute_program / render_program), which records its storage blocks")
    for name, buf in buffers.items():
        if name not in src.storage_blocks:
            declared = ", ".join(sorted(src.storage_blocks)) or "none"
            raise ShaderError(f"{src.name} declares no storage block {name!r} (it declares: {declared})")
        block = prog.get(name, None)
        if block is None:
            continue  # declared, optimized out
        if not isinstance(block, moderngl.StorageBlock):
            raise ShaderError(f"{src.name}: {name!r} is a {type(block).__name__}, not a storage block")
        buf.bind_to_storage_buffer(block.binding)


def dispatch_1d(ctx, prog, n: int, local_size: int) -> None:
    """Run ``prog`` over ``n`` invocations in groups of ``local_size``, split along y
    when the x group count would exceed GL_MAX_COMPUTE_WORK_GROUP_COUNT."""
    groups = (int(n) + local_size - 1) // local_size
    if groups == 0:
        return
    max_x = int(ctx.limits()["GL_MAX_COMPUTE_WORK_GROUP_COUNT"][0])
    if groups <= max_x:
        prog.run(groups, 1, 1)
    else:
        prog.run(max_x, (groups + max_x - 1) // max_x, 1)


def barrier(ctx) -> None:
    """Make SSBO writes of earlier dispatches visible to later dispatches,
    indirect-dispatch argument reads and buffer reads."""
    ctx.mgl.memory_barrier(moderngl.SHADER_STORAGE_BARRIER_BIT | moderngl.COMMAND_BARRIER_BIT
                           | moderngl.BUFFER_UPDATE_BARRIER_BIT)


def rendered(ctx) -> None:
    """After a draw whose render targets later dispatches or draws read (texel fetches,
    image loads): make its framebuffer writes visible to them.

    GL orders framebuffer writes before later commands' reads by itself; a memory
    barrier is required only after shaders' own stores (GL 4.5 Sec. 7.12.2).  Mesa's
    softpipe (22.3) keeps rendered pixels in a tile cache that a compute dispatch's
    texel fetches do not flush, so without this its depth-buffer, LDI and binvox
    methods read empty layers and return empty solids (``tests/test_drivers.py``).  On
    a driver that orders them already this adds a texture cache invalidation.
    """
    ctx.mgl.memory_barrier(moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT)
