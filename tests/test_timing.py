"""Per-stage timings: GPU timer queries, cold vs warm, debug-mode GL error checks."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import slab_case

from glvox.errors import GLError
from glvox.gl.shaders import compute_program
from glvox.gl.timing import Stage, StageTimer, stage_sync
from glvox.methods import run_method


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


def _busy_stage(ctx, timer, name, iterations):
    prog = compute_program(ctx, "testing/busy.comp")
    out = ctx.mgl.buffer(reserve=64 * 64 * 4)
    out.bind_to_storage_buffer(0)
    prog["u_iterations"].value = iterations
    with timer.stage(name):
        prog.run(64)
    out.release()


def test_unsynced_stages_keep_their_own_gpu_times(gl_context):
    """Without the per-stage waits (GLVOX_STAGE_SYNC=0) each stage takes its own pair of
    timestamp queries, read at the end: a long and a short dispatch keep their own
    times, also when another timer (a nested run) times a stage in between, and with a
    framebuffer bound and drawn to (a timestamp in llvmpipe's deferred scene is taken when
    the scene is flushed: each is followed by a flush)."""
    tex = gl_context.mgl.texture((8, 8), 4)
    fbo = gl_context.mgl.framebuffer(color_attachments=[tex])
    fbo.use()
    fbo.clear(0.0, 0.0, 0.0, 1.0)
    with stage_sync(False):
        outer, inner = StageTimer(gl_context), StageTimer(gl_context)
    assert not outer.sync and not inner.sync and StageTimer(gl_context).sync
    _busy_stage(gl_context, outer, "long", 4000)
    _busy_stage(gl_context, inner, "short", 400)
    _busy_stage(gl_context, outer, "long again", 4000)
    short = inner.finish().stage("short").gpu_s
    first, second = (outer.finish().stage(n).gpu_s for n in ("long", "long again"))
    gl_context.release_framebuffer(fbo)
    tex.release()
    assert 0 < short and first > 3 * short and second > 3 * short, (short, first, second)
    assert not outer._pending and not inner._pending  # their queries went back to the context


def test_unsynced_runs_give_the_same_voxels_and_stage_times(gl_context, monkeypatch):
    """A run without the waits is the same run: the same words, the same stages, each
    GPU stage with its GPU time, repeated stages (slab by slab) merged as with them."""
    mesh, spec = slab_case(gl_context, monkeypatch)
    for method in ("ss-conservative", "ss-solid", "gwn-solid"):
        with stage_sync(True):
            synced = run_method(method, mesh, spec, allow_open=True)
        with stage_sync(False):
            unsynced = run_method(method, mesh, spec, allow_open=True)
        assert np.array_equal(synced.words(), unsynced.words()), method
        a, b = synced.run.timings.stages, unsynced.run.timings.stages
        assert [s.name for s in a] == [s.name for s in b], method
        assert [s.gpu_s is None for s in a] == [s.gpu_s is None for s in b], method
        assert all(s.gpu_s >= 0 for s in b if s.gpu_s is not None), method
