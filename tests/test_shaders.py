"""Shader loader (#include, defines, #line, errors, cache) and shared GLSL includes."""

from __future__ import annotations

import re

import numpy as np
import pytest
from conftest import run_ids

import glvox
from glvox.errors import ShaderError
from glvox.gl import shaders as loader
from glvox.gl.shaders import (LINE_BASE, MAX_INCLUDE_DEPTH, builtin_shader_dir, compute_program, preprocess,
                              render_program)
from glvox.gpu.dispatch import bind
from glvox.grid import GridSpec, pack_bits
from glvox.mesh import load_mesh
from glvox.methods import run_method
from glvox.results.voxels import VoxelGrid
from glvox.testing import run_compute


def write(tmp_path, name, text):
    p = tmp_path / name
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(text)
    return p


def test_builtin_shaders_are_found():
    root = builtin_shader_dir()
    assert (root / "common" / "bits.glsl").is_file()
    assert (root / "common" / "voxel_space.glsl").is_file()
    assert (root / "common" / "edge.glsl").is_file()


def test_defines_follow_version_then_line(tmp_path):
    top = write(tmp_path, "a.comp", "// header comment\n#version 450\nlayout(local_size_x=1) in;\nvoid main() {}\n")
    src = preprocess(top, {"FOO": 3, "FLAG": True, "SCALE": 0.5, "NAME": "vec3"})
    lines = src.text.splitlines()
    assert lines[0] == "#version 450"
    assert lines[1:5] == ["#define FOO 3", "#define FLAG 1", "#define SCALE 0.5", "#define NAME vec3"]
    assert lines[5] == "#line 3"  # the next line is line 3 of a.comp
    assert lines[6] == "layout(local_size_x=1) in;"


def test_bad_define_name_is_refused(tmp_path):
    top = write(tmp_path, "a.comp", "#version 450\nvoid main() {}\n")
    with pytest.raises(ShaderError, match=r"define name must be a GLSL identifier, got '2x'"):
        preprocess(top, {"2x": 1})


def test_include_is_recursive_relative_and_once(tmp_path):
    write(tmp_path, "lib/a.glsl", '#include "b.glsl"\nfloat a() { return b(); }\n')
    write(tmp_path, "lib/b.glsl", "float b() { return 1.0; }\n")
    top = write(tmp_path, "main.comp",
                '#version 450\n#include "lib/a.glsl"\n#include "lib/b.glsl"\nvoid main() {}\n')
    src = preprocess(top, search=[tmp_path])
    assert src.text.count("float b()") == 1  # b included once although asked twice
    assert [p.name for p in src.files] == ["main.comp", "a.glsl", "b.glsl"]
    assert "// begin include lib/a.glsl" in src.text


def test_include_cycle_is_harmless_thanks_to_include_once(tmp_path):
    write(tmp_path, "x.glsl", '#include "y.glsl"\nfloat x() { return 1.0; }\n')
    write(tmp_path, "y.glsl", '#include "x.glsl"\nfloat y() { return 2.0; }\n')
    top = write(tmp_path, "m.comp", '#version 450\n#include "x.glsl"\nvoid main() {}\n')
    src = preprocess(top, search=[tmp_path])
    assert src.text.count("float x()") == 1 and src.text.count("float y()") == 1


def test_include_depth_limit(tmp_path):
    n = MAX_INCLUDE_DEPTH + 2
    for i in range(n):
        write(tmp_path, f"d{i}.glsl", f'#include "d{i + 1}.glsl"\n' if i + 1 < n else "float z;\n")
    top = write(tmp_path, "m.comp", '#version 450\n#include "d0.glsl"\nvoid main() {}\n')
    with pytest.raises(ShaderError, match=rf"#include nested deeper than {MAX_INCLUDE_DEPTH} levels"):
        preprocess(top, search=[tmp_path])


def test_missing_include_names_the_file(tmp_path):
    top = write(tmp_path, "m.comp", '#version 450\n#include "nope.glsl"\nvoid main() {}\n')
    with pytest.raises(ShaderError, match=r"shader file 'nope.glsl' not found"):
        preprocess(top, search=[tmp_path])


def test_version_only_in_top_file(tmp_path):
    write(tmp_path, "v.glsl", "#version 450\n")
    top = write(tmp_path, "m.comp", '#version 450\n#include "v.glsl"\nvoid main() {}\n')
    with pytest.raises(ShaderError, match=r"#version may only appear in the top file"):
        preprocess(top, search=[tmp_path])
    nover = write(tmp_path, "n.comp", "void main() {}\n")
    with pytest.raises(ShaderError, match=r"must start with a #version line"):
        preprocess(nover)


def test_compile_error_in_include_names_file_and_line(gl_context, tmp_path):
    write(tmp_path, "helpers.glsl", "// helper\nfloat ok() { return 1.0; }\nfloat bad() { return undefined_name; }\n")
    top = write(tmp_path, "broken.comp",
                '#version 450\n#include "helpers.glsl"\nlayout(local_size_x = 1) in;\nvoid main() { float x = ok(); }\n')
    with pytest.raises(ShaderError) as err:
        compute_program(gl_context, str(top), search=[tmp_path])
    msg = str(err.value)
    assert "compiling" in msg and "broken.comp" in msg
    assert "helpers.glsl:3" in msg, msg  # file and line after includes
    assert "undefined_name" in msg


def test_compile_error_in_top_file_after_include_keeps_line(gl_context, tmp_path):
    write(tmp_path, "h.glsl", "float h1() { return 1.0; }\nfloat h2() { return 2.0; }\n")
    top = write(tmp_path, "t.comp",
                '#version 450\n#include "h.glsl"\nlayout(local_size_x = 1) in;\nvoid main() {\n  int y = nothing_here;\n}\n')
    with pytest.raises(ShaderError, match=r"t\.comp:5"):
        compute_program(gl_context, str(top), {"UNUSED": 1}, search=[tmp_path])


def test_link_error_names_the_files(gl_context, tmp_path):
    v = write(tmp_path, "l.vert", "#version 450\nout vec4 v_color;\nvoid main() { v_color = vec4(1); gl_Position = vec4(0); }\n")
    f = write(tmp_path, "l.frag", "#version 450\nin vec3 v_color;\nout vec4 o;\nvoid main() { o = vec4(v_color, 1); }\n")
    with pytest.raises(ShaderError, match=r"linking .*l\.vert.*l\.frag.* failed"):
        render_program(gl_context, str(v), str(f))


def test_program_cache_per_context_and_defines(gl_context):
    a = compute_program(gl_context, "testing/bits.comp")
    b = compute_program(gl_context, "testing/bits.comp")
    c = compute_program(gl_context, "testing/bits.comp", {"UNUSED_DEFINE": 1})
    assert a is b
    assert c is not a
    compiled = gl_context.compile_seconds
    compute_program(gl_context, "testing/bits.comp")
    assert gl_context.compile_seconds == compiled  # a cache hit compiles nothing


def test_line_encoding_maps_back():
    src = preprocess("testing/bits.comp")
    assert src.location(1 * LINE_BASE + 7).startswith("shaders/common/bits.glsl:7")
    assert src.location(12).startswith("shaders/testing/bits.comp:12")


# -- the shared includes, run on the GPU against numpy ------------------------


def _np_mask_from(lo):
    return np.where(lo >= 32, 0, (0xFFFFFFFF << np.minimum(lo, 31).astype(np.uint64)) & 0xFFFFFFFF)


def test_bits_helpers_match_numpy(gl_context):
    rng = np.random.default_rng(1)
    lo = np.concatenate([np.arange(33), rng.integers(0, 40, 200)]).astype(np.uint32)
    hi = np.concatenate([np.arange(33)[::-1], rng.integers(0, 40, 200)]).astype(np.uint32)
    n = len(lo)
    out = run_compute(gl_context, "testing/bits.comp", (n + 63) // 64,
                      buffers={0: lo, 1: hi, 2: (n * 4, np.uint32)}, read=[2],
                      uniforms={"u_count": n})[2].reshape(n, 4)
    lo64, hi64 = lo.astype(np.uint64), hi.astype(np.uint64)
    mask_from = _np_mask_from(lo64)
    mask_upto = np.where(hi64 >= 31, 0xFFFFFFFF, (np.uint64(1) << (hi64 + np.uint64(1))) - np.uint64(1))
    mask_range = np.where(lo64 > hi64, 0, mask_from & mask_upto)
    word = (hi64 * np.uint64(2654435761)) & np.uint64(0xFFFFFFFF)
    below = np.array([bin(int(w) & ((1 << int(i)) - 1 if i < 32 else 0xFFFFFFFF)).count("1")
                      for w, i in zip(word, lo64)])
    np.testing.assert_array_equal(out[:, 0], mask_from)
    np.testing.assert_array_equal(out[:, 1], mask_upto)
    np.testing.assert_array_equal(out[:, 2], mask_range)
    np.testing.assert_array_equal(out[:, 3], below)


@pytest.mark.parametrize("dims", [(1, 1, 1), (31, 2, 3), (32, 5, 4), (33, 7, 2), (70, 3, 9)])
def test_packed_layout_is_the_same_in_glsl_and_python(gl_context, dims):
    rng = np.random.default_rng(sum(dims))
    occ = rng.random(dims) < 0.3
    idx = np.argwhere(occ).astype(np.int32)
    # a few out-of-grid indices must be ignored by in_grid()
    outside = np.array([[-1, 0, 0], [dims[0], 0, 0], [0, dims[1], 0], [0, 0, -3]], dtype=np.int32)
    allidx = np.concatenate([idx, outside])
    vox = np.zeros((len(allidx), 4), dtype=np.int32)
    vox[:, :3] = allidx
    spec = GridSpec(dims, (0, 0, 0), 1.0)
    words = run_compute(gl_context, "testing/pack.comp", (len(vox) + 63) // 64,
                        buffers={0: vox, 1: (spec.n_words, np.uint32)}, read=[1],
                        uniforms={"u_count": len(vox), "u_dims": dims})[1]
    np.testing.assert_array_equal(words, pack_bits(occ).reshape(-1))
    assert VoxelGrid(words=words, spec=spec).equal(VoxelGrid(occ, spec))


def test_top_left_fill_rule_owns_every_point_once(gl_context):
    """A square cut into triangles two ways plus a fan around its center: every
    sample point of the open square (on shared edges and at shared vertices
    included) is owned by exactly one triangle; points outside by none."""
    c = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)]
    meshes = {
        "diag1": [c[0], c[1], c[2], c[0], c[2], c[3]],
        "diag2": [c[0], c[1], c[3], c[1], c[2], c[3]],
        "fan": [c[0], c[1], (2.0, 2.0), c[1], c[2], (2.0, 2.0), c[2], c[3], (2.0, 2.0), c[3], c[0], (2.0, 2.0)],
        # clockwise input order must not change ownership
        "diag1_cw": [c[0], c[2], c[1], c[0], c[3], c[2]],
    }
    g = np.arange(0.0, 4.01, 0.5)
    pts = np.array([(x, y) for x in g for y in g], dtype=np.float32)
    interior = (pts[:, 0] > 0) & (pts[:, 0] < 4) & (pts[:, 1] > 0) & (pts[:, 1] < 4)
    for name, tris in meshes.items():
        tri = np.array(tris, dtype=np.float32)
        owners = run_compute(gl_context, "testing/fill_rule.comp", (len(pts) + 63) // 64,
                             buffers={0: tri, 1: pts, 2: (len(pts), np.uint32)}, read=[2],
                             uniforms={"u_points": len(pts), "u_tris": len(tri) // 3})[2]
        assert np.all(owners[interior] == 1), (name, pts[interior][owners[interior] != 1])
        assert np.all(owners <= 1), name


# -- storage buffers bound by block name ------------------------------------------


def test_bind_by_block_name(gl_context):
    prog = compute_program(gl_context, "testing/bind.comp")
    n = 100
    target = gl_context.mgl.buffer(reserve=n * 4)
    decoy = gl_context.mgl.buffer(reserve=n * 4)
    try:
        target.clear()
        decoy.clear()
        # keyword order opposite to the declaration and to the binding numbers
        bind(prog, Decoy=decoy, Target=target)
        prog["u_count"].value = n
        prog.run((n + 63) // 64)
        got_target = np.frombuffer(target.read(), np.uint32)
        got_decoy = np.frombuffer(decoy.read(), np.uint32)
    finally:
        target.release()
        decoy.release()
    np.testing.assert_array_equal(got_target, 1000 + np.arange(n))
    np.testing.assert_array_equal(got_decoy, 2000 + np.arange(n))


def test_bind_refuses_an_undeclared_block_naming_the_file(gl_context):
    prog = compute_program(gl_context, "testing/bind.comp")
    buf = gl_context.mgl.buffer(reserve=4)
    try:
        with pytest.raises(ShaderError, match=r"shaders/testing/bind\.comp declares no storage block 'Targets'"):
            bind(prog, Targets=buf)
        # named in comments only: not declared
        for name in ("Ghost", "Phantom"):
            with pytest.raises(ShaderError, match=rf"bind\.comp declares no storage block '{name}'"):
                bind(prog, **{name: buf})
        # a uniform is no storage block
        with pytest.raises(ShaderError, match=r"declares no storage block 'u_count'"):
            bind(prog, u_count=buf)
    finally:
        buf.release()


def test_bind_skips_a_declared_but_inactive_block(gl_context):
    prog = compute_program(gl_context, "testing/bind.comp")
    assert "Unused" in preprocess("testing/bind.comp").storage_blocks
    if "Unused" in prog:
        pytest.skip("this driver keeps the unused storage block active (legal); nothing to skip")
    buf = gl_context.mgl.buffer(reserve=4)
    try:
        bind(prog, Unused=buf)  # no error: the GLSL declares it, the compiler dropped it
    finally:
        buf.release()


def test_bind_needs_a_program_from_the_loader(gl_context):
    prog = gl_context.mgl.compute_shader(preprocess("testing/bind.comp").text)
    buf = gl_context.mgl.buffer(reserve=4)
    try:
        with pytest.raises(ShaderError, match=r"bind\(\) needs a program built by glvox\.gl\.shaders"):
            bind(prog, Target=buf)
    finally:
        buf.release()
        prog.release()


# ---------------------------------------------------------------------------
# geometry shaders: outputs are undefined after EmitVertex()
# ---------------------------------------------------------------------------

_GS_OUT = re.compile(r"^\s*(?:flat\s+|noperspective\s+|smooth\s+)*out\s+(\w+)\s+(\w+)\s*;", re.M)


def _clobbering_emit(text: str) -> str:
    """A define that makes each ``EmitVertex();`` of a geometry shader's source leave its
    outputs holding 7777 afterwards: ``EmitVertex(); g_a = T(7777); ...; memoryBarrier();``
    (the preprocessor does not expand a macro inside its own expansion)."""
    outs = _GS_OUT.findall(text)
    assert outs, "a geometry shader without user outputs"
    return "EmitVertex(); " + " ".join(f"{name} = {typ}(7777);" for typ, name in outs) + " memoryBarrier"


GEOMETRY_SHADER_RUNS = [
    ("karabassi", {}),
    ("passalis-peel", {}),
    ("passalis-stencil", {}),
    ("binvox-solid", {"wire": False}),  # depth/raster.geom alone
    ("binvox-solid", {}),                # and binvox/wire.geom (-aw, the default)
    ("peel-ldi", {}),
]


@pytest.mark.parametrize("name, options", GEOMETRY_SHADER_RUNS, ids=run_ids(GEOMETRY_SHADER_RUNS))
def test_geometry_shaders_set_their_outputs_for_every_vertex(gl_context, monkeypatch, name, options):
    """GLSL 4.50 Sec. 8.16: "On return from [EmitVertex], the values of all output
    variables are undefined."  Mesa's llvmpipe keeps them, a GPU's compiler need not, and a
    flat output is read from each primitive's provoking vertex (the last, by default): a
    shader that sets its flat outputs once before emitting three or four vertices hands the
    fragments whatever the hardware left there.  With every output overwritten right after
    each EmitVertex (a define named EmitVertex, compiled into the methods' own programs), the
    methods that draw through geometry shaders must give the same result."""
    mesh = load_mesh("gen:torus")
    spec = glvox.grid_for(mesh, 24)
    want = run_method(name, mesh, spec, **options)
    real = loader.preprocess
    geometry = []

    def clobbering(path, defines=None, search=(), *args, **kwargs):
        if not str(path).endswith(".geom"):
            return real(path, defines, search, *args, **kwargs)
        plain = real(path, defines, search, *args, **kwargs)
        geometry.append(str(path))
        return real(path, {**(defines or {}), "EmitVertex": _clobbering_emit(plain.text)}, search, *args, **kwargs)

    monkeypatch.setattr(loader, "preprocess", clobbering)
    monkeypatch.setattr(gl_context, "programs", {})  # compile them again, with the define
    got = run_method(name, mesh, spec, **options)
    assert geometry, f"{name} drew through no geometry shader"
    if name == "peel-ldi":
        assert want.counts.any()
        np.testing.assert_array_equal(got.counts, want.counts, err_msg=name)
        np.testing.assert_array_equal(got.depths, want.depths, err_msg=name)
    else:
        assert want.count > 0
        np.testing.assert_array_equal(got.words(), want.words(), err_msg=f"{name}: {sorted(set(geometry))}")
