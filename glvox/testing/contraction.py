"""A compiler that fuses ``a * b + c`` into one fma, emulated on any GL.

GLSL lets a compiler contract a product and a sum into one fma, with one
rounding instead of two, wherever the result is not ``precise`` (GLSL 4.50
Sec. 4.7.1).  glvox's exact shaders keep those results ``precise``
(common/edge.glsl has the convention), so a conforming compiler cannot.  To see
what a contracting compiler would do to them, :func:`write_overlay` writes
copies of ``common/edge.glsl`` and ``ss/setup.glsl`` whose cross product and
edge function are fused by hand, in the order that, of those tried, gives on
llvmpipe the needle results an NVIDIA H100 gave before they were ``precise``:

* a cross product's component ``a*b - c*d`` as ``fma(a, b, -(c*d))``;
* a 2D edge function ``(n.x*d.x + n.y*d.y) + o`` as ``fma(n.y, d.y, n.x*d.x) + o``.

``fma()`` itself cannot stand in for the fusion: Mesa's llvmpipe computes it
with two roundings (``glvox selftest``'s arithmetic row shows it on any GL), so
the overlay fuses in double, ``float(double(a) * double(b) + double(c))``: the
product of two float32 is exact in double, so only the sum rounds before the
float32 rounding (a double rounding, which differs from one fma only where the
double sum lands exactly halfway between two float32).

Point ``GLVOX_SHADER_PATH`` at the folder: its files come before glvox's own
when shaders are included (:mod:`glvox.gl.shaders`, "Preprocessing"), in
every program compiled from then on (use a fresh process: programs are cached
per context).  With it, the needle pins of ``tests/test_reliability.py`` give
what they gave on an NVIDIA H100 before the ``precise`` marks:
``test_gpu_needle_is_the_exact_set`` fails for every variant.  (The H100 also
passed the ss-6sep needles of width 5e-5 then, which were open here; since
``ss/setup.glsl`` takes a normal from the two shorter edges they pass fused or not.)
"""

from __future__ import annotations

import os
from pathlib import Path

from ..gl.shaders import builtin_shader_dir

#: The emulated fma of two float32 products and a sum (see the module docstring).
EMULATED_FMA = "#define FUSED(a, b, c) float(double(a) * double(b) + double(c))\n"

_CROSS = [("p.y", "q.z", "p.z", "q.y"), ("p.z", "q.x", "p.x", "q.z"), ("p.x", "q.y", "p.y", "q.x")]

#: file -> (text as glvox has it, the fused text)
SITES = {
    "common/edge.glsl": [
        ("// Inward edge normal", EMULATED_FMA + "// Inward edge normal"),
    ],
    "ss/setup.glsl": [
        ("precise vec3 n = vec3(" + ", ".join(f"{a} * {b} - {c} * {d}" for a, b, c, d in _CROSS) + ");",
         "precise vec3 n = vec3(" + ", ".join(f"FUSED({a}, {b}, -({c} * {d}))" for a, b, c, d in _CROSS) + ");"),
        ("precise float f = (n.x * d.x + n.y * d.y) + o;", "precise float f = FUSED(n.y, d.y, n.x * d.x) + o;"),
    ],
}


def write_overlay(folder: os.PathLike | str) -> Path:
    """Write the fused copies of the shaders in :data:`SITES` under ``folder``; returns it.

    Raises AssertionError when a site is no longer in glvox's shader as written
    here (the overlay would then fuse nothing)."""
    folder = Path(folder)
    for rel, pairs in SITES.items():
        text = (builtin_shader_dir() / rel).read_text()
        for old, new in pairs:
            assert text.count(old) == 1, f"{rel} no longer has {old!r}: update glvox.testing.contraction.SITES"
            text = text.replace(old, new)
        out = folder / rel
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
    return folder
