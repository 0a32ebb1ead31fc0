"""GL behaviours a method relies on that a context may advertise and still get wrong.

A limit says what a context allows; it does not say that the context does it
right.  Mesa's softpipe (22.3), a conforming-looking GL 4.5 context, writes
zeros where a draw with ``glLogicOp(GL_XOR)`` meets an RGBA32UI render target:
``eisemann-solid`` then returns an empty solid on every mesh, with no GL error.
Each behaviour here has a small functional probe, run once per context the
first time a method that needs it is asked for
(:meth:`glvox.methods.base.Requirements.missing`), so such a context refuses
the method in one line before any work, naming what went wrong and what runs
instead.

    from glvox.gpu.behaviours import broken
    why = broken(ctx, "integer-logic-op")   # None where it works
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..gl.shaders import render_program
from .dispatch import set_uniforms

#: Pixels of the probe's target: a 2 x 2 target takes every fragment of the
#: full-screen triangle through the rasterizer's usual path.
_SIZE = (2, 2)
#: The values drawn, two per logic op (u_value of testing/constant_uint.frag).
_VALUES = {"xor": ((0x5, 0x6, 0x7, 0xFFFFFFFF), (0x3, 0x80000004, 0x7, 0x1)),
           "or": ((0x11, 0x0, 0x80000000, 0x0), (0x2, 0x0, 0x1, 0x0))}


def _integer_logic_op(ctx) -> str | None:
    """XOR and OR, two draws each, onto a zeroed RGBA32UI target: the words must be
    those ops of the fragments' words (GL applies the logic op bit by bit to every
    color buffer that is not floating point, integer ones included)."""
    prog = render_program(ctx, "testing/fullscreen.vert", "testing/constant_uint.frag")
    mgl = ctx.mgl
    tex = mgl.texture(_SIZE, 4, dtype="u4")
    fbo = mgl.framebuffer(color_attachments=[tex])
    vao = mgl.vertex_array(prog, [])
    try:
        fbo.use()
        fbo.viewport = (0, 0, *_SIZE)
        xy = np.stack(np.meshgrid(np.arange(_SIZE[0]), np.arange(_SIZE[1])), axis=-1).astype(np.uint32)
        frag = np.zeros((_SIZE[1], _SIZE[0], 4), np.uint32)
        for op, values in _VALUES.items():
            tex.write(np.zeros_like(frag).tobytes())
            want = np.zeros_like(frag)
            with ctx.logic_op(op):
                for value in values:
                    set_uniforms(prog, {"u_value": value})
                    vao.render(mgl.TRIANGLES, vertices=3)
                    frag[:] = np.asarray(value, np.uint32)
                    frag[..., :2] ^= xy
                    want = want ^ frag if op == "xor" else want | frag
            got = np.frombuffer(tex.read(), np.uint32).reshape(want.shape)
            if not np.array_equal(got, want):
                return (f"glLogicOp({op.upper()}) onto an RGBA32UI render target gives other words than the "
                        f"{op.upper()} of the fragments' words (pixel (0, 0): {tuple(int(w) for w in got[0, 0])}, "
                        f"expected {tuple(int(w) for w in want[0, 0])})")
        return None
    finally:
        vao.release()
        ctx.release_framebuffer(fbo)
        tex.release()


#: Behaviour name -> probe (``ctx`` -> None where it works, else what went wrong).
PROBES: dict[str, Callable] = {"integer-logic-op": _integer_logic_op}


def broken(ctx, name: str) -> str | None:
    """None when ``ctx`` does behaviour ``name`` right, else one line on what it did.
    Probed once per context; a context without a GL context behind it
    (:class:`glvox.testing.gl_limits.FakeContext`) holds its answers already."""
    if name not in PROBES:
        raise KeyError(f"no behaviour probe named {name!r}: {sorted(PROBES)}")
    known = ctx.caches.setdefault("behaviours", {})
    if name not in known:
        known[name] = PROBES[name](ctx)
    return known[name]
