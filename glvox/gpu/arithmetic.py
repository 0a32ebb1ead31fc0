"""What this GL's shader compiler does to the arithmetic glvox's exact shaders rest on.

glvox's exact GPU methods compute every decision with float32 or double
products and sums kept in ``precise`` variables (common/edge.glsl has the
convention).  GLSL 4.50 Sec. 4.9 then forbids the compiler to fuse ``a * b + c``
into one fma or to reorder it; without ``precise``, Sec. 4.7.1 allows both.
A compiler that fuses despite ``precise`` moves the decisions of needles and
ties, so the exact methods can differ from the CPU references there.

:func:`probe_arithmetic` measures this on the current context with
``shaders/testing/arithmetic.comp``: probes whose two-rounding result is 0 and
whose fused result is the rounding error of ``a * b``, in float32 and double, in
an expression and in a helper's precise local, beside an ``fma()`` control that
shows the probes can see a fusion at all.  It also reports (without failing)
whether plain expressions are fused, the ulp error of ``a / b`` (GLSL allows
2.5) and whether float32 denormals survive a product.  ``glvox selftest``
prints it as its first row.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..gl.shaders import compute_program
from .dispatch import barrier, bind, set_uniforms

SHADER = "testing/arithmetic.comp"
LOCAL_SIZE = 64
#: Probes of each kind; random operands, most of whose products are inexact.
PROBES = 4096
#: A float32 whose square is a denormal (1e-40): kept or flushed to zero.
TINY = np.float32(1e-20)


@dataclass
class ArithmeticReport:
    """What :func:`probe_arithmetic` found.

    ``fused_precise_float`` / ``fused_precise_double``: probes whose ``precise``
    expression (or helper local) came back fused: must be 0.  ``control_float``
    / ``control_double``: probes whose ``fma()`` came back with the rounding
    error (the probe's power to see a fusion; 0 means it cannot).
    ``fused_plain_float`` / ``fused_plain_double``: the same expressions without
    ``precise`` (allowed).  ``division_ulp``: the largest error of ``a / b`` in
    units in the last place.  ``denormals_kept``: float32 denormal products survive.
    """

    probes: int
    fused_precise_float: int
    fused_precise_double: int
    control_float: int
    control_double: int
    fused_plain_float: int
    fused_plain_double: int
    division_ulp: float
    denormals_kept: bool
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """``precise`` kept in float32 and double."""
        return self.fused_precise_float == 0 and self.fused_precise_double == 0


def probe_operands(n: int = PROBES, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """float32 (n, 4) and float64 (n, 4) operands (a, b, c, d): c = -fl(a * b), d = 1."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(0.5, 2.0, n) * np.where(rng.random(n) < 0.5, -1.0, 1.0)
    b = rng.uniform(0.5, 2.0, n)
    f = np.empty((n, 4), np.float32)
    f[:, 0], f[:, 1] = a, b
    f[:, 2] = -(f[:, 0] * f[:, 1])  # float32 product, rounded once
    f[:, 3] = 1.0
    d = np.empty((n, 4), np.float64)
    d[:, 0], d[:, 1] = a * (1 + 2.0**-30), b * (1 - 2.0**-29)  # full 53-bit mantissas
    d[:, 2] = -(d[:, 0] * d[:, 1])
    d[:, 3] = 1.0
    return f, d


def _product_error(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> np.ndarray:
    """a * b - p exactly (Dekker's product with Veltkamp's split, float64; p = fl(a * b))."""
    def split(x):
        t = 134217729.0 * x  # 2^27 + 1
        hi = t - (t - x)
        return hi, x - hi
    ah, al = split(a)
    bh, bl = split(b)
    return ((ah * bh - p) + ah * bl + al * bh) + al * bl


def classify(f: np.ndarray, d: np.ndarray, fout: np.ndarray, dout: np.ndarray, extra: np.ndarray,
             tiny: np.float32 = TINY) -> ArithmeticReport:
    """The report from the operands and what the shader returned (no GL: testable alone)."""
    f_err = (f[:, 0].astype(np.float64) * f[:, 1] + f[:, 2]).astype(np.float32)  # exact in float64, rounded once
    d_err = _product_error(d[:, 0], d[:, 1], -d[:, 2])
    f_can, d_can = f_err != 0, d_err != 0  # probes where fused and unfused differ

    def fused(values, err, can):
        return int(np.count_nonzero(can & (values == err) & (values != 0)))

    kept_f = np.count_nonzero(fout[:, 0] != 0) + np.count_nonzero(fout[:, 3] != 0)
    kept_d = np.count_nonzero(dout[:, 0] != 0) + np.count_nonzero(dout[:, 3] != 0)
    exact_q = f[:, 0].astype(np.float64) / f[:, 1].astype(np.float64)
    ulp = np.spacing(np.abs(exact_q.astype(np.float32))).astype(np.float64)
    div_ulp = float(np.max(np.abs(extra[:, 0].astype(np.float64) - exact_q) / ulp))
    denormal = np.float32(np.float64(tiny) * np.float64(tiny))
    report = ArithmeticReport(
        probes=len(f), fused_precise_float=int(kept_f), fused_precise_double=int(kept_d),
        control_float=fused(fout[:, 2], f_err, f_can), control_double=fused(dout[:, 2], d_err, d_can),
        fused_plain_float=fused(fout[:, 1], f_err, f_can), fused_plain_double=fused(dout[:, 1], d_err, d_can),
        division_ulp=div_ulp, denormals_kept=bool(np.all(extra[:, 1] == denormal)))
    if report.fused_precise_float or report.fused_precise_double:
        report.notes.append(
            f"the compiler fuses a*b+c inside precise expressions ({report.fused_precise_float} float32, "
            f"{report.fused_precise_double} double of {2 * len(f)} probes each): GLSL 4.50 Sec. 4.9 forbids it, "
            "and glvox's exact methods can then differ from the CPU references on needles and ties")
    if not report.control_float or not report.control_double:
        which = " and ".join(k for k, v in (("float32", report.control_float), ("double", report.control_double))
                             if not v)
        report.notes.append(f"fma() is not single-rounding in {which} here, so these probes cannot see a "
                            "fusion there (nothing is known either way)")
    report.notes.append(
        f"plain (not precise) a*b+c fused in {report.fused_plain_float} float32 and {report.fused_plain_double} "
        f"double probes of {len(f)} (GLSL allows it; glvox keeps exact arithmetic precise)")
    report.notes.append(f"a / b: at most {report.division_ulp:.2f} ulp (GLSL 4.50 allows 2.5)")
    report.notes.append(f"float32 denormal products are {'kept' if report.denormals_kept else 'flushed to zero'}")
    return report


def probe_arithmetic(ctx, n: int = PROBES) -> ArithmeticReport:
    """Run the probes on ``ctx`` (a :class:`~glvox.gl.context.GLContext`)."""
    f, d = probe_operands(n)
    prog = compute_program(ctx, SHADER)
    set_uniforms(prog, {"u_count": n, "u_tiny": float(TINY)})
    mgl = ctx.mgl
    bufs = {"Floats": mgl.buffer(f.tobytes()), "Doubles": mgl.buffer(d.tobytes()),
            "FloatOut": mgl.buffer(reserve=f.nbytes), "DoubleOut": mgl.buffer(reserve=d.nbytes),
            "Extra": mgl.buffer(reserve=n * 8)}
    try:
        bind(prog, **bufs)
        prog.run((n + LOCAL_SIZE - 1) // LOCAL_SIZE)
        barrier(ctx)  # the shader's stores, before glGetBufferSubData reads them
        fout = np.frombuffer(bufs["FloatOut"].read(), np.float32).reshape(n, 4)
        dout = np.frombuffer(bufs["DoubleOut"].read(), np.float64).reshape(n, 4)
        extra = np.frombuffer(bufs["Extra"].read(), np.float32).reshape(n, 2)
    finally:
        for b in bufs.values():
            b.release()
    return classify(f, d, fout, dout, extra)
