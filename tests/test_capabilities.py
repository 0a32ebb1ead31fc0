"""Capability checks match what each method's shaders declare, per dimension.

GL guarantees compute work groups of 1024 x 1024 x 64 and 1024 invocations
(GL 4.5 core, Table 23.62); NVIDIA reports exactly that, Mesa reports
z = 1024.  A method is refused only for a limit one of its shaders exceeds,
read from the shaders' ``layout(local_size_*)``, ``shared`` arrays and
storage blocks (glvox.gl.workgroups), and every registered method is checked
against the published limits of real GPUs (glvox.testing.gl_limits).
"""

from __future__ import annotations

import ast

import pytest

import glvox
from glvox.errors import CapabilityError
from glvox.gl.workgroups import ComputeNeeds, compute_needs, needs_of_source
from glvox.mesh import load_mesh
from glvox.methods import method_infos, run_method
from glvox.methods.base import Requirements, alternative
from glvox.testing.gl_limits import PUBLISHED, FakeContext, published

GL_METHODS = [i for i in method_infos() if i.uses_gl]


@pytest.mark.parametrize("impl", [p for p in PUBLISHED if p.name != "gl45-minimum"], ids=lambda p: p.name)
def test_every_method_runs_on_published_gpus(impl):
    """No registered method refuses NVIDIA (z = 64), radeonsi, iris, llvmpipe, or
    an Intel-on-Windows-like context with the spec's z = 64 and 32 KiB shared."""
    ctx = FakeContext(impl)
    refused = {i.name: i.requires.missing(ctx) for i in GL_METHODS if i.requires.missing(ctx)}
    assert not refused, f"{impl.name} would refuse: {refused}"


def test_the_spec_minimum_refuses_only_for_storage_buffers():
    """On a bare GL 4.5 context (every limit at its Table 23 minimum, no extension
    listed), every method's compute shape fits: the only refusals are storage
    buffer bindings (8 guaranteed) and blocks per shader (8 guaranteed).  Pinned:
    a method that starts needing more shows up here."""
    ctx = FakeContext(published("gl45-minimum"))
    refused = {i.name: i.requires.missing(ctx) for i in GL_METHODS}
    for name, missing in refused.items():
        for m in missing:
            assert m.startswith(("GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS", "GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS")), (
                name, m)
    assert {n for n, m in refused.items() if m} == {
        "leung-wang-ldi", "ss-6sep", "ss-conservative", "ss-solid", "ss-solid-tiled", "ss-octree", "carve-solid",
        "gwn-solid", "vote-solid", "solid"}


def _fake(**limits):
    base = dict(published("llvmpipe").limits)
    base.update(limits)
    ctx = FakeContext(published("llvmpipe"))
    ctx.limits = lambda: base
    return ctx


def test_work_group_sizes_are_compared_per_dimension():
    """A 256 x 1 x 1 group fits (1024, 1024, 64); a 1 x 1 x 128 one does not, and
    the message names the dimension, the need and what the context has."""
    wide = Requirements(limits={"GL_MAX_COMPUTE_WORK_GROUP_SIZE": (256, 1, 1)})
    deep = Requirements(limits={"GL_MAX_COMPUTE_WORK_GROUP_SIZE": (1, 1, 128)})
    nv = FakeContext(published("nvidia-580"))
    assert wide.missing(nv) == []
    assert deep.missing(nv) == ["GL_MAX_COMPUTE_WORK_GROUP_SIZE z >= 128 (context has (1024, 1024, 64))"]
    assert deep.missing(FakeContext(published("intel-iris"))) == []


def test_a_scalar_need_for_a_per_dimension_limit_is_refused():
    """The old form, {"GL_MAX_COMPUTE_WORK_GROUP_SIZE": 256}, compared the minimum
    over x, y, z; it cannot be written any more."""
    with pytest.raises(ValueError, match="GL_MAX_COMPUTE_WORK_GROUP_SIZE is a 3-component limit"):
        Requirements(limits={"GL_MAX_COMPUTE_WORK_GROUP_SIZE": 256})


def test_invocations_and_shared_memory_come_from_the_shader():
    text = """#version 450
#ifndef WG
#define WG 8
#endif
#define ROWS (1u << 4)
const uint SEG = uint(WG) >= 64u ? 8u : 2u;
layout(local_size_x = WG, local_size_y = 4, local_size_z = 2) in;
layout(std430, binding = 5) buffer A { uint a[]; };
layout(std430, binding = 2) readonly buffer B { uint b[]; };
shared uint s_rows[ROWS * SEG];
shared uvec2 s_pairs[3];
void main() {}
"""
    need = needs_of_source(text)
    # hand-worked: 8 x 4 x 2 = 64 invocations; (16 * 2) * 4 + 3 * 8 = 152 bytes; 2 blocks, bindings 0..5
    assert need == ComputeNeeds((8, 4, 2), 64, 152, 2, 6)
    wide = needs_of_source(text.replace("#version 450\n", "#version 450\n#define WG 64\n"))
    assert wide.local_size == (64, 4, 2) and wide.invocations == 512 and wide.shared_bytes == (16 * 8) * 4 + 24
    too_many = Requirements(limits={"GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS": 2048,
                                    "GL_MAX_COMPUTE_SHARED_MEMORY_SIZE": 40000})
    assert too_many.missing(FakeContext(published("nvidia-580"))) == [
        "GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS >= 2048 (context has 1024)"]


def test_the_radix_scatter_shared_memory_is_read_from_its_defines():
    """sort/radix_scatter.comp with 8-bit digits and 32 invocations: s_cnt
    128 x 32, s_base 256, and common.glsl's raking scan (segment 4, 8 parts:
    32 + 9 words) -- 4393 words, under the 32 KiB GL guarantees."""
    need = compute_needs("sort/radix_scatter.comp", {"WG_SIZE": 32, "ITEMS": 256, "DIGIT_BITS": 8})
    assert need.local_size == (32, 1, 1)
    assert need.shared_bytes == 4 * (128 * 32 + 256 + 32 + 9)


def test_a_refusal_names_the_limit_and_what_runs_instead(gl_context, monkeypatch):
    """One line: the limit, what the context has, and a method of the same
    definition whose requirements the context meets."""
    limits = dict(gl_context.limits(), GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS=8)
    monkeypatch.setattr(gl_context, "limits", lambda: limits)
    mesh = load_mesh("gen:torus")
    with pytest.raises(CapabilityError, match=r"^method 'ss-conservative' needs GL_MAX_SHADER_STORAGE_BUFFER_"
                                              r"BINDINGS >= 9 \(context has 8\) \(.*\); 'eisemann-surface' runs "
                                              r"on this context instead$"):
        run_method("ss-conservative", mesh, glvox.grid_for(mesh, 8), ctx=gl_context)
    ctx = _fake(GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS=8)
    info = {i.name: i for i in GL_METHODS}
    assert alternative(info["carve-solid"], ctx) == "reference-carve"  # no GL carve fits: its CPU reference
    assert alternative(info["ss-solid"], ctx) == "eisemann-solid"


class _Recording(dict):
    """A program cache that records every key asked for (hits and misses)."""

    def __init__(self, base):
        super().__init__()
        self.base, self.seen = base, set()

    def get(self, key, default=None):
        self.seen.add(key)
        return self.base.get(key, default)

    def __setitem__(self, key, value):
        self.seen.add(key)
        self.base[key] = value


@pytest.mark.parametrize("info", GL_METHODS, ids=lambda i: i.name)
def test_declared_shaders_cover_what_a_run_compiles(gl_context, info, monkeypatch):
    """Every compute program a run asks for, with the defines it passes, fits
    the needs the method declares (so the check before the run is complete)."""
    mesh = load_mesh("gen:torus")
    rec = _Recording(gl_context.programs)
    monkeypatch.setattr(gl_context, "programs", rec)
    run_method(info.name, mesh, glvox.grid_for(mesh, 12), ctx=gl_context)
    monkeypatch.undo()
    declared = info.requires.compute_needs
    for kind, paths, defines, _ in rec.seen:
        if kind != "compute":
            continue
        need = compute_needs(paths[0], {k: ast.literal_eval(v) for k, v in defines})
        assert all(a <= b for a, b in zip(need.local_size, declared.local_size)), (paths[0], need, declared)
        assert need.invocations <= declared.invocations, (paths[0], need, declared)
        assert need.shared_bytes <= declared.shared_bytes, (paths[0], need, declared)
        assert need.storage_blocks <= declared.storage_blocks, (paths[0], need, declared)
        assert need.storage_bindings <= declared.storage_bindings, (paths[0], need, declared)
