"""``glvox selftest``: every registered method on this machine's GPU against the CPU references.

    glvox selftest                       # every method, a table, exit 1 on any mismatch
    glvox selftest --methods ss-conservative peel-ldi --json

Small generated meshes (and one shared mesh when it is on this machine, at no
download) on 16^3 to 32^3 grids, checked the way the test suite checks them:

* an exact method against its exact reference (``MethodInfo.reference``, with
  the options that make it comparable, :func:`glvox.study.harness.reference_of`):
  a voxel that differs counts as a mismatch unless it is a proven tie of the
  reference (:func:`glvox.metrics.tie_set`); an LDI as its parity solid
  against ``reference-ldi``'s, ``ss-octree`` as its dense grid;
* an approximate method against the bound its paper states (:data:`BOUNDS`),
  from both sides where it has two, so that an empty result never passes:
  karabassi and leung-wang-ldi only add to the exact solid; passalis-stencil
  is the exact solid outside the voxels it marks unclassifiable, which must
  lie in columns of more than four crossings along every axis; eisemann-surface
  is its CPU formulation (:func:`glvox.testing.slices.off_slices`);
  scanline-slv is the conservative surface up to its ties and scanline-rlv lies
  between it and the voxels the triangles overlap by more than the tie
  tolerance (up to its own float ties); scanline-ilv equals the CPU model of
  its integer lattice (:func:`glvox.reference.scanline.scanline_surface`);
* the CPU references define the checks and are listed, not checked.

Beside them, :func:`tie_cases`: closed meshes with vertices and edges exactly on
voxel center planes, where a column center lies on a projected edge or vertex
and only the top-left and half-open rules decide, and a hull with a face along
the render axis whose projection runs through column centers.  On an NVIDIA H100 (driver
580) every generated case passed while these failed in the test suite and a
diagnostic run: ss-solid set a voxel half a voxel outside a box,
eisemann-solid one outside a tetrahedron.

A method that fails is a failure like a mismatch; one the context refuses
(a limit, or a behaviour its probe found broken: :mod:`glvox.gpu.behaviours`)
is reported once as ``refused``, with the refusal's line, and fails the run
too: the user learns which methods do not run on that GPU and driver.  The
figure on llvmpipe (2 shared cores) is in docs/testing.md.

The first row, ``arithmetic``, checks the compiler itself
(:mod:`glvox.gpu.arithmetic`): whether it keeps ``a * b + c`` unfused where the
result is ``precise``, as GLSL 4.50 Sec. 4.9 demands and every exact shader
relies on; a fused probe is a mismatch.  Its detail lines say what GLSL leaves
free: whether plain expressions are fused, the error of ``a / b``, denormals.

The second, ``ties``, checks the arithmetic the exact solids decide ties with
(:mod:`glvox.testing.tie_probe`: coverage in integers, crossings in double): on
every (triangle, column center) pair of the tie cases, ss-solid's and
eisemann's edge functions, top-left flags, verdicts and crossings on the GPU,
in a compute and a fragment shader, must equal their model word for word
(Python's integers and numpy float64); a detail line names
each pair that differs and the quantity (the first few).  Then the methods'
own passes, traced: every crossing ss-solid's voxelize pass flips and every
fragment eisemann-solid's render draws must be a pair the model covers, from
its first voxel, and every pair the model covers must be there, and the
render's targets and packed grid must be what those fragments make; a detail
line says which step did otherwise (no fragment drawn: the rasterizer; drawn
and decided otherwise: the fragment stage; then the masks and logic op, or
the pack).

The third, ``readback``, checks the way large results leave the GPU
(:mod:`glvox.gpu.readback`; the cases above are too small to take it): a
surface and a solid at :data:`READBACK_N`^3 read into mapped buffers they own
must have the words glGetBufferSubData reads, and a result kept while another
call runs must keep its own.  Its detail line gives both ways' readback times
on this GPU.  Where CUDA sees the GL context's GPU (and ``glvox[cuda]`` is
installed), the same two results kept on the GPU (``device='cuda'``,
:mod:`glvox.gpu.cuda`) must hold the same words in CUDA memory; a last detail
line says so, or why that was not checked.
"""

from __future__ import annotations

import json
import time
import warnings
from dataclasses import asdict, dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from ..datasets import find
from ..errors import CapabilityError, GlvoxError, NotWatertightWarning, SuspiciousResultWarning
from ..gl.context import get_context
from ..gpu.arithmetic import probe_arithmetic
from ..gpu.behaviours import broken
from ..gpu.cuda import CudaSink
from ..gpu.readback import forced_mode, is_mapped, readback_pool
from ..grid import GridSpec, grid_for, pack_bits, popcount
from ..mesh import load_mesh
from ..methods import get_method, method_infos, run_method
from ..methods.depth.layers import CLASSIFIABLE_COUNT
from ..methods.scanline.voxelize import gpu_voxel_coords
from ..metrics import not_tie_words
from ..reference.scanline import float_variant_ties, scanline_surface
from ..reference.solid import column_crossings
from ..reference.surface import conservative_surface
from ..testing.cells import cells_mesh, occupancy
from ..testing.slices import off_slices
from ..testing.tie_probe import probe, trace
from ..tolerances import TIE_EPS
from . import harness
from .plan import Contender

#: (mesh, grid size along the longest side): generated meshes, then one shared
#: mesh used only when it is already on this machine.
CASES = (("gen:torus", 24), ("gen:sphere", 16), ("gen:box", 20), ("gen:bunny-like", 32))
SHARED_CASE = ("cad_fandisk.off", 24)
#: The tetrahedron of :func:`tie_cases`: at one voxel, the column's ray grazes the edge two
#: of its faces share on its silhouette.
TIE_TETRAHEDRON = (np.array([[0.5, 0, 0], [-1, 1, 0], [0, 0, 0], [0, 0, 1]]),
                   np.array([[3, 0, 1], [1, 0, 2], [2, 3, 1], [0, 3, 2]]))
#: The hull of :func:`tie_cases` (found by the slow fuzz): its face [1, 3, 2] is parallel to z
#: and its projection, a segment, runs through column centers at :data:`TIE_HULL_DIMS`,
#: collinear with edges of three other faces.  The float32 upload turns that face into a
#: sliver; edge functions in double put centers inside it and outside its neighbours, and
#: its crossing in double was voxels off (eisemann-solid: 26 voxels far from the surface).
TIE_HULL = (np.array([[1.0, 0, 0], [-0.5, 0, -0.75], [-1, 0.75, 0], [0, -0.75, 0], [0, 1, 1]]),
            np.array([[4, 0, 2], [2, 3, 4], [4, 3, 0], [2, 0, 1], [1, 3, 2], [0, 3, 1]]))
TIE_HULL_DIMS = (33, 59, 22)
#: Two box shells one inside the other, cells of uneven widths, other ones along each axis
#: (Passalis et al.'s Fig. 4 in boxes): a column through the middle crosses eight faces, past
#: the four that passalis-stencil's double-layer buffers hold, so it leaves voxels
#: unclassifiable there and the peeling methods peel more layers.  At :data:`NESTED_N`
#: voxels along x, rows end inside a word (softpipe got a loop over a word's bits wrong there:
#: docs/testing.md), and no column center lies on a face's diagonal.
NESTED_BREAKPOINTS = (np.array([0.0, 0.11, 0.27, 0.4, 0.57, 0.73, 0.86, 1.0]),
                      np.array([0.0, 0.13, 0.26, 0.43, 0.55, 0.71, 0.88, 1.0]),
                      np.array([0.0, 0.09, 0.24, 0.41, 0.6, 0.74, 0.87, 1.0]))
NESTED_N = 40
#: Boxes of :func:`tie_cases`: (x, y, z) breakpoints in world units and a grid (an int: the
#: fitted cube of that many voxels).  Faces on voxel center planes put column centers on the
#: boxes' edges and corners.  The first two are Hypothesis's finds on the H100 with the voxel
#: sizes as it printed them (rounded); the first, so rounded, failed there again.
TIE_BOXES = (
    ("box on center planes", ((0.0, 910.6738821297131), (113.83423526621414, 1138.3423526621414),
                              (0.0, 1138.3423526621414)), GridSpec((3, 3, 3), (0, 0, 0), 455.337)),
    ("box on center planes", ((0.0, 71.171875), (0.0, 88.96484375), (6.8808746337890625, 266.89453125)),
     GridSpec((3, 3, 8), (0, 0, 0), 35.5859)),
    ("box", ((0.0, 0.5), (0.0, 0.75), (0.0, 0.5)), 17),
    ("box", ((0.0, 0.5), (0.0, 0.75), (0.0, 0.5)), 19),
)
#: Grid of the ``readback`` row: 8 MiB of packed words, over the mapped threshold.
READBACK_N = 400

#: How an approximate method may differ from its reference (its paper's
#: approximation): 'superset' (only adds voxels), 'ilv-model' (equals the CPU
#: model of scanline-ilv's integer lattice), 'ties' (equals its reference up
#: to the reference's tie set, which is too coarse for the method to claim
#: exactness: binvox-solid's, whole columns; SLV's, corners), 'stencil' (the
#: reference outside the voxels it marks unclassifiable, and those only where
#: every axis's column holds more than CLASSIFIABLE_COUNT crossings), 'slices'
#: (eisemann-surface's CPU formulation) or 'between' (inside the conservative
#: surface, holding every voxel the triangles overlap by more than TIE_EPS,
#: up to the method's float ties: scanline-rlv).
BOUNDS = {
    "karabassi": "superset", "leung-wang-ldi": "superset", "passalis-stencil": "stencil",
    "eisemann-surface": "slices", "scanline-rlv": "between", "scanline-slv": "ties", "scanline-ilv": "ilv-model",
    "binvox-solid": "ties",
}


@dataclass
class Row:
    """One method's line of the table."""

    method: str
    check: str
    cases: int = 0
    mismatches: int = 0
    seconds: float = 0.0
    status: str = "ok"
    detail: list[str] = field(default_factory=list)


def nested_shells():
    """The closed mesh of :data:`NESTED_BREAKPOINTS`: the cells at Chebyshev distance 3
    (the outer shell) and 1 (the inner one) from the middle cell of 7 x 7 x 7."""
    d = np.abs(np.indices((7, 7, 7)) - 3).max(axis=0)
    v, f = cells_mesh(list(NESTED_BREAKPOINTS), (d == 3) | (d == 1))
    return load_mesh((v, f), name="nested box shells")


def tie_cases() -> list[tuple[str, object, GridSpec]]:
    """(label, mesh, grid) of the cases on voxel center planes (module docstring)."""
    tet = load_mesh(TIE_TETRAHEDRON, name="tetrahedron on an edge")
    out = [(f"{tet.name}@1", tet, grid_for(tet, dims=(1, 1, 1)))]
    for name, bp, grid in TIE_BOXES:
        v, f = cells_mesh([np.asarray(b, np.float64) for b in bp], occupancy("box"))
        mesh = load_mesh((v, f), name=name)
        spec = grid_for(mesh, grid) if isinstance(grid, int) else grid
        out.append((f"{name}@{'x'.join(map(str, spec.dims))}", mesh, spec))
    hull = load_mesh(TIE_HULL, name="hull with a face along z")
    out.append((f"{hull.name}@{'x'.join(map(str, TIE_HULL_DIMS))}", hull, grid_for(hull, dims=TIE_HULL_DIMS)))
    return out


def _words(result) -> np.ndarray:
    """Packed words of a result of any kind (an LDI's or an octree's dense solid)."""
    return (result if hasattr(result, "words") else result.to_grid()).words()


def _describe(name: str) -> str:
    info = get_method(name).info
    if info.family == "reference":
        return "reference"
    if info.exact:
        return f"exact vs {'reference-ldi' if info.kind == 'ldi' else info.reference}"
    bound = BOUNDS.get(name)
    if bound is None:
        raise GlvoxError(f"selftest has no bound for the approximate method {name!r}: add it to BOUNDS")
    return {"superset": f"bounded: contains {info.reference}",
            "stencil": f"bounded: {info.reference} where classifiable",
            "slices": "bounded: equals its CPU formulation",
            "between": f"bounded: {info.reference} less overlaps under 1e-4",
            "ilv-model": "bounded: equals the ILV model",
            "ties": f"bounded: {info.reference} up to its ties"}[bound]


def _mismatches(name: str, result, mesh, spec, refs: harness.References) -> int:
    """Voxels of ``result`` (of method ``name``) outside what its check allows."""
    info = get_method(name).info
    words = _words(result)
    if BOUNDS.get(name) == "ilv-model" and not info.exact:
        tunnel = info.options["tunnel"].default
        model = scanline_surface(gpu_voxel_coords(mesh, spec), spec.dims, "ilv", tunnel)
        return popcount(words ^ pack_bits(model))
    if info.kind == "ldi":
        ref_words, ties = refs.words("reference-solid"), refs.ties("reference-solid")
        if info.exact:
            ref_words = _words(run_method("reference-ldi", mesh, spec))
    else:
        ref, opts = harness.reference_of(Contender.of_method(name), mesh)
        ref_words = refs.words(ref, opts)
        ties = refs.ties(ref, opts)
    bound = BOUNDS.get(name)
    if info.exact or bound == "ties":
        return popcount(not_tie_words(words, ref_words, ties))
    if bound == "superset":
        return popcount(ref_words & ~words & ~ties)
    if bound == "slices":
        return int(off_slices(result.dense(), mesh, spec, info.options["axis"].default).sum())
    if bound == "stencil":
        marked = _words(result.extras["unclassifiable"])
        allowed = pack_bits(_unclassifiable(mesh, spec))
        return popcount(not_tie_words(words, ref_words, ties) & ~marked) + popcount(marked & ~allowed)
    # 'between': nothing outside the conservative surface, nothing lost that the triangles
    # overlap by more than the tie tolerance, except where RLV's float32 and float64 runs may differ
    tris = mesh.triangles_voxel(spec)
    lost = pack_bits(conservative_surface(tris, spec.dims, 0.5 - TIE_EPS)) & ~words
    if lost.any():
        lost &= ~pack_bits(float_variant_ties(tris, spec.dims, "rlv", info.options["tunnel"].default))
    return popcount(words & ~ref_words & ~ties) + popcount(lost)


def _unclassifiable(mesh, spec) -> np.ndarray:
    """Voxels no direction of passalis-stencil can classify: along every axis its column
    holds more than CLASSIFIABLE_COUNT crossings (the reference's, top-left rule), or
    is a tie of that count (a crossing within TIE_EPS of a column center's edge or vertex
    may be counted once more or less by the GPU)."""
    tris = mesh.triangles_voxel(spec)
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    out = np.ones(spec.dims, bool)
    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        keep = n[:, axis] != 0.0
        counts = np.zeros((spec.dims[u], spec.dims[v]), np.int64)
        for _, ju, jv, _q in column_crossings(tris[keep], n[keep], tuple(spec.dims), axis):
            np.add.at(counts, (ju.astype(np.int64), jv.astype(np.int64)), 1)
        crowded = counts > CLASSIFIABLE_COUNT - 1  # one crossing more or less at a tie
        shape = [1, 1, 1]
        shape[u], shape[v] = spec.dims[u], spec.dims[v]
        out &= np.broadcast_to((crowded if u < v else crowded.T).reshape(shape), spec.dims)
    return out


def _readback_ms(result) -> float:
    return 1e3 * sum(s.wall_s for s in result.run.timings.stages if s.name == "readback")


#: Detail lines of the ``ties`` row: at most this many differing pairs are named.
TIE_DETAIL = 6


def ties_row(ctx) -> Row:
    """The ``ties`` row: the tie functions on the GPU, then ss-solid's and eisemann-solid's
    own passes traced, against their float64 model (module docstring)."""
    t0 = time.perf_counter()
    row = Row("ties", "tie decisions = float64 model (edge functions, traced passes)")
    try:
        traced: list[str] = []
        for label, mesh, spec in tie_cases():
            pairs, diffs = probe(ctx, mesh, spec)
            row.cases += pairs
            row.mismatches += len(diffs)
            row.detail += [f"{label}: {d}" for d in diffs[:max(0, TIE_DETAIL - len(row.detail))]]
            pairs, diffs = trace(ctx, mesh, spec)
            row.cases += pairs
            row.mismatches += len(diffs)
            traced += [f"{label}: {d}" for d in diffs[:max(0, TIE_DETAIL - len(traced))]]
        row.detail += traced
        why = broken(ctx, "integer-logic-op")
        if why is not None:
            row.detail.append(f"eisemann-solid's render targets and pack not traced: {why} "
                              "(the methods that need the logic op are refused on this context)")
    except GlvoxError as exc:
        row.status = "error"
        row.detail.append(str(exc))
    if row.mismatches and row.status == "ok":
        row.status = "mismatch"
    row.seconds = time.perf_counter() - t0
    return row


def readback_row(ctx) -> Row:
    """The ``readback`` row: mapped against copied words (see the module)."""
    t0 = time.perf_counter()
    row = Row("readback", "mapped words = glGetBufferSubData's")
    mesh, other = load_mesh("gen:sphere"), load_mesh("gen:torus")
    spec = grid_for(mesh, READBACK_N)
    times: dict[str, list[float]] = {"copy": [], "mapped": []}
    try:
        for name in ("ss-conservative", "ss-solid"):
            with forced_mode("copy"):
                want = run_method(name, mesh, spec, ctx=ctx)
            with forced_mode("mapped"):
                got = run_method(name, mesh, spec, ctx=ctx)
                kept = np.array(got.words())
                later = run_method(name, other, spec, ctx=ctx)  # while got is kept
            row.cases += 1
            row.mismatches += popcount(got.words() ^ want.words()) + popcount(got.words() ^ kept)
            times["copy"].append(_readback_ms(want))
            times["mapped"].append(_readback_ms(got))
            if not is_mapped(got.words()):
                row.detail.append("results are copied: this context lends no mapped memory "
                                  f"({'no persistent mapping' if readback_pool(ctx).unmappable else 'limit reached'})")
            del got, later
    except GlvoxError as exc:
        row.status = "error"
        row.detail.append(str(exc))
    if row.mismatches and row.status == "ok":
        row.status = "mismatch"
    mib = spec.n_words * 4 / 2**20
    row.detail.append(f"{mib:.0f} MiB per result, readback stage: mapped " +
                      ", ".join(f"{t:.1f}" for t in times["mapped"]) + " ms, copied " +
                      ", ".join(f"{t:.1f}" for t in times["copy"]) + " ms")
    row.detail.append(_device_check(ctx, mesh, spec, row))
    row.seconds = time.perf_counter() - t0
    return row


def _device_check(ctx, mesh, spec, row: Row) -> str:
    """The readback row's ``device='cuda'`` part: its detail line."""
    try:
        CudaSink().open_device(ctx)
    except CapabilityError as exc:
        why = str(exc).removeprefix("device='cuda'").lstrip(": ")
        return f"device='cuda' not checked: {why}"
    times, before = [], row.mismatches
    try:
        for name in ("ss-conservative", "ss-solid"):
            want = run_method(name, mesh, spec, ctx=ctx, device="host")
            got = run_method(name, mesh, spec, ctx=ctx, device="cuda")
            row.cases += 1
            row.mismatches += popcount(got.device_words.to_host() ^ want.words())
            times.append(_readback_ms(got))
    except GlvoxError as exc:
        row.status = "error"
        return f"device='cuda': {exc}"
    stage = "readback stage " + ", ".join(f"{t:.1f}" for t in times) + " ms"
    if row.mismatches > before:
        row.status = "mismatch" if row.status == "ok" else row.status
        return f"device='cuda': {row.mismatches - before} voxels differ in CUDA memory, {stage}"
    return f"device='cuda': the same words in CUDA memory, {stage}"


def selftest(methods: Sequence[str] | None = None, progress: Callable[[str], None] = lambda s: None,
             ctx=None) -> dict[str, Any]:
    """Run ``methods`` (default: every registered one) on :data:`CASES` and check each.

    Returns
    -------
    dict
        ``renderer``, ``vendor``, ``version``, ``cases`` (``'mesh@n'``), ``methods``
        (one :class:`Row` as a dict each: method, check, cases, mismatches,
        seconds of the method's runs, status 'ok' / 'mismatch' / 'error' / 'refused',
        detail lines; the first three are the compiler's ``arithmetic``, the
        ``ties`` and the ``readback`` row), ``arithmetic``
        (:class:`~glvox.gpu.arithmetic.ArithmeticReport` as a dict), ``ok`` and
        ``seconds`` (the whole test).
    """
    t_all = time.perf_counter()
    ctx = ctx if ctx is not None else get_context()
    names = list(methods) if methods else [i.name for i in method_infos()]
    progress("arithmetic: precise kept?")
    t0 = time.perf_counter()
    arith = probe_arithmetic(ctx)
    arith_row = Row("arithmetic", "precise a*b+c unfused (GLSL 4.50 Sec. 4.9)", cases=4 * arith.probes,
                    mismatches=arith.fused_precise_float + arith.fused_precise_double,
                    seconds=time.perf_counter() - t0, status="ok" if arith.ok else "mismatch", detail=arith.notes)
    progress("ties: edge functions against their model")
    tie_row = ties_row(ctx)
    progress("readback: mapped words")
    read_row = readback_row(ctx)
    rows = {n: Row(n, _describe(n)) for n in names}
    named = list(CASES)
    shared = find(SHARED_CASE[0])
    if shared is not None:
        named.append((str(shared), SHARED_CASE[1]))
    cases = []
    for mesh_name, n in named:
        mesh = load_mesh(mesh_name)
        cases.append((f"{mesh.name or mesh_name}@{n}", mesh, grid_for(mesh, n)))
    nested = nested_shells()
    cases.append((f"{nested.name}@{NESTED_N}", nested, grid_for(nested, NESTED_N)))
    labels = []
    for label, mesh, spec in cases + tie_cases():
        labels.append(label)
        refs = harness.References(mesh, spec)
        for name in names:
            row = rows[name]
            if row.status == "refused":
                continue
            progress(f"{label}: {name}")
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", NotWatertightWarning)
                    # the tetrahedron's one voxel is empty by design; the check says what is wrong
                    warnings.simplefilter("ignore", SuspiciousResultWarning)
                    t0 = time.perf_counter()
                    result = run_method(name, mesh, spec, ctx=ctx if get_method(name).info.uses_gl else None)
                    row.seconds += time.perf_counter() - t0
                    row.cases += 1
                    if row.check == "reference":
                        continue
                    bad = _mismatches(name, result, mesh, spec, refs)
            except CapabilityError as exc:
                row.status = "refused"
                row.detail.append(f"refused: {exc}")
                continue
            except GlvoxError as exc:
                row.status = "error"
                row.detail.append(f"{label}: {exc}")
                continue
            if bad:
                row.mismatches += bad
                row.status = "error" if row.status == "error" else "mismatch"
                row.detail.append(f"{label}: {bad} voxels outside the check")
    out_rows = [asdict(arith_row), asdict(tie_row), asdict(read_row)] + [asdict(r) for r in rows.values()]
    return {"renderer": ctx.renderer, "vendor": ctx.vendor, "version": ctx.version, "cases": labels,
            "methods": out_rows, "arithmetic": asdict(arith), "ok": all(r["status"] == "ok" for r in out_rows),
            "seconds": time.perf_counter() - t_all}


def print_report(report: dict[str, Any]) -> None:
    """The table: method, check, cases, mismatches, seconds, status (details below it)."""
    rows = report["methods"]
    w = max([len(r["method"]) for r in rows] + [6])
    c = max([len(r["check"]) for r in rows] + [5])
    print(f"{'method':<{w}}  {'check':<{c}}  {'cases':>5}  {'mismatches':>10}  {'time s':>7}  status")
    for r in rows:
        print(f"{r['method']:<{w}}  {r['check']:<{c}}  {r['cases']:>5}  {r['mismatches']:>10}  "
              f"{r['seconds']:>7.2f}  {r['status']}")
    for r in rows:
        for line in r["detail"]:
            print(f"  {r['method']}: {line}")
    failed = [r["method"] for r in rows if r["status"] != "ok"]
    verdict = "all methods agree with their checks" if not failed else f"FAILED: {', '.join(failed)}"
    print(f"{verdict} ({report['seconds']:.1f} s)")


def main(args) -> int:
    """``glvox selftest``: exit 0 when every method passes its check, 1 otherwise."""
    ctx = get_context(getattr(args, "backend", None))
    head = {"renderer": ctx.renderer, "vendor": ctx.vendor, "version": ctx.version}
    if not args.json:
        for key, value in head.items():
            print(f"{key + ':':<10} {value}", flush=True)
    progress = (lambda s: None) if args.json or args.quiet else (lambda s: print(f"  {s}", flush=True))
    report = selftest(args.methods, progress=progress, ctx=ctx)
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print(f"cases:     {', '.join(report['cases'])}")
        print_report(report)
    return 0 if report["ok"] else 1
