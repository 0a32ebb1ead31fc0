"""The tie probe (glvox.testing.tie_probe): the double arithmetic that decides ties in the
exact solids, on this GL against its float64 model, and that the comparison can fail.

What it rests on: GLSL 4.50 Sec. 4.7.1 asks double operations for no more than single
precision; glvox's exact solids need the GPU to add, subtract, multiply and compare
doubles as IEEE 754 does (the CPU references do), and ``precise`` (Sec. 4.9) to keep the
compiler from fusing or reordering them.  The probe checks exactly that, on the values
that decide the tie cases of ``glvox selftest``.
"""

from __future__ import annotations

import numpy as np
import pytest

from glvox.study.selftest import tie_cases
from glvox.testing import tie_probe
from glvox.testing.tie_probe import KINDS, WORDS, probe


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
