"""Results read back into persistently mapped buffers that the result owns
(glvox/gpu/readback.py): the same words as glGetBufferSubData, never overwritten
while a result holds them, reused once it is gone, valid past the context's release.

What the tests rest on: GL 4.4's persistent, coherent mapping (ARB_buffer_storage:
the mapping stays valid while the buffer lives and is used, and after a fence the
GPU's writes to it are visible to the host) and glCopyNamedBufferSubData's ordering
with the dispatches before it (GL 4.5, command order).
"""

from __future__ import annotations

import gc

import numpy as np
import pytest
import trimesh

import glvox
from glvox.errors import CapabilityError, GlvoxError
from glvox.gl.raw import RawGL
from glvox.gl.context import create_context, deferred_contexts
from glvox.gpu import readback
from glvox.gpu.readback import is_mapped, readback_pool
from glvox.mesh import load_mesh
from glvox.methods import run_method

#: 128^3 words are 256 KiB, 256^3 are 2 MiB: over MIN_MAPPED_BYTES (1 MiB).
N = 256


def _sphere(radius=1.0, center=(0.0, 0.0, 0.0)):
    m = trimesh.creation.icosphere(3, radius=radius)
    return load_mesh((m.vertices + np.asarray(center), m.faces), name=f"sphere-{radius}")


def _copied(name, mesh, spec, monkeypatch, **kw):
    with monkeypatch.context() as m:
        m.setenv("GLVOX_READBACK", "copy")
        return run_method(name, mesh, spec, **kw)


@pytest.mark.parametrize("name", ["ss-conservative", "ss-solid", "eisemann-solid", "scanline-ilv"])
def test_large_results_view_a_mapped_buffer_with_the_copied_words(gl_context, monkeypatch, name):
    """From 1 MiB of words a result views a mapped buffer, and its words equal the
    glGetBufferSubData read (ss-solid reads only the mesh's slices into it)."""
    mesh = _sphere()
    spec = glvox.grid_for(mesh, N)
    got = run_method(name, mesh, spec)
    assert is_mapped(got.words()) and not got.words().flags.writeable
    want = _copied(name, mesh, spec, monkeypatch)
    assert not is_mapped(want.words())
    np.testing.assert_array_equal(got.words(), want.words())
    assert got.count == want.count > 0


def test_small_results_are_read_into_numpy(gl_context):
    mesh = _sphere()
    got = run_method("ss-conservative", mesh, glvox.grid_for(mesh, 64))  # 32 KiB of words
    assert not is_mapped(got.words())


def test_a_kept_result_is_never_overwritten_and_a_dropped_one_is_reused(gl_context):
    """Two results alive at once hold two buffers; a third call after one is dropped
    takes that one, already mapped, and the kept result's words do not change."""
    pool = readback_pool(gl_context)
    small, big = _sphere(0.5), _sphere(1.0)
    spec = glvox.grid_for(big, N)
    kept = run_method("ss-conservative", small, spec)
    before = np.array(kept.words())
    dropped = run_method("ss-conservative", big, spec)
    where = dropped.words().__array_interface__["data"][0]
    assert where != kept.words().__array_interface__["data"][0]  # two buffers while both live
    del dropped
    gc.collect()
    reused = pool.counts["reused"]
    again = run_method("ss-conservative", big, spec)
    assert pool.counts["reused"] == reused + 1
    assert again.words().__array_interface__["data"][0] == where  # the dropped one's, taken back
    np.testing.assert_array_equal(kept.words(), before)
    assert not np.array_equal(again.words(), before)


def test_the_unread_slices_are_zero_in_a_reused_buffer(gl_context, monkeypatch):
    """ss-solid reads only the slices its mesh spans; in a pooled buffer that a
    fuller grid used before, the others must come back zero (cleared on the GPU)."""
    pool = readback_pool(gl_context)
    full = _sphere(1.0)
    spec = glvox.grid_for(full, N)
    dirty = run_method("ss-solid", full, spec)
    assert dirty.count > 0
    del dirty
    gc.collect()
    reused = pool.counts["reused"]
    low = _sphere(0.1, center=(0.0, 0.0, -0.85))  # a few slices near the bottom
    got = run_method("ss-solid", low, spec)
    assert pool.counts["reused"] == reused + 1 and is_mapped(got.words())
    want = _copied("ss-solid", low, spec, monkeypatch)
    np.testing.assert_array_equal(got.words(), want.words())
    assert got.count == int(np.bitwise_count(got.words()).sum())


def test_slabs_are_copied_into_one_mapped_result(gl_context, monkeypatch):
    """Over the storage-block limit, each z slab is copied on the GPU into its part."""
    mesh = _sphere()
    spec = glvox.grid_for(mesh, N)
    whole = _copied("ss-conservative", mesh, spec, monkeypatch)
    real = gl_context.limits()
    monkeypatch.setattr(gl_context, "limits",
                        lambda: {**real, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": spec.n_words * 4 // 3})
    sliced = run_method("ss-conservative", mesh, spec)
    assert sliced.run.stats["slabs"] == 4 and is_mapped(sliced.words())
    np.testing.assert_array_equal(sliced.words(), whole.words())


def test_past_the_lent_limit_results_are_copied(gl_context, monkeypatch):
    pool = readback_pool(gl_context)
    mesh = _sphere()
    spec = glvox.grid_for(mesh, N)
    monkeypatch.setattr(readback, "lent_limit", lambda: pool.lent_bytes)  # nothing more may be lent
    copied = pool.counts["copied"]
    got = run_method("ss-conservative", mesh, spec)
    assert not is_mapped(got.words()) and pool.counts["copied"] == copied + 1
    monkeypatch.undo()
    np.testing.assert_array_equal(got.words(), run_method("ss-conservative", mesh, spec).words())


def test_a_buffer_the_driver_refuses_leaves_no_gl_error(gl_context):
    """A mapping the driver cannot make is refused in one line, and its GL error is taken,
    not left for the next unrelated check to raise.  2^60 bytes is past any CPU's virtual
    address space (57 bits at most): NVIDIA's driver (580) reserves 1 TiB lazily and maps it."""
    with pytest.raises(CapabilityError, match=r"could not map a 1152921504606846976-byte buffer persistently"):
        gl_context.raw.create_mapped_buffer(1 << 60)
    gl_context.check_error("after a refused mapping")


@pytest.mark.parametrize("small", [True, False])
def test_a_refused_mapping_falls_back_to_copies(monkeypatch, small):
    """A refused small buffer means the context maps nothing (every later result is
    copied); a refused large one costs only that result its mapping."""
    def refuse(self, size):
        raise CapabilityError("refused")

    ctx = create_context()
    try:
        pool = readback_pool(ctx)
        if not small:
            monkeypatch.setattr(readback, "MIN_MAPPED_BYTES", 1 << 10)  # 2 MiB is then large
        monkeypatch.setattr(RawGL, "create_mapped_buffer", refuse)
        mesh = _sphere()
        spec = glvox.grid_for(mesh, N)
        got = run_method("ss-conservative", mesh, spec, ctx=ctx)
        assert not is_mapped(got.words()) and pool.unmappable == small
        monkeypatch.undo()
        np.testing.assert_array_equal(got.words(), run_method("ss-conservative", mesh, spec, ctx=ctx).words())
    finally:
        ctx.release()


def test_a_released_context_waits_for_its_results():
    """Releasing a context whose result still views its memory keeps the GL context
    (the words stay readable) until the result is gone; the next context switch then
    releases it."""
    ctx = create_context()
    try:
        mesh = _sphere()
        got = run_method("ss-conservative", mesh, glvox.grid_for(mesh, N), ctx=ctx)
        assert is_mapped(got.words())
        want = np.array(got.words())
        before = deferred_contexts()
        ctx.release()
        assert deferred_contexts() == before + 1
        np.testing.assert_array_equal(got.words(), want)  # still mapped, still the bits
        del got
        gc.collect()
    finally:
        ctx.release()
    other = create_context()  # any make-current reaps what nothing views
    other.release()
    assert deferred_contexts() == before


def test_a_bad_readback_mode_is_refused_before_any_work(gl_context, monkeypatch):
    monkeypatch.setenv("GLVOX_READBACK", "zero-copy")
    mesh = _sphere()
    with pytest.raises(GlvoxError, match=r"^GLVOX_READBACK must be one of mapped, copy, got 'zero-copy'$"):
        run_method("ss-conservative", mesh, glvox.grid_for(mesh, 16))
