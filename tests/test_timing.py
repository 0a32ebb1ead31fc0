"""Per-stage timings: GPU timer queries, cold vs warm, debug-mode GL error checks."""

from __future__ import annotations

import numpy as np
import pytest

from glvox.errors import GLError
from glvox.gl.shaders import compute_program
from glvox.gl.timing import Stage, StageTimer


def _dispatch(ctx, defines):
    prog = compute_program(ctx, "testing/bits.comp", defines)
    lo = ctx.mgl.buffer(np.arange(64, dtype=np.uint32).tobytes())
    out = ctx.mgl.buffer(reserve=64 * 16)
    lo.bind_to_storage_buffer(0)
    lo.bind_to_storage_buffer(1)
    out.bind_to_storage_buffer(2)
    prog["u_count"].value = 64
    prog.run(1)
    lo.release()
    out.release()


def test_gpu_stage_has_timer_query_time_and_cold_then_warm(gl_context):
    defines = {"TIMING_TEST_VARIANT": 1}  # a program no other test compiled: the first run is cold
    t1 = StageTimer(gl_context, method="demo")
    with t1.stage("compile+dispatch"):
        _dispatch(gl_context, defines)
    with t1.stage("host", gpu=False):
        sum(range(1000))
    first = t1.finish()
    assert first.cold and first.compile_s > 0
    assert first.stage("compile+dispatch").gpu_s is not None and first.stage("compile+dispatch").gpu_s >= 0
    assert first.stage("host").gpu_s is None and first.stage("host").wall_s > 0
    assert first.gpu_s == first.stage("compile+dispatch").gpu_s
    assert [s["name"] for s in first.to_dict()["stages"]] == ["compile+dispatch", "host"]
    t2 = StageTimer(gl_context, method="demo")
    with t2.stage("dispatch"):
        _dispatch(gl_context, defines)
    warm = t2.finish()
    assert not warm.cold and warm.compile_s == 0
    assert "cold" not in warm.summary() and "dispatch" in warm.summary()


def test_debug_mode_names_method_and_stage_on_gl_error(gl_context):
    timer = StageTimer(gl_context, debug=True, method="ss-demo")
    with pytest.raises(GLError, match=r"OpenGL error GL_INVALID_ENUM after method 'ss-demo', stage 'broken'"):
        with timer.stage("broken"):
            gl_context.raw.fn("glEnable")(0xFFFF)  # not a capability: GL_INVALID_ENUM
    assert gl_context.mgl.error == "GL_NO_ERROR"  # reading it cleared it


def test_without_debug_errors_are_left_to_the_caller(gl_context):
    timer = StageTimer(gl_context, debug=False, method="x")
    with timer.stage("quiet"):
        gl_context.raw.fn("glEnable")(0xFFFF)
    assert gl_context.mgl.error == "GL_INVALID_ENUM"


def test_unknown_stage_name():
    t = StageTimer(None).finish()
    with pytest.raises(KeyError, match=r"no stage 'x'; stages are \[\]"):
        t.stage("x")


def test_gpu_time_of_a_long_dispatch_is_measured(gl_context):
    """A dispatch of ~0.1 s: the timestamps give a GPU time that is positive and
    not longer than the stage's wall time (it includes the wait for the GPU)."""
    prog = compute_program(gl_context, "testing/busy.comp")
    out = gl_context.mgl.buffer(reserve=64 * 64 * 4)
    out.bind_to_storage_buffer(0)
    prog["u_iterations"].value = 4000
    timer = StageTimer(gl_context)
    with timer.stage("busy"):
        prog.run(64)
    out.release()
    s = timer.finish().stage("busy")
    assert 0 < s.gpu_s <= s.wall_s


def test_compute_stage_after_a_draw_is_measured(gl_context):
    """With a framebuffer bound and drawn to (as every raster method leaves the
    context), a compute stage's GPU time is still its work, not ~0: llvmpipe
    defers timestamps into the bound framebuffer's scene unless flushed."""
    mgl = gl_context.mgl
    tex = mgl.texture((8, 8), 4)
    fbo = mgl.framebuffer(color_attachments=[tex])
    fbo.use()
    fbo.clear(0.0, 0.0, 0.0, 1.0)
    prog = compute_program(gl_context, "testing/busy.comp")
    out = mgl.buffer(reserve=64 * 64 * 4)
    out.bind_to_storage_buffer(0)
    prog["u_iterations"].value = 4000
    timer = StageTimer(gl_context)
    with timer.stage("busy"):
        prog.run(64)
    out.release()
    gl_context.release_framebuffer(fbo)
    tex.release()
    s = timer.finish().stage("busy")
    assert 0.5 * s.wall_s <= s.gpu_s <= s.wall_s, (s.gpu_s, s.wall_s)


def test_merge_repeats_sums_stages_by_name():
    t = StageTimer()
    t.timings.stages[:] = [Stage("a", 1.0, 0.5), Stage("b", 2.0, None), Stage("a", 3.0, 0.25), Stage("b", 4.0, 1.0)]
    t.merge_repeats()
    assert t.timings.stages == [Stage("a", 4.0, 0.75), Stage("b", 6.0, None)]
