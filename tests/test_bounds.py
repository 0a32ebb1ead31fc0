"""No shader writes past the buffer it was given, or reads what nobody wrote, whatever the
driver does with such a write or read.

A store past the end of a storage buffer is undefined in GL (4.5 core Sec. 7.8, without
robust buffer access): llvmpipe checks every access against the bound buffer's size and
drops it, so a store one word too far changes nothing here, while a GPU may write it into
whatever memory follows.  These tests give every pooled buffer (:class:`BufferPool`) the
size its method asked for plus a guard of canary words, inside the buffer, where llvmpipe
keeps a stray store, and check after each run that the guard is intact.
"""

from __future__ import annotations

import contextlib
import warnings

import moderngl
import numpy as np
import pytest
from conftest import gl_option_runs, run_ids, slab_case

import glvox
from glvox.gl import raw as rawgl
from glvox.gl.shaders import compute_program
from glvox.gpu import buffers as gpu_buffers
from glvox.gpu.buffers import buffer_pool, check_buffer_size, release_pools
from glvox.gpu.dispatch import barrier, bind
from glvox.mesh import load_mesh
from glvox.methods import method_infos, run_method

CANARY = 0xA5A5A5A5


def guard_bytes(nbytes: int) -> int:
    """The guard after a buffer of ``nbytes``: as long as the buffer (at least 4 KiB), so that
    a store that runs a whole slice or row too far still lands in it."""
    return max(4096, -(-nbytes // 4) * 4)


@contextlib.contextmanager
def guarded(ctx, monkeypatch):
    """Every BufferPool buffer made in the block is fresh, its asked size plus
    :func:`guard_bytes` of CANARY; clears stop at the asked size.  Yields ``check()``, which returns the buffers
    whose guard changed (and re-arms them)."""
    tracked: dict[int, tuple] = {}  # GL name -> (buffer, asked bytes, pool name)
    plain_clear = rawgl.RawGL.clear_buffer_words
    plain_mgl_clear = moderngl.Buffer.clear

    def get(self, name, nbytes, *, what=None, clear=True):
        nbytes = max(4, int(nbytes))
        check_buffer_size(self.ctx, nbytes, what or name)
        old = self._bufs.get(name)
        if old is not None:
            tracked.pop(old.glo, None)
            old.release()
        nbytes = -(-nbytes // 4) * 4
        buf = self._bufs[name] = self.ctx.mgl.buffer(reserve=nbytes + guard_bytes(nbytes))
        plain_clear(self.ctx.raw, buf.glo, 0, nbytes, 0 if clear else 0xDEADBEEF)
        plain_clear(self.ctx.raw, buf.glo, nbytes, guard_bytes(nbytes), CANARY)
        tracked[buf.glo] = (buf, nbytes, name)
        return buf

    def clear_words(self, buffer, offset, size, value):
        held = tracked.get(int(buffer))
        if held is not None:
            size = min(size, held[1] - offset)
            if size <= 0:
                return None
        return plain_clear(self, buffer, offset, size, value)

    def mgl_clear(self, size=-1, offset=0, chunk=None):
        held = tracked.get(self.glo)
        if held is not None and (size < 0 or offset + size > held[1]):
            size = held[1] - offset
        return plain_mgl_clear(self, size=size, offset=offset, chunk=chunk)

    def check() -> list[str]:
        ctx.mgl.memory_barrier()
        bad = []
        for glo, (buf, nbytes, name) in tracked.items():
            guard = np.frombuffer(buf.read(size=guard_bytes(nbytes), offset=nbytes), dtype="<u4")
            if (guard != CANARY).any():
                i = int(np.argmax(guard != CANARY))
                bad.append(f"{name}: word {i} past its {nbytes} bytes holds {int(guard[i]):#x}")
                plain_clear(ctx.raw, glo, nbytes, guard_bytes(nbytes), CANARY)
        return bad

    release_pools(ctx)  # every buffer from here on is a guarded one
    monkeypatch.setattr(gpu_buffers.BufferPool, "get", get)
    monkeypatch.setattr(rawgl.RawGL, "clear_buffer_words", clear_words)
    monkeypatch.setattr(moderngl.Buffer, "clear", mgl_clear)
    try:
        yield check
    finally:
        release_pools(ctx)  # no guarded buffer outlives the test in a pool


def test_the_guard_sees_a_store_one_word_past_the_end(gl_context, monkeypatch, tmp_path):
    (tmp_path / "past.comp").write_text(
        "#version 450\nlayout(local_size_x = 1) in;\nuniform uint u_at;\n"
        "layout(std430, binding = 0) writeonly buffer Out { uint data[]; };\n"
        "void main() { data[u_at] = 7u; }\n")
    prog = compute_program(gl_context, "past.comp", search=[tmp_path])
    with guarded(gl_context, monkeypatch) as check:
        buf = buffer_pool(gl_context, "test-bounds").get("out", 64)
        bind(prog, Out=buf)
        prog["u_at"].value = 15  # the last word asked for
        prog.run(1)
        barrier(gl_context)
        assert check() == []
        prog["u_at"].value = 16  # one past it
        prog.run(1)
        assert check() == ["out: word 0 past its 64 bytes holds 0x7"]


OPTION_RUNS = gl_option_runs()


def _result(out) -> list[np.ndarray]:
    """What a run gave, as arrays to compare: packed words, an LDI's counts and depths, an
    octree's dense grid."""
    if hasattr(out, "words"):
        return [np.asarray(out.words())]
    if hasattr(out, "depths"):
        return [np.asarray(out.counts), np.asarray(out.depths)]
    return [np.asarray(out.to_grid().words())]


@pytest.mark.parametrize("name, options", OPTION_RUNS, ids=run_ids(OPTION_RUNS))
def test_no_method_stores_past_its_buffers(gl_context, monkeypatch, name, options):
    """An odd grid (rows end inside a word) and a larger one, with tiles where a method has
    them.  The guarded runs also hand out the buffers asked for without clearing full of
    0xDEADBEEF (GL leaves a new buffer's content undefined; llvmpipe's are zero), so a
    method that reads what it never wrote gives another result."""
    mesh = load_mesh("gen:bunny-like")
    cases = [(glvox.grid_for(mesh, n), extra)
             for n, extra in ((23, {}), (72, {"tile": 32} if "tile" in _options(name) else {}))]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = [_result(run_method(name, mesh, spec, **options, **extra)) for spec, extra in cases]
        with guarded(gl_context, monkeypatch) as check:
            for (spec, extra), want in zip(cases, plain):
                got = _result(run_method(name, mesh, spec, **options, **extra))
                assert check() == [], f"{name} {options} at {spec.dims}"
                for g, w in zip(got, want):
                    np.testing.assert_array_equal(g, w, err_msg=f"{name} {options} at {spec.dims}")


def _options(name):
    return next(i.options for i in method_infos() if i.name == name)


@pytest.mark.parametrize("name", ["ss-conservative", "ss-6sep", "ss-solid", "gwn-solid"])
def test_no_slab_stores_past_its_buffers(gl_context, monkeypatch, name):
    mesh, spec = slab_case(gl_context, monkeypatch)
    with guarded(gl_context, monkeypatch) as check:
        run_method(name, mesh, spec)
        assert check() == []
