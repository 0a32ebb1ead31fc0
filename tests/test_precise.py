"""Exact arithmetic in the shaders does not depend on the compiler (static check).

Convention: a GLSL function whose result is claimed exact (or bit-identical to a CPU
reference or to another pass) carries a ``// exact:`` comment line right above its
signature.  Inside it, every statement that computes a product-sum (a ``*`` and a
binary ``+`` or ``-``: what a compiler may fuse into one fma) must store it in a
``precise`` variable, declared precise in that same function; a ``return`` may not
compute one, and ``dot``/``cross``/``fma`` are not used (write the terms out).

The guarantee this rests on is GLSL 4.50 Sec. 4.9: an r-value consumed by an l-value
qualified ``precise`` in the same function is evaluated in its stated order, and
``a * b + c`` is not allowed to become ``fma(a, b, c)``.  Without ``precise``,
Sec. 4.7.1 allows either, so "exact" would depend on the compiler (NVIDIA's results
differed from llvmpipe's).  A helper's return value is not covered by the caller's
``precise`` (Sec. 4.9), hence the rule on ``return``.  llvmpipe does not seem to
contract, so the GPU tests cannot show a missing ``precise``: this scan does.

Limits, stated: the scan is lexical.  It does not follow a product computed in one
non-precise statement and added in another; a precise consumer covers such a product
anyway (Sec. 4.9: "operations contributing to a variable's value").
"""

from __future__ import annotations

import re

import pytest

from glvox.gl.shaders import builtin_shader_dir

# Families whose shaders compute exact predicates: each must mark at least these
# functions (a sentinel that the convention is in use where the issue found the drift).
REQUIRED = {
    "common/edge.glsl": {"edge_normal", "edge_box_term_conservative", "edge_box_term_6sep"},
    "common/snap.glsl": {"snap_to_planes", "vertex_to_voxel"},
    "common/voxel_space.glsl": {"world_to_voxel"},
    "common/transform.comp": {"main"},
    "ss/setup.glsl": {"setup_triangle", "proj_edge", "proj_test", "plane_test"},
    "ss/surface.comp": {"ceil_div", "floor_div", "voxelize_columns"},
    "common/fixed.glsl": {"fixed_point", "fixed_det_words", "fixed_value", "fixed_det", "fixed_det_sign", "fixed_edge",
                          "fixed_orientation", "fixed_top_left"},
    "ss/solid.glsl": {"solid_fixed", "solid_setup", "solid_edge", "solid_covers", "solid_may_cover",
                      "solid_first_flip"},
    "eisemann/column.glsl": {"eis_fixed", "eis_normal", "eis_weights", "eis_covers_at", "eis_crossing",
                             "eis_first_flipped"},
    "depth/cover.glsl": {"covers"},
    "depth/raster.frag": {"crossing"},
    "depth/key.glsl": {"depth_code"},
    "gwn/strip.glsl": {"gwn_edge"},
    "scanline/lines.glsl": {"clip_axis", "clip_segment", "fline_t"},
    "scanline/voxelize.comp": {"float_triangle", "icross"},
    "ldi/cells.glsl": {"ldi_cell_depth"},
    "ldi/peel_record.comp": {"peel_crossing"},
}

_FUNC = re.compile(r"^[ \t]*(?:\w+[ \t]+)+?(\w+)[ \t]*\(([^)]*)\)\s*\{", re.M)
_BINARY_PM = re.compile(r"(?<=[\w)\]])\s*[+-](?![+-=])")


def exact_functions(text):
    """(name, body) of each function preceded by a ``// exact:`` comment line."""
    out = []
    lines = text.splitlines(keepends=True)
    offsets = [0]
    for line in lines:
        offsets.append(offsets[-1] + len(line))
    for m in _FUNC.finditer(text):
        start_line = text.count("\n", 0, m.start())
        prev = start_line - 1
        while prev >= 0 and lines[prev].strip().startswith("//") and not lines[prev].strip().startswith("// exact:"):
            prev -= 1
        if prev < 0 or not lines[prev].strip().startswith("// exact:"):
            continue
        depth, i = 1, m.end()
        while depth:
            depth += {"{": 1, "}": -1}.get(text[i], 0)
            i += 1
        out.append((m.group(1), text[m.end():i - 1]))
    return out


def _strip(stmt):
    stmt = re.sub(r"//[^\n]*", "", stmt)
    while re.search(r"\[[^\[\]]*\]", stmt):  # index arithmetic is integer
        stmt = re.sub(r"\[[^\[\]]*\]", "", stmt)
    stmt = re.sub(r"\b\d+(\.\d*)?([eE][+-]?\d+)?(lf|u|f)?\b", "1", stmt)  # 1e-6: no binary minus
    return re.sub(r"\+\+|--", " ", stmt)


def violations(body):
    """Statements of an exact function's body that break the convention."""
    bad = []
    body = re.sub(r"//[^\n]*", "", body)
    body = re.sub(r"(?m)^[ \t]*#.*$", "", body)  # preprocessor lines
    precise = set()
    for m in re.finditer(r"\bprecise\s+\w+\s+([^;]*);", body):
        for decl in re.split(r",(?![^()]*\))", m.group(1)):
            precise.add(decl.split("=")[0].strip())
    for raw in re.split(r"[;{}]", body):
        stmt = _strip(raw).strip()
        if not stmt:
            continue
        if re.search(r"\b(dot|cross|fma)\s*\(", stmt):
            bad.append(f"built-in product-sum: {stmt}")
            continue
        core = re.sub(r"^(if|while|for)\s*\(", "(", stmt)
        product_sum = "*" in core and _BINARY_PM.search(core)
        if not product_sum:
            continue
        if core.startswith("return"):
            bad.append(f"return computes a product-sum: {stmt}")
            continue
        if core.startswith("precise "):
            continue
        target = re.match(r"^([\w.]+)\s*[-+*/]?=(?!=)", core)
        if target and target.group(1).split(".")[0] in precise:
            continue
        bad.append(f"product-sum outside a precise variable: {stmt}")
    return bad


def _shader(path):
    return (builtin_shader_dir() / path).read_text()


@pytest.mark.parametrize("path", sorted(REQUIRED))
def test_exact_functions_are_marked_and_precise(path):
    funcs = dict(exact_functions(_shader(path)))
    assert REQUIRED[path] <= set(funcs), f"{path}: not marked // exact: {sorted(REQUIRED[path] - set(funcs))}"
    bad = {name: v for name, body in funcs.items() if (v := violations(body))}
    assert not bad, f"{path}: {bad}"


def test_every_marked_function_in_every_shader_is_precise():
    root = builtin_shader_dir()
    bad = {}
    for p in sorted(root.rglob("*")):
        if p.suffix not in (".glsl", ".comp", ".frag", ".vert", ".geom"):
            continue
        text = p.read_text()
        funcs = exact_functions(text)
        markers = len(re.findall(r"(?m)^[ \t]*// exact:", text))
        if markers != len(funcs):  # a marker the scan cannot attach to a function checks nothing
            bad[str(p.relative_to(root))] = [f"{markers} '// exact:' markers, {len(funcs)} marked functions found"]
        for name, body in funcs:
            if v := violations(body):
                bad[f"{p.relative_to(root)}:{name}"] = v
    assert not bad, bad


@pytest.mark.parametrize("body,ok", [
    ("precise float f = a * b - c * d; return f;", True),
    ("float f = a * b - c * d; return f;", False),            # the contraction hazard
    ("return a * b + c;", False),                              # a helper's return is not covered
    ("precise float f; f = a * b + c; return f;", True),       # assignment to a precise variable
    ("precise vec3 n; float s = dot(n, p); return s;", False), # hidden product-sum
    ("float x = a[i * 3 + 1]; return x;", True),               # integer index arithmetic
    ("float y = a * 1e-6; return y;", True),                   # a product alone cannot fuse
    ("bool b = x * y >= z - 1.0; return b;", False),
])
def test_the_scan_itself(body, ok):
    """The checker flags exactly the hazards it names (so the scan above can fail)."""
    assert (violations(body) == []) == ok, violations(body)
