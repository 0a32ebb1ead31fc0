"""Mutation testing: does the default suite notice when the code it guards is broken?

Each mutant is a small text patch (one or more exact replacements) of a GLSL
shader or a Python module, meant to be *meaningful*: a box test shrunk by less
than the tie epsilon, a fill rule's strict comparison made non-strict, a prefix
fill started one voxel late, and so on (:data:`MUTANTS`).  For each mutant the
script

1. copies the checkout (``git ls-files``: tracked and untracked, not ignored
   files) into a scratch folder, once;
2. applies the patch there (every ``old`` text must occur exactly once, so a
   refactor that moves the code makes the mutant fail loudly, not pass
   silently), runs the mutant's tests (``python -m pytest -x`` on the files
   and ``-k`` selection listed with it) against the scratch copy
   (``PYTHONPATH`` and ``GLVOX_SHADER_PATH`` point there, and the run checks
   that glvox is imported from there), and restores the file in a
   ``finally``;
3. reports the mutant *killed* when pytest fails a test (exit status 1) with
   an assertion, *survived* when the tests pass, and *error* for anything else
   (a collection error, a shader that no longer compiles: such a mutant tests
   nothing and must be rewritten).

The checkout itself is never touched.  Before the mutants, the same tests run
unmutated in the scratch copy and must pass.  Exit status 0 iff every mutant
is killed.

Usage::

    python compare/mutants.py                 # every mutant, a table at the end
    python compare/mutants.py --list          # the mutants and their tests
    python compare/mutants.py -m ss-box-shrink-simple fill-rule-non-strict
    python compare/mutants.py --json mutants.json

Keep the list growing as methods land: a mutant is (id, why, file, [(old, new)],
tests), the tests being the few default-suite tests that should catch it (by
file and ``-k``), so each run stays short.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Mutant:
    id: str
    why: str
    file: str
    patches: tuple[tuple[str, str], ...]
    tests: tuple[str, ...]  # pytest arguments: files / node ids, and -k expressions
    extra: tuple[str, ...] = field(default=())


_SHRINK = (  # S&S's box test on the box [p + 5e-5, p + 1 - 5e-5]: 1e-4 voxel smaller, < the tie epsilon
    ("    precise ivec3 first = ivec3(ceil(mn)) - 1;\n    ivec3 last = ivec3(floor(mx));",
     "    precise ivec3 first = ivec3(ceil(mn + 5e-5)) - 1;\n    ivec3 last = ivec3(floor(mx - 5e-5));"),
    ("return edge_box_term_6sep(n, vec2(1.0));", "return edge_box_term_6sep(n, vec2(1.0 - 1e-4));"),
    ("return edge_box_term_conservative(n, vec2(1.0));", "return edge_box_term_conservative(n, vec2(1.0 - 1e-4));"),
    ("    vec2 r = vec2(rq);", "    vec2 r = vec2(rq) + 5e-5;"),
    ("    precise float lim = 0.5 * max(a.x, max(a.y, a.z));",
     "    precise float lim = (0.5 - 5e-5) * max(a.x, max(a.y, a.z));"),
    ("    precise vec3 d = p - T.v0;", "    precise vec3 d = p + 5e-5 - T.v0;"),
    ("    precise float hi = s + (pos.x + pos.y + pos.z);\n    precise float lo = s + (neg.x + neg.y + neg.z);",
     "    precise float hi = s + (1.0 - 1e-4) * (pos.x + pos.y + pos.z);\n"
     "    precise float lo = s + (1.0 - 1e-4) * (neg.x + neg.y + neg.z);"),
)


def _grow(patches):
    """The same patches with the box grown by as much."""
    # the longer keys first, each through a placeholder, so no swap undoes another
    swap = {"1.0 - 1e-4": "1.0 + 1e-4", "0.5 - 5e-5": "0.5 + 5e-5", "+ 5e-5": "- 5e-5", "- 5e-5": "+ 5e-5"}
    out = []
    for old, new in patches:
        for i, a in enumerate(swap):
            new = new.replace(a, f"\0{i}\0")
        for i, b in enumerate(swap.values()):
            new = new.replace(f"\0{i}\0", b)
        out.append((old, new))
    return tuple(out)


EXACT = "tests/test_exact.py"

MUTANTS: list[Mutant] = [
    *[Mutant(f"ss-box-shrink-{v}", f"the issue's mutation: S&S box test shrunk by 5e-5 voxel ({v})", "shaders/ss/setup.glsl",
             _SHRINK, (EXACT, "-k", k))
      for v, k in (("simple", "variant-simple"), ("specialized", "variant-specialized"),
                   ("sorted", "variant-sorted"), ("6sep", "ss-6sep"))],
    *[Mutant(f"ss-box-grow-{v}", f"S&S box test grown by 5e-5 voxel ({v})", "shaders/ss/setup.glsl",
             _grow(_SHRINK), (EXACT, "-k", k))
      for v, k in (("simple", "variant-simple"), ("specialized", "variant-specialized"),
                   ("sorted", "variant-sorted"), ("6sep", "ss-6sep"))],
    Mutant("ss-column-range-rounded", "the column range of the specialized variant from a rounded quotient again "
           "(the bug this issue's exact tests found)", "shaders/ss/surface.comp",
           (("    if (below >= a) return m - 1;\n    precise float at = float(m) * b;\n    return at < a ? m + 1 : m;",
             "    return m;"),
            ("    if (above <= a) return m + 1;\n    precise float at = float(m) * b;\n    return at > a ? m - 1 : m;",
             "    return m;"),
            ("    int m = int(ceil(a / b));", "    int m = int(ceil(a * (1.0 / b)));"),
            ("    int m = int(floor(a / b));", "    int m = int(floor(a * (1.0 / b)));")),
           (EXACT, "-k", "variant-specialized")),
    Mutant("sliver-plane-trusted", "ss surface: a sliver's rounded plane trusted again (the fuzz-found bug)",
           "shaders/ss/setup.glsl", (("    if (T.no_plane) return true;\n", ""),
                                     ("    T.no_plane = all(lessThanEqual(abs(T.n), bound)) && !any(in_plane);",
                                      "    T.no_plane = false;")),
           ("tests/test_reliability.py", "-k", "needle")),
    Mutant("sliver-ties-at-half", "reference ties: free slivers' projections at exactly 0.5 again",
           "glvox/reference/ties.py",
           (("            ties |= f(sliver, dims, 0.5 + eps, flip=flip, no_plane=no_plane)",
             "            ties |= f(sliver, dims, 0.5, flip=flip, no_plane=no_plane)"),),
           ("tests/test_reliability.py", "-k", "needle_in_a_diagonal_plane")),
    Mutant("reference-solid-one-late", "reference-solid: every crossing flips from one voxel later",
           "glvox/reference/solid.py", (("        qbar = np.floor(q + 0.5)", "        qbar = np.floor(q + 0.5) + 1"),),
           (EXACT, "-k", "libigl")),
    Mutant("fill-rule-non-strict", "S&S solid: the top-left rule's strict comparison made non-strict "
           "(centers on an edge count for both triangles)", "shaders/ss/solid.glsl",
           (("if (!(s > 0 || (s == 0 && ((t.tl >> i) & 1) != 0))) return false;",
             "if (!(s >= 0 || (s == 0 && ((t.tl >> i) & 1) != 0))) return false;"),),
           (EXACT, "-k", "solid_methods and ss-solid")),
    Mutant("ss-tile-test-strict", "S&S tiled solid: a box whose critical corner lies exactly on an edge "
           "dropped (the exact tile test made strict)", "shaders/ss/solid.glsl",
           (("        if (hi < 0) return false;", "        if (fixed_sign(hi, lo) <= 0) return false;"),),
           (EXACT, "-k", "solid_methods and (ss-solid-tiled or ss-octree)")),
    Mutant("ss-vertex-rounded-per-triangle", "S&S solid: each triangle rounds its vertices to the fixed point "
           "with its own offset, so the triangles of an edge see different edges", "shaders/ss/solid.glsl",
           (("    t.f = ivec2[3](solid_fixed(p0.yz), solid_fixed(p1.yz), solid_fixed(p2.yz));",
             "    t.f = ivec2[3](solid_fixed(p0.yz + p1.x * 1e-6), solid_fixed(p1.yz + p2.x * 1e-6), "
             "solid_fixed(p2.yz + p0.x * 1e-6));"),),
           (EXACT, "-k", "solid_methods and ss-solid")),
    Mutant("half-open-rule-swapped", "S&S solid: a center exactly on the crossing flips (>= instead of >)",
           "shaders/ss/solid.glsl",
           (("    precise double first = floor(q + 0.5lf);",
             "    precise double first = ceil(q - 0.5lf);"),),
           (EXACT, "-k", "solid_methods and ss-solid")),
    Mutant("eisemann-top-left-non-strict", "eisemann column test: centers on every projected edge covered "
           "(the top-left rule's strict comparison made non-strict)", "shaders/eisemann/column.glsl",
           (("        if (!(s[i] > 0 || (s[i] == 0 && fixed_top_left(f, i, sgn)))) return false;",
             "        if (!(s[i] >= 0 || (s[i] == 0 && fixed_top_left(f, i, sgn)))) return false;"),),
           (EXACT, "-k", "solid_methods and eisemann-solid")),
    Mutant("eisemann-det-borrow-lost", "fixed-point coverage: the 64-bit difference of the products "
           "without the low words' borrow", "shaders/common/fixed.glsl",
           (("    hi = ab_hi - cd_hi - int(borrow);", "    hi = ab_hi - cd_hi;"),),
           ("tests/test_eisemann.py", "-k", "determinant")),
    Mutant("eisemann-crossing-normal-denominator", "eisemann: the crossing divided by the double normal's "
           "a component instead of the exact weights' sum (the same number but for rounding)",
           "shaders/eisemann/column.glsl",
           (("(w.x * (p2.z - p0.z) + w.z * (p1.z - p0.z)) / (w.x + w.y + w.z);",
             "(w.x * (p2.z - p0.z) + w.z * (p1.z - p0.z)) / (eis_normal(p0, p1, p2).z "
             "* double(1 << u_eis_fix_bits) * double(1 << u_eis_fix_bits));"),),
           ("tests/test_eisemann.py", "-k", "sliver_stays")),
    Mutant("eisemann-miter-quotient", "eisemann setup: the miter's length tested as |a + b| against 1 + a.b, "
           "which passes a sliver's tip where both round to zero", "shaders/eisemann/setup.comp",
           (("        miter = miter && c * (EIS_MITER_MAX * EIS_MITER_MAX) >= 2.0 * (EIS_GROW * EIS_GROW);",
             "        miter = miter && EIS_GROW * length(a + b) <= EIS_MITER_MAX * c;"),),
           ("tests/test_eisemann.py", "-k", "proxy_of_a_sliver")),
    Mutant("ldi-widen-without-section", "leung-wang-ldi: a steep triangle's samples widened over its whole "
           "extent, not bounded by its points near the ray", "shaders/ldi/depths.frag",
           (("    if (widen > 1.0) {", "    if (false) {"),),
           ("tests/test_ldi.py", "-k", "face_along_the_rays")),
    Mutant("depth-top-left-swapped", "depth layers' rasterization: the top-left rule inverted (the other "
           "edges own the centers on them)", "shaders/depth/cover.glsl",
           (("        if (!(s > 0 || (s == 0 && fixed_top_left(f, i, sgn)))) return false;",
             "        if (!(s > 0 || (s == 0 && !fixed_top_left(f, i, sgn)))) return false;"),),
           (EXACT, "-k", "solid_methods and passalis-peel")),
    Mutant("prefix-fill-one-late", "ss-solid: the prefix XOR along a row starts one voxel late",
           "shaders/ss/solid_fill.comp",
           (("            c ^= c << 1u;\n            c ^= c << 2u;",
             "            c = c << 1u;\n            c ^= c << 1u;\n            c ^= c << 2u;"),),
           (EXACT, "-k", "solid_methods and ss-solid")),
    Mutant("depth-peel-skips-a-layer", "depth peeling: the layer behind layer 0 is peeled past unrecorded",
           "glvox/methods/depth/raster.py",
           (("    for index in range(1, known):\n        run.draw(target, cur, cls=cls, prev=prev)",
             "    for index in range(1, known):\n        if index == 1:\n            run.draw(target, cur, cls=cls, prev=prev)\n"
             "            cur, prev = prev, cur\n        run.draw(target, cur, cls=cls, prev=prev)"),),
           (EXACT, "-k", "solid_methods and (peel-ldi or passalis-peel)")),
    Mutant("xor-mask-off-by-one-slice", "eisemann: each fragment's suffix mask starts one slice late",
           "shaders/eisemann/masks.glsl",
           (("ivec4 lo = clamp(ivec4(first - 128 * t) - ivec4(0, 32, 64, 96), 0, 32);",
             "ivec4 lo = clamp(ivec4(first + 1 - 128 * t) - ivec4(0, 32, 64, 96), 0, 32);"),),
           (EXACT, "-k", "solid_methods and eisemann-solid")),
    Mutant("eisemann-slice-rounded", "eisemann-surface: the crossing's slice rounded to the nearest, not floored",
           "shaders/eisemann/column.glsl",
           (("int eis_slice_of(double q, int n) { return q == double(n) ? n - 1 : eis_to_int(floor(q)); }",
             "int eis_slice_of(double q, int n) { return q == double(n) ? n - 1 : eis_to_int(floor(q + 0.5)); }"),),
           (EXACT, "-k", "surface_methods and eisemann-surface")),
    Mutant("bit-packing-shift-glsl", "common/bits.glsl: a voxel's bit one position off",
           "shaders/common/bits.glsl",
           (("uint bit_of(uint i) { return 1u << (i & 31u); }", "uint bit_of(uint i) { return 1u << ((i + 1u) & 31u); }"),),
           (EXACT, "-k", "surface_methods and ss-conservative")),
    Mutant("bit-packing-shift-python", "glvox.grid.unpack_bits: big-endian bit order within a byte",
           "glvox/grid.py",
           (('        bits = np.unpackbits(rows, axis=1, bitorder="little")',
             '        bits = np.unpackbits(rows, axis=1, bitorder="big")'),
            ('                bits[r:e] = np.unpackbits(rows[r:e], axis=1, bitorder="little")',
             '                bits[r:e] = np.unpackbits(rows[r:e], axis=1, bitorder="big")')),
           ("tests/test_grid.py",)),
    Mutant("grid-origin-fraction", "glvox.grid.fit_grid: the origin moved by 1/100 voxel",
           "glvox/grid.py",
           (("    origin = center - 0.5 * np.asarray(d, dtype=np.float64) * h",
             "    origin = center - 0.5 * np.asarray(d, dtype=np.float64) * h + 0.01 * h"),),
           ("tests/test_grid.py",)),
    Mutant("tie-eps-larger", "TIE_EPS 1e-4 -> 1.2e-4 (the design's tolerance changed)", "glvox/tolerances.py",
           (("TIE_EPS = 1e-4\n", "TIE_EPS = 1.2e-4\n"),), (EXACT, "-k", "tie_sets")),
    Mutant("tie-eps-smaller", "TIE_EPS 1e-4 -> 0.8e-4", "glvox/tolerances.py",
           (("TIE_EPS = 1e-4\n", "TIE_EPS = 0.8e-4\n"),), (EXACT, "-k", "tie_sets")),
    Mutant("reference-conservative-strict", "reference-conservative: the plane test's comparisons made strict "
           "(touching boxes dropped)", "glvox/reference/surface.py",
           (("        ok = np.minimum(lo, hi) <= 0.0\n        ok &= np.maximum(lo, hi) >= 0.0",
             "        ok = np.minimum(lo, hi) < 0.0\n        ok &= np.maximum(lo, hi) > 0.0"),),
           (EXACT, "-k", "reference-conservative")),
    Mutant("reference-6sep-edge-offset", "reference-6sep: the edge offsets from the smaller normal component",
           "glvox/reference/surface.py",
           (("        h = np.where(ane[:, p, :, 0] >= ane[:, p, :, 1], halves[:, a, None], halves[:, b, None])\n"
             "        oe[:, p] = h * ane[:, p].max(axis=-1)",
             "        h = np.where(ane[:, p, :, 0] >= ane[:, p, :, 1], halves[:, a, None], halves[:, b, None])\n"
             "        oe[:, p] = h * ane[:, p].min(axis=-1)"),),
           (EXACT, "-k", "reference-6sep")),
    # robust solids (issue 19) and attributes (issue 21)
    Mutant("vote-or-instead-of-majority", "vote-solid: any parity's inside wins instead of two of three",
           "shaders/vote/vote.comp", (("    WORDS v = (x & y) | (grid_z[idx] & (x | y));",
                                       "    WORDS v = x | y | grid_z[idx];"),),
           ("tests/test_vote.py", "-k", "outvoted")),
    # (the same comparison in gwn/segment.glsl is left out: it decides w there only where w is
    # farther from the threshold than the error bound, or refined in float32 from an open
    # mesh's strips, where w equal to the threshold never came up: an equivalent mutant in practice)
    Mutant("gwn-rows-threshold-strict", "gwn-solid's closed rows (word by word): inside when C > threshold",
           "shaders/gwn/rows.comp", (("            if (i > from && float(run) >= u_threshold) word |= mask_range(from, i - 1u);",
                                      "            if (i > from && float(run) > u_threshold) word |= mask_range(from, i - 1u);"),
                                     ("        if (float(run) >= u_threshold) word |= mask_from(from);",
                                      "        if (float(run) > u_threshold) word |= mask_from(from);")),
           ("tests/test_gwn.py", "-k", "overlapping_spheres or add_up")),
    Mutant("gwn-rows-block-threshold-strict", "gwn-solid's closed rows with the field: inside when C > threshold",
           "shaders/gwn/rows.comp", (("            vec4 w = vec4(c);\n            uint x = 4u * q;\n"
                                      "            uvec4 in4 = uvec4(greaterThanEqual(w, vec4(u_threshold)))",
                                      "            vec4 w = vec4(c);\n            uint x = 4u * q;\n"
                                      "            uvec4 in4 = uvec4(greaterThan(w, vec4(u_threshold)))"),),
           ("tests/test_gwn.py", "-k", "add_up")),
    Mutant("gwn-events-no-carry", "gwn-solid's crossing counts: plane 0 toggles, nothing carries into plane 1",
           "shaders/gwn/events.comp", (("    if ((atomicXor(events[at], b) & b) == 0u) return;",
                                        "    atomicXor(events[at], b);\n    return;"),),
           ("tests/test_gwn.py", "-k", "add_up")),
    Mutant("gwn-events-carry-unflagged", "gwn-solid's crossing counts: a carry into plane 1 leaves its "
           "row unflagged, so the row pass reads plane 0 alone there",
           "shaders/gwn/events.comp", (("    carried[u_carried0 + slab_row(j, k)] = 1u;\n", ""),),
           ("tests/test_gwn.py", "-k", "add_up")),
    Mutant("gwn-caps-carry-flags-shared", "gwn-solid's caps: their carries flag the mesh's rows, not "
           "their own", "glvox/methods/gwn/field.py",
           (("carried=carried, carried0=(s1 - s0) * ny)", "carried=carried, carried0=0)"),),
           ("tests/test_gwn.py", "-k", "caps_count_three")),
    Mutant("gwn-far-g-halved", "gwn-solid's cluster records: the s . n part of the expansion's g "
           "vector halved (it counts for fans around an apex off the node's center)",
           "glvox/methods/gwn/tree.py", (("    g = (2.0 * (T[:, 0, :, 0]", "    g = (1.0 * (T[:, 0, :, 0]"),),
           ("tests/test_gwn.py", "-k", "far_field_error")),
    Mutant("host-cpu-whole-process", "compare/outside_stages.py's host share counts the process's CPU "
           "time (a software renderer's shader threads included), not the calling thread's",
           "compare/outside_stages.py",
           (("        c0, t0 = time.thread_time(), time.perf_counter()", "        c0, t0 = time.process_time(), time.perf_counter()"),
            ("        cpus.append(time.thread_time() - c0)", "        cpus.append(time.process_time() - c0)")),
           ("tests/test_gpu_report.py", "-k", "per_call")),
    Mutant("far-voxels-caps-bound-no-gradient", "compare/gwn_far_voxels.py's model of the caps' bound: "
           "a fan's solid angle at the ball's center taken for the whole ball (no gradient term)",
           "compare/gwn_far_voxels.py",
           (("np.minimum(crude.sum(axis=1), np.abs(omega) + grad * hd)", "np.minimum(crude.sum(axis=1), np.abs(omega))"),),
           ("tests/test_gwn.py", "-k", "caps_bound_holds_over")),
    Mutant("gwn-tree-scale-power", "gwn-solid's tree mapped onto a grid: one T entry scaled by the cube "
           "of the voxel size, not its fourth power", "glvox/methods/gwn/tree.py",
           (("                         4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 2, 1, 0, 0, 0]",
             "                         4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 3, 2, 1, 0, 0, 0]"),),
           ("tests/test_gwn.py", "-k", "serves_every_grid")),
    Mutant("gwn-tree-no-margin", "gwn-solid's tree mapped onto a grid: the radii without the margin "
           "for the GPU's float32 vertices", "glvox/methods/gwn/tree.py",
           (("    rec[:, 0, 3] += RADIUS_MARGIN\n", ""),),
           ("tests/test_gwn.py", "-k", "serves_every_grid")),
    Mutant("gwn-chunks-shared-list", "gwn-solid's chunk plan: the cached lists themselves handed out, "
           "so a caller's change reaches the next call", "glvox/methods/gwn/plan.py",
           (("    return [list(c) for c in per_limit[limit]]", "    return per_limit[limit]"),),
           ("tests/test_gwn.py", "-k", "serves_every_grid")),
    Mutant("gwn-chunks-budget-ignored", "gwn-solid's chunk plan cached per topology whatever the loop "
           "budget", "glvox/methods/gwn/plan.py",
           (("    per_limit = _CHUNKS.setdefault(tree.topology, {})", "    per_limit = _CHUNKS.setdefault(tree.topology, {})\n    limit = next(iter(per_limit), limit)"),),
           ("tests/test_gwn.py", "-k", "accuracy_only_moves")),
    Mutant("gwn-caps-first-unshifted", "gwn-solid's caps' records: each fan's first triangle counted "
           "from the triangle records, not from the buffer's start", "glvox/methods/gwn/caps.py",
           (("    head_bits[:, 1, 1] = CAP_VEC4 * n_loops + first", "    head_bits[:, 1, 1] = first"),),
           ("tests/test_gwn.py", "-k", "caps_close")),
    Mutant("gwn-caps-no-apex-voxels", "gwn-solid: the voxel positions computed for the boundary's "
           "vertices but not the caps' apexes", "glvox/methods/gwn/tree.py",
           (("    idx = np.concatenate(loops.loops + [np.arange(extra_from, len(vertices))]).astype(np.int64)",
             "    idx = np.concatenate(loops.loops).astype(np.int64)"),),
           ("tests/test_gwn.py", "-k", "caps_close")),
    Mutant("gwn-overflow-seen-late", "gwn-solid: planes that overflowed go on through the tree's "
           "passes before the slabs run again with ints", "glvox/methods/gwn/field.py",
           (("        if self.tree is not None and self.overflowed():", "        if False:"),),
           ("tests/test_gwn.py", "-k", "past_the_planes")),
    Mutant("gwn-super-ball-shrunk", "gwn-solid's super bricks: the caps' bound taken over a ball of "
           "0.3 of the super brick's radius, not around all its voxel centers", "shaders/gwn/bricks.comp",
           (("caps_decide(0.5 * (lo + hi), 0.5 * length(hi - lo))", "caps_decide(0.5 * (lo + hi), 0.15 * length(hi - lo))"),),
           ("tests/test_gwn.py", "-k", "open_shared_meshes_64")),
    Mutant("gwn-super-after-recounts", "gwn-solid's finer super bricks test again the ones the coarser "
           "pass decided", "shaders/gwn/bricks.comp",
           (("    if (((cap_bits[first / 32u] >> (first & 31u)) & 1u) != 0u) return;",
             "    if (false) return;"),),
           ("tests/test_gwn.py", "-k", "super")),
    Mutant("gwn-super-after-skips-the-rest", "gwn-solid's finer super bricks skip the ones the coarser "
           "pass left", "shaders/gwn/bricks.comp",
           (("    if (((cap_bits[first / 32u] >> (first & 31u)) & 1u) != 0u) return;",
             "    if (((cap_bits[first / 32u] >> (first & 31u)) & 1u) == 0u) return;"),),
           ("tests/test_gwn.py", "-k", "super")),
    Mutant("gwn-todo-run-short", "gwn-solid's listing of the segments the bricks left: the last of "
           "each run of segments is never listed", "shaders/gwn/todo.comp",
           (("    uint end = min(first + uint(GWN_TODO_RUN), u_items);",
             "    uint end = min(first + uint(GWN_TODO_RUN) - 1u, u_items);"),),
           ("tests/test_gwn.py", "-k", "open_shared_meshes_64")),
    Mutant("gwn-todo-last-run-dropped", "gwn-solid's listing: the dispatch rounds the runs down, the "
           "partial last run is never listed", "glvox/methods/gwn/field.py",
           (("        dispatch_1d(ctx, prog, -(-n // TODO_RUN), _LOCAL)",
             "        dispatch_1d(ctx, prog, n // TODO_RUN, _LOCAL)"),),
           ("tests/test_gwn.py", "-k", "storage_limit_is_streamed")),
    Mutant("gwn-caps-always", "gwn-solid's caps decide every brick, whatever their bound",
           "shaders/gwn/caps.glsl", (("    return min(each, signed_rest + abs(omega_all)) < limit;",
                                      "    return true;"),),
           ("tests/test_gwn.py", "-k", "far_from_planar")),
    Mutant("gwn-caps-inside-the-common-ball", "gwn-solid's caps: the common ball's area bound used from "
           "inside the ball too", "shaders/gwn/caps.glsl",
           (("    if (all > 0.0 && u_caps_area / (all * all) < limit) return true;",
             "    if (u_caps_area / (all * all) < limit) return true;"),),
           ("tests/test_gwn.py", "-k", "far_from_planar")),
    Mutant("gwn-caps-no-gradient", "gwn-solid's caps: the solid angle at the brick's center bounds the "
           "whole brick (its gradient bound left out)", "shaders/gwn/caps.glsl",
           (("min(crude, abs(omega) + 2e-3 + grad * hd)", "min(crude, abs(omega) + 2e-3)"),
            ("signed_rest += apart ? 2e-3 + grad * hd : crude;", "signed_rest += apart ? 2e-3 : crude;")),
           ("tests/test_gwn.py", "-k", "far_from_planar")),
    Mutant("gwn-caps-fan-by-fan", "gwn-solid's caps: only the bound fan by fan, not the fans' signed sum "
           "(fans of opposite sense no longer cancel)", "shaders/gwn/caps.glsl",
           (("    return min(each, signed_rest + abs(omega_all)) < limit;", "    return each < limit;"),),
           ("tests/test_gwn.py", "-k", "opposite")),
    Mutant("gwn-caps-signed-without-the-rest", "gwn-solid's caps: the signed sum of the fans' solid "
           "angles leaves out the fans that come into the brick", "shaders/gwn/caps.glsl",
           (("signed_rest += apart ? 2e-3 + grad * hd : crude;", "signed_rest += apart ? 2e-3 + grad * hd : 0.0;"),),
           ("tests/test_gwn.py", "-k", "far_from_planar or opposite")),
    Mutant("gwn-caps-through-the-fan", "gwn-solid's caps: the center's solid angle used for a brick the "
           "fan passes through", "shaders/gwn/caps.glsl",
           (("            apart = apart && dt > 0.0 && g > 0.0;", "            apart = true;"),),
           ("tests/test_gwn.py", "-k", "caps_decide_most")),
    Mutant("gwn-caps-word-without-caps", "gwn-solid's rows: a word whose bricks the caps decide counts the "
           "mesh's crossings alone", "shaders/gwn/rows.comp",
           (("    if (float(run + run_caps) >= u_threshold) word |= mask_from(from);",
             "    if (float(run) >= u_threshold) word |= mask_from(from);"),),
           ("tests/test_gwn.py", "-k", "pipe or capped_mesh")),
    Mutant("gwn-lean-every-row", "gwn-solid's rows: every row taken word by word from the counts, "
           "as if the caps decided all its bricks", "shaders/gwn/rows.comp",
           (("        int lean_end = u_segs.x + int((left - b0) / per_word);",
             "        int lean_end = u_segs.x + u_segs.y;"),),
           ("tests/test_gwn.py", "-k", "caps")),
    Mutant("gwn-lean-row-restarted", "gwn-solid's rows: after the leading words the caps decide, the "
           "block loop starts the row again", "shaders/gwn/rows.comp",
           (("        q8_first = 8u * uint(lean_end);", "        q8_first = 0u;"),),
           ("tests/test_gwn.py", "-k", "open_shared_meshes_128")),
    Mutant("gwn-caps-block-without-caps", "gwn-solid's rows: a block of a brick the caps decide counts "
           "the mesh's crossings alone", "shaders/gwn/rows.comp",
           (("                ivec4 closed = c + ck;", "                ivec4 closed = c;"),),
           ("tests/test_gwn.py", "-k", "caps_decide_most")),
    Mutant("scanline-slv-box-skips-another", "scanline-slv: an event's box leaves out its far corner, "
           "not the voxel the line marked before", "shaders/scanline/lines.glsl",
           (("            mark_box_but(lo, hi, (1u << box_corner(l.cur, lo))",
             "            mark_box_but(lo, hi, (1u << box_corner(hi, lo))"),),
           ("tests/test_scanline.py", "-k", "slv")),
    Mutant("scanline-slv-box-corners-unmarked", "scanline-slv: the corner loop marks nothing, so a "
           "singular event's box and a vertex on a face plane lose all but one or two voxels",
           "shaders/scanline/lines.glsl",
           (("        mark(mix(lo, hi, bvec3((c & 1u) != 0u, (c & 2u) != 0u, (c & 4u) != 0u)));", "        ;"),),
           ("tests/test_scanline.py", "-k", "slv")),
    Mutant("scanline-slv-vertex-box-lost", "scanline-slv: a triangle's third vertex's incident voxels "
           "are not marked (the edges leave their end points to the triangle)",
           "shaders/scanline/voxelize.comp", (("    mark_incident(P2);\n", ""),),
           ("tests/test_scanline.py", "-k", "slv")),
    Mutant("scanline-float-layer-not-reset", "scanline-rlv/slv: a layer's scanlines continue the count "
           "of the layer before", "shaders/scanline/voxelize.comp",
           (("            i = 0;\n        }\n", "        }\n"),),
           ("tests/test_scanline.py", "-k", "float_paths_equal_cpu")),
    Mutant("scanline-ilv-small-nibble-bits-lost", "scanline-ilv: a table row whose voxels are all at "
           "x + 2 or x + 3 of the block is skipped", "shaders/scanline/voxelize.comp",
           (("    t = (t | (t >> 2)) & 0x11111111u;", "    t = t & 0x11111111u;"),),
           ("tests/test_scanline.py", "-k", "in_a_block")),
    Mutant("scanline-ilv-small-second-word-lost", "scanline-ilv: a small triangle's row across a word "
           "boundary loses the bits of its second word", "shaders/scanline/voxelize.comp",
           (("    if (second != 0u) atomicOr(grid[row + uint(w + 1)], second);\n", ""),),
           ("tests/test_scanline.py", "-k", "in_a_block")),
    Mutant("scanline-ilv-small-left-unclipped", "scanline-ilv: a small triangle's row keeps the voxels "
           "left of the grid", "shaders/scanline/voxelize.comp",
           (("    if (v.x < 0) bits &= mask_from(uint(-v.x));", "    if (v.x < -3) bits &= mask_from(uint(-v.x));"),),
           ("tests/test_scanline.py", "-k", "clipped_at_every_face")),
    Mutant("scanline-ilv-small-right-unclipped", "scanline-ilv: a small triangle's row keeps the voxels "
           "right of the grid", "shaders/scanline/voxelize.comp",
           (("    if (over > 0) bits &=", "    if (over > 2) bits &="),),
           ("tests/test_scanline.py", "-k", "clipped_at_every_face")),
    Mutant("scanline-ilv-small-corner-transposed", "scanline-ilv: the table is looked up with x and y "
           "of the corners swapped", "shaders/scanline/voxelize.comp",
           (("uint small_corner(ivec3 d) { return uint(d.x + 4 * d.y + 16 * d.z); }",
             "uint small_corner(ivec3 d) { return uint(d.y + 4 * d.x + 16 * d.z); }"),),
           ("tests/test_scanline.py", "-k", "in_a_block")),
    Mutant("scanline-ilv-small-rows-transposed", "scanline-ilv: a small triangle's rows are read with y "
           "and z swapped", "shaders/scanline/voxelize.comp",
           (("lo + ivec3(0, int(r & 3u), int(r >> 2u))", "lo + ivec3(0, int(r >> 2u), int(r & 3u))"),),
           ("tests/test_scanline.py", "-k", "in_a_block")),
    Mutant("scanline-ilv-small-index-unsorted", "scanline-ilv: the table is looked up with the corners "
           "in the vertices' order", "shaders/scanline/voxelize.comp",
           (("    uint lo = min(c0, min(c1, c2)), hi = max(c0, max(c1, c2));",
             "    uint lo = c0, hi = c2;"),),
           ("tests/test_scanline.py", "-k", "in_a_block")),
    Mutant("scanline-ilv-small-table-built-transposed", "scanline-ilv: the table's build stores a voxel "
           "with x and y swapped", "shaders/scanline/budget.glsl",
           (("        uint bit = uint(d.x + 4 * d.y + 16 * d.z);",
             "        uint bit = uint(d.y + 4 * d.x + 16 * d.z);"),),
           ("tests/test_scanline.py", "-k", "in_a_block")),
    Mutant("scanline-ilv-scan-list-lost", "scanline-ilv: the table pass does not list the triangles "
           "it leaves to the scan", "shaders/scanline/voxelize.comp",
           (("    if (listed) scan_list[atomicAdd(scan_n, 1u)] = tri;", "    if (listed && tri == 0xFFFFFFFFu) scan_list[atomicAdd(scan_n, 1u)] = tri;"),),
           ("tests/test_scanline.py", "-k", "scans_only")),
    Mutant("indirect-groups-rounded-down", "an indirect dispatch over a counted list (scanline-ilv's "
           "scan, gwn-solid's segments, ss-octree's chunks) leaves out the last, partial work group",
           "shaders/common/dispatch.glsl",
           (("    uint groups = (n + local_size - 1u) / local_size;", "    uint groups = n / local_size;"),),
           ("tests/test_scanline.py", "-k", "scans_only or equals_cpu")),
    Mutant("carve-runs-not-joined", "carve-solid: a free run no longer carries into the next word of its row",
           "shaders/carve/sweep.comp", (("            if (carry != 0u) AT(g, c) |= (~fc & (fc + 1u)) - 1u;\n", ""),),
           ("tests/test_carve.py", "-k", "corridor or random_blockers")),
    Mutant("attr-distance-to-a-vertex", "attributes: the source triangle by the distance to its first vertex, "
           "not to its closest point", "shaders/attributes/pair.glsl",
           (("    dvec3 q = closest_bary(p, attr_a, attr_b, attr_c);", "    dvec3 q = dvec3(1.0lf, 0.0lf, 0.0lf);"),),
           ("tests/test_attributes.py", "-k", "cube or real_meshes")),
    Mutant("attr-reference-ties-to-highest", "attribute reference: ties go to the highest triangle index",
           "glvox/reference/attributes.py", (("        first = np.lexsort((tri, d, slot))",
                                              "        first = np.lexsort((-tri, d, slot))"),),
           ("tests/test_attributes.py", "-k", "cube or shared_edge")),
    Mutant("reference-solid-half-open", "reference-solid: centers on the crossing flip (>= instead of >)",
           "glvox/reference/solid.py", (("        qbar = np.floor(q + 0.5)", "        qbar = np.ceil(q - 0.5)"),),
           (EXACT, "-k", "rules_on_the_surface")),
    Mutant("eisemann-pack-x-last-target-dropped", "eisemann pack along x: the loop over the targets stops one short",
           "shaders/eisemann/pack.comp", (("    for (int t = 0; t < EIS_TARGETS; ++t) {\n        uvec4 words",
                                           "    for (int t = 0; t < EIS_TARGETS - 1; ++t) {\n        uvec4 words"),),
           ("tests/test_eisemann.py", "-k", "fewer_targets_more_passes")),
    Mutant("device-sink-ignored", "device='cuda': read_grid_words reads into host memory whatever the sink",
           "glvox/gpu/buffers.py", (("    if sink is not None:  # a device result", "    if False:  # a device result"),),
           ("tests/test_device_results.py", "-k", "hands_its_grid_to_the_sink")),
    Mutant("device-grid-counted-on-the-host", "device='cuda': the envelope counts a grid the GPU did not count "
           "(reading it back)", "glvox/methods/envelope.py",
           (("    count = None if on_device else getattr(result, \"count\", None)",
             "    count = getattr(result, \"count\", None)"),),
           ("tests/test_device_results.py", "-k", "uncounted")),
    Mutant("word-index-int32", "a packed word's index from the voxel's flat index in int, shifted with its sign "
           "(wrong past 2^31 voxels in one buffer, as NVIDIA's 2048^3 grids are)", "shaders/common/voxel_space.glsl",
           (("    return (k * uint(u_dims.y) + uint(v.y)) * words_per_row() + (uint(v.x) >> 5);",
             "    int at = (int(k) * u_dims.y + v.y) * int(words_per_row()) * 32 + v.x;\n    return uint(at >> 5);"),),
           ("tests/test_ss.py", "-k", "one_buffer_past")),
    Mutant("binvox-total-plain-xor", "binvox-solid: a column's total parity flipped by a plain read-modify-write "
           "across dispatches with no barrier between them (the hazard a GPU would show)",
           "shaders/binvox/record.comp", (("        atomicXor(total[col.y * u_view_size.x + col.x], 1u);",
                                           "        total[col.y * u_view_size.x + col.x] ^= 1u;"),),
           ("tests/test_hazards.py", "-k", "binvox")),
    Mutant("eisemann-setup-barrier-dropped", "eisemann: the draw reads the per-triangle setup with no barrier "
           "after the compute pass that stored it", "glvox/methods/eisemann/passes.py",
           (("        dispatch_1d(ctx, prog, n_tri, _LOCAL)\n        barrier(ctx)\n    return on_grid",
             "        dispatch_1d(ctx, prog, n_tri, _LOCAL)\n    return on_grid"),),
           ("tests/test_hazards.py", "-k", "eisemann")),
    Mutant("ss-surface-slab-end-unclipped", "ss surfaces: a triangle's voxels not clipped at its slab's last "
           "slice (stores past the slab's buffer, which llvmpipe drops)", "shaders/ss/setup.glsl",
           (("    T.hi.z = min(T.hi.z, u_slab.x + u_slab.y - 1);\n", ""),),
           ("tests/test_bounds.py", "-k", "slab")),
    Mutant("ss-solid-slab-end-unclipped", "ss-solid: a triangle's columns not clipped at its slab's last row "
           "(stores past the slab's buffer, which llvmpipe drops)", "shaders/ss/solid_input.glsl",
           (("    c.w = min(c.w, u_slab.x + u_slab.y - 1);\n", ""),),
           ("tests/test_bounds.py", "-k", "slab")),
    Mutant("ss-solid-grid-not-cleared", "ss-solid: the crossing grid taken from the pool without clearing "
           "(a new GL buffer's content is undefined; llvmpipe's is zero)", "glvox/methods/ss/solid.py",
           (('    grid = pool.get("grid" + tag, slices * per_slice, what=f"the {spec.dims} bit grid")',
             '    grid = pool.get("grid" + tag, slices * per_slice, what=f"the {spec.dims} bit grid", clear=False)'),),
           ("tests/test_bounds.py", "-k", "ss-solid")),
    Mutant("gwn-gradient-sign", "gwn-solid: the bricks' first-order records with the gradient of F reversed",
           "shaders/gwn/bricks.comp",
           (("    return vec4(g * (0.25 / GWN_PI), h * (1.001 * 0.25 / GWN_PI));",
             "    return vec4(g * (-0.25 / GWN_PI), h * (1.001 * 0.25 / GWN_PI));"),),
           ("tests/test_gwn.py", "-k", "first_order")),
    Mutant("gwn-second-derivative-tenth", "gwn-solid: the bound of F's second derivative over a brick a tenth "
           "of the proven one", "shaders/gwn/bricks.comp",
           (("h * (1.001 * 0.25 / GWN_PI)", "h * (0.1 * 0.25 / GWN_PI)"),),
           ("tests/test_gwn.py", "-k", "first_order")),
    Mutant("gwn-first-order-unused", "gwn-solid: the rows pass ignores the first-order records",
           "shaders/gwn/rows.comp",
           (("    return bvec4(uvec4(near0) * uvec4(near1));", "    return near0;"),),
           ("tests/test_gwn.py", "-k", "first_order")),
    Mutant("eisemann-cull-off", "eisemann-*: the setup draws every small box, covered or not",
           "shaders/eisemann/setup.comp",
           (("#define EIS_CULL_CENTERS 4", "#define EIS_CULL_CENTERS 0"),),
           ("tests/test_eisemann.py", "-k", "culls")),
    Mutant("eisemann-cull-off-center", "eisemann-*: the setup's cull tests points a quarter voxel off the centers",
           "shaders/eisemann/setup.comp",
           (("dvec2(col) + 0.5, w_unused", "dvec2(col) + 0.25, w_unused"),),
           ("tests/test_eisemann.py", "-k", "culls or subset or generated")),
    Mutant("depth-cull-off", "depth layers: the geometry stage draws every small box, covered or not",
           "shaders/depth/raster.geom",
           (("const int CULL_CENTERS = 4;", "const int CULL_CENTERS = 0;"),),
           ("tests/test_depth.py", "-k", "culls")),
    Mutant("depth-cull-off-center", "depth layers: the geometry stage's cull tests points a quarter voxel off the centers",
           "shaders/depth/raster.geom",
           (("fixed_center(pix, u_fix_bits), w_unused", "fixed_center(pix, u_fix_bits) + (1 << (u_fix_bits - 2)), w_unused"),),
           ("tests/test_depth.py", "-k", "culls or watertight or generated")),
    Mutant("depth-key-rounded-depth", "the z-buffers' key is the depth (its code) rounded to float again, which can give "
           "two crossings across a slot's boundary one key", "shaders/depth/key.glsl",
           (("    return uintBitsToFloat(u_far ? KEY_LAST - m : KEY_FIRST + m);",
             "    float key = float(double(m) / 536870912.0lf);\n    return u_far ? 1.0 - key : key;"),),
           ("tests/test_depth.py", "-k", "depth_keys")),
    Mutant("raster-view-size-unchecked", "depth/raster.frag leaves the view's size to the geometry stage alone "
           "(softpipe then draws nothing in a view after a view of another size)", "shaders/depth/raster.frag",
           (("    ivec2 pix = min(ivec2(gl_FragCoord.xy), u_target_size - 1);",
             "    ivec2 pix = ivec2(gl_FragCoord.xy);"),),
           ("tests/test_drivers.py", "-k", "different_sizes")),
    Mutant("binvox-wire-owners-ignored", "binvox-solid -aw: the wireframe draws every copy of a shared edge",
           "shaders/binvox/wire.geom",
           (("        if ((own & (1u << uint(k))) == 0u) continue;\n", ""),),
           ("tests/test_binvox.py", "-k", "each_shared_edge")),
    Mutant("binvox-wire-owners-swapped", "binvox-solid -aw: the nearest z-buffer's copy of a shared edge is its last",
           "glvox/methods/binvox/solid.py",
           (("    bits[first] |= 1\n    bits[last] |= 8\n", "    bits[first] |= 8\n    bits[last] |= 1\n"),),
           ("tests/test_binvox.py", "-k", "owners")),
    Mutant("depth-draw-no-barrier", "depth layers: no barrier after a draw whose layer a dispatch then reads "
           "(GL orders it; softpipe's tile cache does not)", "glvox/methods/depth/raster.py",
           (("        rendered(self.ctx)\n", ""),),
           ("tests/test_drivers.py", "-k", "softpipe")),
    Mutant("depth-combine-break", "passalis-stencil's combine: the loop over a word's bits left by break "
           "past the row's end (softpipe's interpreter gets it wrong)", "shaders/depth/combine.comp",
           (("        uint bits = min(32u, nx - wi * 32u);\n        for (uint b = 0u; b < bits; ++b) {\n"
             "            uint i = wi * 32u + b;\n",
             "        for (uint b = 0u; b < 32u; ++b) {\n            uint i = wi * 32u + b;\n"
             "            if (i >= nx) break;\n"),),
           ("tests/test_drivers.py", "-k", "softpipe_runs")),
    Mutant("binvox-combine-break", "binvox-solid's vote: the loop over a word's bits left by break past the "
           "row's end (softpipe's interpreter gets it wrong)", "shaders/binvox/combine.comp",
           (("        uint bits = min(32u, nx - wi * 32u);\n        for (uint b = 0u; b < bits; ++b) {\n"
             "            uint i = wi * 32u + b;\n",
             "        for (uint b = 0u; b < 32u; ++b) {\n            uint i = wi * 32u + b;\n"
             "            if (i >= nx) break;\n"),),
           ("tests/test_drivers.py", "-k", "parity_vote")),
    Mutant("eisemann-logic-op-unprobed", "eisemann-*: the logic op on integer targets taken on trust, not probed",
           "glvox/methods/eisemann/slicing.py",
           (("    behaviours=(\"integer-logic-op\",))", "    behaviours=())"),),
           ("tests/test_drivers.py",)),
    Mutant("zink-inlined-uniforms-left-on", "the context factory leaves zink's inlined uniforms on",
           "glvox/gl/context.py",
           (('DRIVER_DEFAULTS = {"ZINK_INLINE_UNIFORMS": "0"}', "DRIVER_DEFAULTS = {}"),),
           ("tests/test_drivers.py", "-k", "zink")),
    Mutant("uniform-probe-blind", "the uniform-update probe runs its dispatches and reports nothing",
           "glvox/gpu/behaviours.py",
           (("    if not errors:\n        return None\n    hint", "    if True:\n        return None\n    hint"),),
           ("tests/test_drivers.py", "-k", "zink")),
    Mutant("osmesa-path-ignored", "the OSMesa backend ignores GLVOX_OSMESA (only the system's library)",
           "glvox/gl/backends.py",
           (('name = os.environ.get("GLVOX_OSMESA") or ctypes.util.find_library("OSMesa")',
             'name = ctypes.util.find_library("OSMesa")'),),
           ("tests/test_context.py", "-k", "backend")),
    Mutant("osmesa-any-gallium-driver", "OSMesa tried with whatever GALLIUM_DRIVER names (it segfaults)",
           "glvox/gl/backends.py",
           (("        if driver and driver not in OSMESA_DRIVERS:", "        if False:"),),
           ("tests/test_context.py", "-k", "osmesa")),
    Mutant("compare-counts-padding-bits", "VoxelGrid.compare counts the bits past nx in a row's last word",
           "glvox/results/voxels.py",
           (("        a, b = self.words() & mask, reference.words() & mask",
             "        a, b = self.words(), reference.words()"),),
           ("tests/test_grid.py", "-k", "compare")),
    Mutant("pack-planes-wrong-bit", "pack_bits' plane path shifts planes past x = 31 into bit 0",
           "glvox/grid.py",
           (("            packed[x >> 3] |= planes[x] << np.uint8(x & 7)",
             "            packed[x >> 3] |= planes[x] << np.uint8(x % 8 if x < 32 else 0)"),),
           ("tests/test_grid.py", "-k", "pack")),
    Mutant("report-timeout-spares-children", "a timed-out report step kills its shell but not the children "
           "it started, which run on into the next step",
           "compare/gpu_report.py",
           (("            os.killpg(proc.pid, signal.SIGKILL)", "            proc.kill()"),),
           ("tests/test_gpu_report.py", "-k", "killed")),
    Mutant("outside-profile-counts-stages", "the outside-the-stages profile keeps profiling inside the stages",
           "compare/outside_stages.py",
           (("        prof.disable()\n        try:\n            with timed_stage",
             "        try:\n            with timed_stage"),),
           ("tests/test_gpu_report.py", "-k", "outside")),
    Mutant("outside-stage-last-instance", "the outside-the-stages table keeps a repeated stage's last "
           "instance, not its sum over the call",
           "compare/outside_stages.py",
           (("                total[0] += s.wall_s", "                total[0] = s.wall_s"),),
           ("tests/test_gpu_report.py", "-k", "outside")),
    Mutant("report-sync-without-gwn", "the GPU report's sync step leaves gwn-solid out",
           "compare/gpu_report.py",
           (('SYNC_METHODS = ("ss-conservative", "ss-solid", "gwn-solid")',
             'SYNC_METHODS = ("ss-conservative", "ss-solid")'),),
           ("tests/test_gpu_report.py", "-k", "sync")),
    Mutant("far-voxels-rows-swapped", "the far-voxel diagnosis reads a listed segment's row as (k, j)",
           "compare/gwn_far_voxels.py",
           (("    j, k, seg = j0 + ids % rows % nj, k0 + ids % rows // nj, segs[0] + ids // rows",
             "    k, j, seg = k0 + ids % rows % nj, j0 + ids % rows // nj, segs[0] + ids // rows"),),
           ("tests/test_gwn.py", "-k", "far_voxels")),
    Mutant("far-voxels-block-offset", "the far-voxel diagnosis places a segment's blocks 4 voxels apart "
           "from the wrong origin",
           "compare/gwn_far_voxels.py",
           (("seg[which] * 4 * SEGV + 4 * block", "seg[which] * 4 * SEGV + 4 * block + 4"),),
           ("tests/test_gwn.py", "-k", "far_voxels")),
    Mutant("lease-peer-builds-gl-viewer", "the peer build compiles trimesh2's OpenGL viewer too "
           "(it needs GL headers the device image lacks)",
           "compare/gpu_lease.py",
           (('        if cc.name.startswith("GL"):', "        if False:"),),
           ("tests/test_gpu_report.py", "-k", "recipe")),
    Mutant("lease-peer-always-rebuilt", "the device rebuilds cuda_voxelizer even where the carried one runs",
           "compare/gpu_lease.py",
           (('    if why is None:\n        print(f"peer: {binary} runs")',
             '    if False:\n        print(f"peer: {binary} runs")'),),
           ("tests/test_gpu_report.py", "-k", "keeps")),
    Mutant("report-peer-in-the-bench", "the report's bench waits on cuda_voxelizer (a peer step no longer "
           "of its own)",
           "compare/gpu_report.py",
           (('"--repeat", "5", "--check-max", "128", "--peers", "-q"]',
             '"--repeat", "5", "--check-max", "128", "--peers", "cuda-voxelizer", "--cuda-voxelizer", '
             'str(args.cuda_voxelizer), "-q"]'),),
           ("tests/test_gpu_report.py", "-k", "peer_step")),
]


def scratch_copy(dest: Path) -> None:
    files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=ROOT, check=True,
                           capture_output=True).stdout.decode().split("\0")
    for f in filter(None, files):
        src = ROOT / f
        if src.is_file():
            (dest / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / f)


def env_for(scratch: Path) -> dict:
    from glvox.datasets import mesh_dir  # the meshes the checkout would use, by absolute path

    env = dict(os.environ)
    env["PYTHONPATH"] = str(scratch) + os.pathsep + env.get("PYTHONPATH", "")
    env["GLVOX_SHADER_PATH"] = str(scratch / "shaders")
    env.setdefault("GLVOX_MESHES", str(mesh_dir().resolve()))
    env.setdefault("GLVOX_UNPACKED_DRIVERS", str(ROOT / ".drivers"))  # git ignores it: the zink tests find it here
    return env


def run_tests(scratch: Path, tests, env) -> tuple[int, str, float]:
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-p", "no:randomly",
                        *tests], cwd=scratch, env=env, capture_output=True, text=True)
    return p.returncode, p.stdout + p.stderr, time.perf_counter() - t0


def first_failure(out: str) -> str:
    for line in out.splitlines():
        if line.startswith(("FAILED", "ERROR")):
            return line.split(" - ")[0].replace("FAILED ", "").replace("ERROR ", "ERROR ")
    return ""


def apply(scratch: Path, m: Mutant) -> str:
    """Patch the scratch file; returns its original text (restored by the caller)."""
    path = scratch / m.file
    text = path.read_text()
    new = text
    for old, rep in m.patches:
        if new.count(old) != 1:
            raise SystemExit(f"mutant {m.id}: {old!r} occurs {new.count(old)} times in {m.file}, not once")
        new = new.replace(old, rep)
    path.write_text(new)
    return text


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("-m", "--mutants", nargs="*", help="ids to run (default: all)")
    ap.add_argument("--list", action="store_true", help="list the mutants and their tests")
    ap.add_argument("--json", type=Path, help="write the results here")
    a = ap.parse_args(argv)
    chosen = [m for m in MUTANTS if not a.mutants or m.id in a.mutants]
    if a.list:
        for m in chosen:
            print(f"{m.id:32s} {m.file}: {m.why}\n{'':32s} tests: {' '.join(m.tests)}")
        return 0
    t_all = time.perf_counter()
    results = []
    with tempfile.TemporaryDirectory(prefix="glvox-mutants-") as tmp:
        scratch = Path(tmp)
        scratch_copy(scratch)
        env = env_for(scratch)
        where = subprocess.run([sys.executable, "-c", "import glvox, glvox.gl.shaders as s; "
                                "print(glvox.__file__); print(s._search_dirs()[0])"],
                               cwd=scratch, env=env, capture_output=True, text=True, check=True).stdout.split("\n")
        if not all(w.startswith(str(scratch)) for w in where[:2]):
            raise SystemExit(f"the scratch copy is not what runs: {where}")
        union = sorted({t for m in chosen for t in m.tests if t.startswith("tests/")})
        rc, out, dt = run_tests(scratch, union, env)
        print(f"unmutated: {' '.join(union)}: exit {rc} in {dt:.0f} s", flush=True)
        if rc != 0:
            print(out[-3000:])
            raise SystemExit("the tests fail unmutated: fix that first")
        for m in chosen:
            original = apply(scratch, m)
            try:
                rc, out, dt = run_tests(scratch, m.tests, env)
            finally:
                (scratch / m.file).write_text(original)
            failed = first_failure(out)
            compile_error = "ShaderError" in out or "compile" in out.lower() and "error" in out.lower() and rc != 1
            status = "killed" if rc == 1 and failed and not compile_error else ("survived" if rc == 0 else "error")
            results.append({"id": m.id, "file": m.file, "why": m.why, "status": status, "killed_by": failed,
                            "seconds": round(dt, 1), "tests": list(m.tests)})
            print(f"{m.id:32s} {status:8s} {dt:6.1f} s  {failed}", flush=True)
            if status == "error":
                print(out[-2000:])
    total = time.perf_counter() - t_all
    killed = sum(r["status"] == "killed" for r in results)
    print(f"\n{killed} of {len(results)} mutants killed in {total:.0f} s")
    if a.json:
        a.json.write_text(json.dumps({"total_seconds": round(total, 1), "mutants": results}, indent=1))
    return 0 if killed == len(results) else 1


if __name__ == "__main__":
    sys.exit(main())
