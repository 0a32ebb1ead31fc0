"""The compiler probe of ``glvox selftest`` (glvox.gpu.arithmetic): its verdicts on
hand-made shader outputs, its exact error terms, and its run on this GL."""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from glvox.gpu.arithmetic import PROBES, _product_error, classify, probe_arithmetic, probe_operands


def _outputs(f, d, *, fused_float=(), fused_double=(), control=True):
    """Shader outputs as a compiler gives them: 0 for each unfused probe, the rounding
    error for the columns named fused (0 precise, 1 plain, 2 fma, 3 helper)."""
    n = len(f)
    f_err = (f[:, 0].astype(np.float64) * f[:, 1] + f[:, 2]).astype(np.float32)
    d_err = _product_error(d[:, 0], d[:, 1], -d[:, 2])
    fout, dout = np.zeros((n, 4), np.float32), np.zeros((n, 4))
    for col in fused_float + ((2,) if control else ()):
        fout[:, col] = f_err
    for col in fused_double + ((2,) if control else ()):
        dout[:, col] = d_err
    extra = np.stack([(f[:, 0].astype(np.float64) / f[:, 1]).astype(np.float32),
                      np.full(n, np.float32(1e-40), np.float32)], axis=1)
    return fout, dout, extra


def test_the_probes_tell_fused_from_unfused():
    """Nearly every probe's product is inexact, so a fusion shows in nearly every one."""
    f, d = probe_operands()
    f_err = f[:, 0].astype(np.float64) * f[:, 1] + f[:, 2]
    assert np.count_nonzero(f_err) > 0.9 * PROBES
    assert np.count_nonzero(_product_error(d[:, 0], d[:, 1], -d[:, 2])) > 0.9 * PROBES
    assert np.all((f[:, 0] * f[:, 1] + f[:, 2]) == 0)  # two roundings: 0 by construction


def test_the_double_error_term_is_exact():
    f, d = probe_operands(64, seed=3)
    err = _product_error(d[:, 0], d[:, 1], -d[:, 2])
    for a, b, c, e in zip(d[:, 0], d[:, 1], d[:, 2], err):
        assert Fraction(float(e)) == Fraction(float(a)) * Fraction(float(b)) + Fraction(float(c))


def test_an_unfusing_compiler_passes():
    f, d = probe_operands()
    r = classify(f, d, *_outputs(f, d))
    assert r.ok and r.fused_precise_float == r.fused_precise_double == 0
    assert r.control_float > 0.9 * PROBES and r.control_double > 0.9 * PROBES
    assert r.fused_plain_float == 0 and r.division_ulp <= 0.5 and r.denormals_kept


def test_fusing_a_precise_expression_or_helper_fails():
    f, d = probe_operands()
    for fused_float, fused_double in (((0,), ()), ((3,), ()), ((), (0,)), ((), (3,))):
        r = classify(f, d, *_outputs(f, d, fused_float=fused_float, fused_double=fused_double))
        assert not r.ok, (fused_float, fused_double)
        assert r.fused_precise_float + r.fused_precise_double > 0.9 * PROBES
        assert "inside precise expressions" in r.notes[0]


def test_plain_fusion_and_a_blind_control_are_reported_not_failed():
    f, d = probe_operands()
    r = classify(f, d, *_outputs(f, d, fused_float=(1,), fused_double=(1,), control=False))
    assert r.ok and r.fused_plain_float > 0.9 * PROBES and r.fused_plain_double > 0.9 * PROBES
    assert r.control_float == r.control_double == 0
    assert any("cannot see a fusion" in n for n in r.notes)


def test_this_gl_keeps_precise_and_divides_within_the_glsl_bound(gl_context):
    """GLSL 4.50 Sec. 4.9 (precise) and Sec. 4.7.1 (a / b within 2.5 ulp) hold on any
    conforming GL; whether this one's fma() rounds once is its own affair (reported)."""
    r = probe_arithmetic(gl_context)
    assert r.ok, r.notes
    assert r.division_ulp <= 2.5
