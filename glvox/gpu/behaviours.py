"""GL behaviours a method relies on that a context may advertise and still get wrong.

A limit says what a context allows; it does not say that the context does it
right.  Mesa's softpipe (22.3), a conforming-looking GL 4.5 context, writes
zeros where a draw with ``glLogicOp(GL_XOR)`` meets an RGBA32UI render target:
``eisemann-solid`` then returns an empty solid on every mesh, with no GL error.
Each behaviour here has a small functional probe, run once per context the
first time a method that needs it is asked for
(:meth:`glvox.methods.base.Requirements.missing`), so such a context refuses
the method in one line before any work, naming what went wrong and what runs
instead.  The behaviours of :data:`EVERY_METHOD` are asked of every GL method.

Mesa's zink (22.3, GL over Vulkan) with its inlined uniforms (a program
specialized on the uniforms its branches read) dispatched a compute program
with the values another program had been given since its own last dispatch:
``ss-solid-tiled`` then returned empty solids after ``ss-conservative``'s sorted
variant had run in the same context.  glvox turns zink's inlining off
(:func:`glvox.gl.context.create_context` sets ``ZINK_INLINE_UNIFORMS=0`` unless
the environment says otherwise), and ``uniform-update`` refuses every method on
a context that still gets it wrong.

    from glvox.gpu.behaviours import broken
    why = broken(ctx, "integer-logic-op")   # None where it works
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..gl.shaders import compute_program, render_program
from .dispatch import barrier, bind, set_uniforms

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


#: The uniform-update probe's dispatches: (program, the values set before it, or
#: None for the values it holds since its last dispatch).  Values (u_flag, u_mode,
#: u_value) of ``testing/uniform_branch.comp``; the two programs take turns, each
#: sometimes dispatched again without a change after the other was given others.
UNIFORM_STEPS: tuple[tuple[int, tuple[bool, int, int] | None], ...] = (
    (0, (True, 1, 11)), (1, (False, 1, 12)), (0, (True, 1, 11)), (1, (False, 1, 12)),
    (0, (False, 1, 11)), (1, (False, 1, 12)), (0, None), (1, (True, 2, 13)), (0, (False, 2, 14)),
    (1, None), (0, (True, 1, 15)), (1, (False, 2, 16)), (0, None), (1, None),
)


def uniform_branch_word(variant: int, flag: bool, mode: int, value: int) -> int:
    """The word ``testing/uniform_branch.comp`` (``VARIANT`` = variant) writes."""
    if flag:
        return value if mode == 1 else ~value & 0xFFFFFFFF
    return (value + 1 + variant) & 0xFFFFFFFF if mode == 1 else value ^ 0x5A5A5A5A


def uniform_update_errors(dispatch: Callable[[int, tuple | None], int]) -> list[str]:
    """Run :data:`UNIFORM_STEPS` through ``dispatch(program, values or None) -> word``
    and return one line per dispatch whose word is not its program's current values'."""
    held: list[tuple | None] = [None, None]
    out = []
    for i, (prog, values) in enumerate(UNIFORM_STEPS):
        if values is not None:
            held[prog] = values
        got = dispatch(prog, values)
        want = uniform_branch_word(prog, *held[prog])
        if got != want:
            out.append(f"dispatch {i + 1} (program {prog}, uniforms {held[prog]}"
                       f"{'' if values is not None else ', unchanged since its last dispatch'}): "
                       f"{got:#x}, expected {want:#x}")
    return out


def _uniform_update(ctx) -> str | None:
    """Two compute programs take turns; each dispatch must see the uniform values
    its own program holds (uniforms are program state, GL 4.5 Sec. 7.6), also
    where they did not change since its last dispatch but the other program's did."""
    progs = [compute_program(ctx, "testing/uniform_branch.comp", {"VARIANT": v}) for v in (0, 1)]
    out = ctx.mgl.buffer(reserve=4)

    def dispatch(prog: int, values) -> int:
        if values is not None:
            set_uniforms(progs[prog], dict(zip(("u_flag", "u_mode", "u_value"), values)))
        bind(progs[prog], Out=out)
        progs[prog].run(1)
        barrier(ctx)
        return int(np.frombuffer(out.read(size=4), np.uint32)[0])

    try:
        errors = uniform_update_errors(dispatch)
    finally:
        out.release()
    if not errors:
        return None
    hint = ("; zink specializes programs on their uniforms (inlined uniforms): ZINK_INLINE_UNIFORMS=0, "
            "glvox's default, turns that off" if ctx.renderer.startswith("zink") else "")
    return (f"a compute program dispatched with other uniform values than it holds, {len(errors)} of "
            f"{len(UNIFORM_STEPS)} dispatches ({errors[0]}){hint}")


#: Behaviour name -> probe (``ctx`` -> None where it works, else what went wrong).
PROBES: dict[str, Callable] = {"integer-logic-op": _integer_logic_op, "uniform-update": _uniform_update}
#: The behaviours every GL method relies on (Requirements.missing asks them of all).
EVERY_METHOD: tuple[str, ...] = ("uniform-update",)


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
