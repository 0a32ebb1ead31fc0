"""The tie probe (glvox.testing.tie_probe): the double arithmetic that decides ties in the
exact solids, on this GL against its float64 model, and that the comparison can fail.

What it rests on: GLSL 4.50 Sec. 4.7.1 asks double operations for no more than single
precision; glvox's exact solids need the GPU to add, subtract, multiply and compare
doubles as IEEE 754 does (the CPU references do), and ``precise`` (Sec. 4.9) to keep the
compiler from fusing or reordering them.  The probe checks exactly that, on the values
that decide the tie cases of ``glvox selftest``.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from glvox.gl.shaders import builtin_shader_dir

from glvox.study.selftest import tie_cases
from glvox.testing import tie_probe
from glvox.testing.tie_probe import KINDS, TRACED, WORDS, probe, trace


@pytest.mark.parametrize("index", range(len(tie_cases())), ids=[c[0] for c in tie_cases()])
def test_this_gl_decides_every_tie_as_the_float64_model(gl_context, index):
    label, mesh, spec = tie_cases()[index]
    pairs, diffs = probe(gl_context, mesh, spec)
    assert pairs >= len(KINDS) * len(mesh.faces) and not diffs, [str(d) for d in diffs[:5]]


def test_the_tie_cases_put_centers_on_edges(gl_context):
    """The probe looks where it matters: every case has a pair of a triangle that takes part
    whose center lies on one of its edges up to double rounding (an edge function within 1e-12
    of zero), and both families meet edge functions that are exactly zero, where the top-left
    flag decides (the boxes on center planes; the tetrahedron's, whose vertices are thirds, is
    5.6e-17 along eisemann's render axis)."""
    exact = {"ss": 0, "eis": 0}
    for label, mesh, spec in tie_cases():
        near = False
        for family in exact:
            tris, centers = tie_probe.triangles(mesh, spec, family)
            words = tie_probe.model(family, tris, centers)
            part = words[:, 0:1] == 1
            f = np.ascontiguousarray(words[:, 3:9]).view(np.float64)
            exact[family] += int((part & (f == 0)).sum())
            near |= bool((part & (np.abs(f) <= 1e-12)).any())
        assert near, label
    assert exact["ss"] > 0 and exact["eis"] > 0, exact


def test_a_model_that_differs_is_named_with_the_quantity(gl_context):
    """With the model's top-left rule turned around, the probe names the pairs, the flags and,
    where a zero edge function decided, the verdict."""
    def turned(family, tris, centers):
        words = tie_probe.model(family, tris, centers)
        words[:, 9:12] ^= np.uint32(1)
        return words

    label, mesh, spec = tie_cases()[1]
    pairs, diffs = probe(gl_context, mesh, spec, model_fn=turned)
    assert diffs and {d.kind for d in diffs} == {k for k, _, _ in KINDS}
    assert all("top-left flags" in d.fields for d in diffs)
    assert all(d.gpu.shape == (WORDS,) for d in diffs)
    assert "ss-solid (compute): triangle" in str(diffs[0])


@pytest.mark.parametrize("index", range(len(tie_cases())), ids=[c[0] for c in tie_cases()])
def test_the_methods_own_passes_decide_as_the_model(gl_context, index):
    """ss-solid's voxelize pass and eisemann-solid's render, traced, flip exactly the
    (triangle, column) pairs the float64 model covers, from the model's first voxel, and
    the render draws a fragment over every one of them (what GL guarantees there: GL 4.6
    Sec. 14.6.1 covers every pixel center inside a polygon, and the proxies are grown past
    the vertex snap)."""
    label, mesh, spec = tie_cases()[index]
    pairs, diffs = trace(gl_context, mesh, spec)
    assert not diffs, [str(d) for d in diffs[:5]]
    assert pairs > 0 or label.startswith("tetrahedron")


def _covers_ties(family, tris, centers):
    """The model with every tie (a zero edge function) decided the other way."""
    words = tie_probe.model(family, tris, centers)
    f = np.ascontiguousarray(words[:, 3:9]).view(np.float64)
    words[:, 12] ^= ((words[:, 0] == 1) & (f == 0).any(axis=1)).astype(np.uint32)
    return words


def test_a_pass_that_differs_from_the_model_is_named(gl_context):
    """Against a model that decides every tie the other way, the traces of both passes
    name the pairs: covered by the pass and not by the model, or the other way round."""
    label, mesh, spec = tie_cases()[1]
    pairs, diffs = trace(gl_context, mesh, spec, model_fn=_covers_ties)
    assert {d.kind for d in diffs} == {k for k, _ in TRACED}
    whats = {d.what.split(" (")[0].split(",")[0] for d in diffs}
    assert "covered by the pass" in str(diffs) and "the model covers" in str(diffs), whats
    assert str(diffs[0]).startswith("ss-solid voxelize: triangle ")


#: Overlays that break one step of eisemann-solid's render after another, and what the trace
#: must then say (and only that): (file, text, replacement, the words of every difference).
BROKEN_STEPS = {
    "proxies shrunk": ("eisemann/setup.comp", "#define EIS_GROW 0.0625", "#define EIS_GROW -0.25",
                       "no fragment drawn"),
    "masks a slice late": ("eisemann/masks.glsl", "ivec4 lo = clamp(ivec4(first - 128 * t)",
                           "ivec4 lo = clamp(ivec4(first + 1 - 128 * t)", "the masks written or the logic op"),
    "pack flips a bit": ("eisemann/pack.comp", "grid[row_word(j, s0 + c, x_word)] = a[c][ch];",
                         "grid[row_word(j, s0 + c, x_word)] = a[c][ch] ^ 1u;", "(the pack)"),
}


@pytest.mark.parametrize("step", sorted(BROKEN_STEPS))
def test_the_trace_names_the_step_of_the_render_that_differs(tmp_path, step):
    """With one step of eisemann's render broken (a shader overlay through GLVOX_SHADER_PATH),
    the trace names that step and no other, while the probe, which evaluates the tie
    functions without the render, stays clean: shrunk proxies leave centers on and near the
    edges without a fragment (the rasterizer), masks a slice late make targets that are not
    the XOR of the fragments drawn (the fragment's masks or the logic op), and a pack that
    flips a bit makes a grid that is not the targets' masks."""
    rel, old, new, words = BROKEN_STEPS[step]
    text = (builtin_shader_dir() / rel).read_text()
    assert text.count(old) == 1
    (tmp_path / rel).parent.mkdir(parents=True)
    (tmp_path / rel).write_text(text.replace(old, new))
    script = (
        "from glvox.gl.context import get_context\n"
        "from glvox.study.selftest import tie_cases\n"
        "from glvox.testing.tie_probe import probe, trace\n"
        "ctx = get_context()\n"
        "label, mesh, spec = tie_cases()[3]\n"
        "print(len(probe(ctx, mesh, spec)[1]))\n"
        "for d in trace(ctx, mesh, spec)[1]: print(d)\n")
    env = {**os.environ, "GLVOX_SHADER_PATH": str(tmp_path)}
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.splitlines()
    assert lines[0] == "0" and len(lines) > 1, proc.stdout[-2000:]
    assert all(line.startswith("eisemann-solid render: ") and words in line for line in lines[1:]), lines[:5]
