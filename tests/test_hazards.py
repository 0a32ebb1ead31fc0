"""Memory barriers: every command that reads what a shader stored waits for it, on any driver.

llvmpipe finishes each command before the next, so a missing glMemoryBarrier changes
nothing here; a GPU overlaps commands and caches, and reads stale words.
:mod:`glvox.testing.hazards` traces the incoherent stores and the barriers of a run;
these tests check the tracer on hand-made cases first, then hold every GL method (with
each value of its choice options, and the paths that tiles, slabs, attributes, fields
and the SDF take) to no hazard.  The rule they rest on: GL 4.5 core Sec. 7.12.2, a
shader's stores to buffer memory are seen by later commands only after a barrier with
the bit for the way they read it; atomic operations see earlier atomic operations.
"""

from __future__ import annotations

import warnings

import moderngl
import numpy as np
import pytest
from conftest import gl_option_runs, run_ids, slab_case

import glvox
from glvox.cli import main as cli_main
from glvox.gl.shaders import active_text, compute_program, preprocess, program_source
from glvox.gpu.dispatch import barrier, bind
from glvox.mesh import load_mesh
from glvox.methods import run_method
from glvox.testing import run_compute
from glvox.testing.hazards import trace

WRITER = """#version 450
layout(local_size_x = 64) in;
layout(std430, binding = 0) writeonly buffer Out { uint data[]; };
void main() { data[gl_GlobalInvocationID.x] = gl_GlobalInvocationID.x; }
"""
READER = """#version 450
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer In { uint data[]; };
layout(std430, binding = 1) buffer Sum { uint total[]; };
void main() { atomicAdd(total[0], data[gl_GlobalInvocationID.x]); }
"""
ADDER = """#version 450
layout(local_size_x = 64) in;
layout(std430, binding = 1) buffer Sum { uint total[]; };
void main() { atomicAdd(total[0], 1u); }
"""


@pytest.fixture
def programs(gl_context, tmp_path):
    for name, text in (("w.comp", WRITER), ("r.comp", READER), ("a.comp", ADDER)):
        (tmp_path / name).write_text(text)
    get = lambda name: compute_program(gl_context, name, search=[tmp_path])  # noqa: E731
    data = gl_context.mgl.buffer(reserve=256 * 4)
    total = gl_context.mgl.buffer(reserve=4)
    yield get("w.comp"), get("r.comp"), get("a.comp"), data, total
    data.release()
    total.release()


def test_a_read_without_the_barrier_is_a_hazard(gl_context, programs):
    write, read, _, data, total = programs
    with trace() as t:
        bind(write, Out=data)
        write.run(4)
        bind(read, In=data, Sum=total)
        read.run(4)
    assert len(t.hazards) == 1, t.describe()
    assert "block In" in t.describe() and "r.comp" in t.describe() and "w.comp" in t.describe()
    gl_context.mgl.memory_barrier()


def test_the_barrier_clears_it_and_only_with_the_right_bit(gl_context, programs):
    write, read, _, data, total = programs
    with trace() as t:
        bind(write, Out=data)
        write.run(4)
        barrier(gl_context)
        bind(read, In=data, Sum=total)
        read.run(4)
        barrier(gl_context)
        total.read()
    assert not t.hazards, t.describe()
    with trace() as t:
        bind(write, Out=data)
        write.run(4)
        gl_context.mgl.memory_barrier(moderngl.COMMAND_BARRIER_BIT)  # not the storage bit
        bind(read, In=data, Sum=total)
        read.run(4)
        total.read()  # glGetBufferSubData needs BUFFER_UPDATE_BARRIER_BIT after the atomics
    assert [h.read_as for h in t.hazards] == ["storage", "update"], t.describe()
    gl_context.mgl.memory_barrier()


def test_atomics_after_atomics_need_no_barrier(gl_context, programs):
    _, read, add, data, total = programs
    data.clear()
    with trace() as t:
        bind(add, Sum=total)
        add.run(4)
        add.run(4)  # atomicAdd on what atomicAdd wrote: no hazard
        bind(read, In=data, Sum=total)
        read.run(4)  # also atomic on Sum; reads In, which no shader wrote
    assert not t.hazards, t.describe()
    gl_context.mgl.memory_barrier()


def test_access_follows_the_selected_branches():
    text = ("#define MODE 2\n#if MODE == 1 && !defined(X)\nbuffer A { uint a[]; };\n#elif MODE == 2\n"
            "readonly buffer A { uint a[]; };\n#else\nbuffer B { uint b[]; };\n#endif\n"
            "#ifdef UNKNOWN\nbuffer C { uint c[]; };\n#endif\n#if SOMETHING(1)\nbuffer D { uint d[]; };\n#endif\n")
    lines = active_text(text).split("\n")
    assert len(lines) == len(text.split("\n"))
    kept = [line for line in lines if line]
    # the MODE == 2 branch; D's condition cannot be evaluated here, so it is kept
    assert kept == ["readonly buffer A { uint a[]; };", "buffer D { uint d[]; };"]
    src = preprocess("depth/record.comp", {"CLASSIFIABLE_COUNT": 2, "STENCIL_MODE": 2})
    assert src.storage_access == {"Flips": (True, True, True), "Crowded": (False, True, False)}
    assert {"Flips", "Stats", "Crowded"} <= src.storage_blocks  # bind() still knows every block


OPTION_RUNS = gl_option_runs()


def _hazards_of(fn) -> str:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with trace() as t:
            out = fn()
            if hasattr(out, "words"):
                out.words()
    assert t.commands > 0
    return "" if not t.hazards else t.describe()


@pytest.mark.parametrize("name, options", OPTION_RUNS, ids=run_ids(OPTION_RUNS))
def test_every_method_waits_for_the_stores_it_reads(gl_context, name, options):
    mesh = load_mesh("gen:torus")
    spec = glvox.grid_for(mesh, 40)
    assert _hazards_of(lambda: run_method(name, mesh, spec, **options)) == ""


@pytest.mark.parametrize("name, options", [
    ("karabassi", {"tile": 32}), ("passalis-peel", {"tile": 32}), ("passalis-stencil", {"tile": 32}),
    ("binvox-solid", {"tile": 32}), ("eisemann-solid", {"tile": 32}), ("leung-wang-ldi", {"tile": 32}),
    ("peel-ldi", {"tile": 32}), ("gwn-solid", {"winding": True}), ("gwn-solid", {"shell": True}),
    ("carve-solid", {"close": True}), ("ss-octree", {"walls": True}),
])
def test_tiles_fields_and_options_wait_too(gl_context, name, options):
    mesh = load_mesh("gen:torus")
    spec = glvox.grid_for(mesh, 72)
    assert _hazards_of(lambda: run_method(name, mesh, spec, **options)) == ""


@pytest.mark.parametrize("name", ["ss-conservative", "ss-6sep", "ss-solid", "gwn-solid"])
def test_slabs_wait_too(gl_context, monkeypatch, name):
    mesh, spec = slab_case(gl_context, monkeypatch)
    assert _hazards_of(lambda: run_method(name, mesh, spec)) == ""


def test_attributes_and_the_sdf_wait_too(gl_context):
    mesh = load_mesh("gen:torus")
    spec = glvox.grid_for(mesh, 40)
    for name in ("ss-conservative", "ss-solid", "eisemann-solid"):
        assert _hazards_of(lambda: run_method(name, mesh, spec, attributes=["triangle", "normal"],
                                              fill_attributes="nearest" if name != "ss-conservative" else "none")) == ""
    assert _hazards_of(lambda: glvox.sdf(mesh, 32)) == ""
    assert np.isfinite(glvox.sdf(mesh, 16).sdf).any()


def test_the_access_map_covers_every_block_the_compiler_keeps(gl_context):
    """The tracer reads each block's access from the #if branches it evaluates itself
    (glvox.gl.shaders.active_text); every storage block the GL program keeps active must
    be in that map, or the evaluation dropped a branch the compiler took."""
    mesh = load_mesh("gen:torus")
    spec = glvox.grid_for(mesh, 16)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, options in OPTION_RUNS:
            run_method(name, mesh, spec, **options)
    checked = 0
    for prog in list(gl_context.programs.values()):
        src = program_source(prog)
        if src is None:
            continue
        active = {n for n in prog if isinstance(prog[n], moderngl.StorageBlock)}
        assert active <= set(src.storage_access), f"{src.name}: {active - set(src.storage_access)}"
        checked += bool(active)
    assert checked >= 50


def test_the_harness_and_the_selftest_wait_too(gl_context, tmp_path, capsys):
    """run_compute (the harness users test their shaders with) reads its buffers after a
    barrier, and so does every probe of ``glvox selftest`` (the arithmetic, the tie probe,
    the read-back), which is what users run on a GPU glvox has not met."""
    (tmp_path / "twice.comp").write_text(
        "#version 450\nlayout(local_size_x = 64) in;\n"
        "layout(std430, binding = 0) readonly buffer In { uint a[]; };\n"
        "layout(std430, binding = 1) writeonly buffer Out { uint b[]; };\n"
        "void main() { uint i = gl_GlobalInvocationID.x; b[i] = 2u * a[i]; }\n")
    values = np.arange(256, dtype=np.uint32)
    with trace() as t:
        out = run_compute(gl_context, "twice.comp", 4, buffers={"In": values, "Out": (256, np.uint32)},
                          read=["Out"], search=[tmp_path])
    np.testing.assert_array_equal(out["Out"], 2 * values)
    assert t.commands >= 2 and not t.hazards, t.describe()
    with trace() as t:
        assert cli_main(["selftest", "-q", "--methods", "ss-conservative"]) == 0
    capsys.readouterr()
    assert t.commands > 100 and not t.hazards, t.describe()
