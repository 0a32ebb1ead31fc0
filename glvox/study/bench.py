"""``glvox bench``: glvox against the voxelizers people use today, side by side.

    glvox bench --preset quick                     # the ratio table in a few minutes
    glvox bench --preset full -o results/bench     # bunny and dragon, 128^3 to 1024^3
    glvox bench --preset quick --check             # no-regression check against compare/bench_baseline.json
    glvox bench --preset quick --save-baseline compare/bench_baseline.json   # refresh the checkout's baseline
    glvox bench --preset quick --against HEAD~1    # side by side with an earlier revision (:mod:`.ab`)
    glvox bench --sdf --meshes stanford_bunny_bun_zipper.ply -r 128   # glvox sdf against its peers (:mod:`.sdf_bench`)

A thin layer over the study's runner (:mod:`glvox.study.harness`, whose
docstring gives the timing protocol): every glvox GPU method and every
installed peer (:mod:`.peers`) on the same mesh and grid in one process,
solid methods on open meshes too (parity of crossings), and the calibration
workload (:mod:`.calibration`) timed in every round.  On top of the rows
this layer adds the ratio of each glvox method to the fastest peer of its
kind (surface: Open3D, trimesh; solid: trimesh fill, PyVista, libigl;
glvox's sparse ss-octree counts as solid; below 1 is faster), the
regression check against a baseline (:mod:`.regression`), the cold start
of each method in a fresh process (:mod:`.coldstart`) and the report
(:mod:`.bench_report`).
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path
from typing import Any, Callable, Sequence

from glvox.errors import GlvoxError
from glvox.methods import get_method, method_names
from glvox.progress import Progress, Stages
from glvox.tolerances import REGRESSION_TOLERANCE

from . import ab, endtoend, harness, regression, sdf_bench
from .bench_report import report
from .coldstart import cold_start
from ..datasets import resolve_mesh
from .options import AB_REPEAT, BENCH_BUDGET, BENCH_PRESETS, BENCH_REPEAT
from .peers import PEERS, get_peer
from .plan import CALIBRATION_CONTENDER, Contender, Plan

#: Variants benchmarked beside a method's default (their own rows).
VARIANTS: dict[str, list[dict[str, Any]]] = {
    "ss-conservative": [{"variant": "simple"}, {"variant": "specialized"}, {"variant": "sorted"}],
}

#: Kinds of glvox method the bench races against the peers.
KINDS = ("surface", "solid", "sparse")


def glvox_contenders(methods: Sequence[str] | None = None, variants: bool = True) -> list[Contender]:
    """The glvox methods of kinds surface, solid and sparse (every registered GPU one
    when ``methods`` is None), each default plus the :data:`VARIANTS` beside it."""
    out = []
    for name in (list(methods) if methods else method_names()):
        info = get_method(name).info  # unknown names: one error listing the known ones
        if info.kind not in KINDS or (methods is None and not info.uses_gl):
            continue
        out.append(Contender.of_method(name))
        out += [Contender.of_method(name, opts) for opts in (VARIANTS.get(name, []) if variants else [])]
    return out


def peer_contenders(names: Sequence[str] | None, log: Callable[[str], None]) -> list[Contender]:
    """The installed peers among ``names`` (all when None); a line per missing one."""
    out = []
    for name in (names if names is not None else list(PEERS)):
        why = get_peer(name).missing()
        if why:
            log(why)
            continue
        out.append(Contender.of_peer(name))
    return out


def add_ratios(rows: list[dict[str, Any]]) -> None:
    """Put on each glvox row its ratio to the fastest peer of its group in its cell
    (``ratio``, medians, ``fastest_peer``), best run to best peer run (``ratio_best``),
    and to every peer of that group (``ratios``)."""
    cells: dict[tuple, list[dict]] = {}
    for r in rows:
        cells.setdefault((r["mesh"], r["n"], r["group"]), []).append(r)
    for group_rows in cells.values():
        peers = [r for r in group_rows if r["peer"] and r["status"] == "ok"]
        if not peers:
            continue
        fastest = min(peers, key=lambda r: r["wall_ms"])
        best = min(p["min_ms"] for p in peers)
        for r in group_rows:
            if r["peer"] or r["status"] != "ok":
                continue
            r["fastest_peer"] = fastest["method"]
            r["ratio"] = r["wall_ms"] / fastest["wall_ms"]
            r["ratio_best"] = r["min_ms"] / best  # best run against the best run of any peer
            r["ratios"] = {p["method"]: r["wall_ms"] / p["wall_ms"] for p in peers}


def run_plan(plan: Plan, *, log: Callable[[str], None] = lambda s: None,
             progress: Progress | None = None) -> list[dict[str, Any]]:
    """Every cell of ``plan`` with the calibration workload beside the contenders;
    rows in mesh, size, contender order, ratios added.  ``progress`` counts the
    cells (the calibration rows included) and shows the step at hand."""
    if CALIBRATION_CONTENDER not in plan.contenders:
        plan = Plan(**{**vars(plan), "contenders": [*plan.contenders, CALIBRATION_CONTENDER]})
    if progress is None:
        rows = harness.run_plan(plan, log=log)
    else:
        progress.total += len(plan.cells())
        rows = harness.run_plan(plan, log=log, progress=progress.status,
                                on_rows=lambda new: progress.update(len(new)))
    add_ratios(rows)
    return rows


# ---------------------------------------------------------------------------
# the plan from the command line
# ---------------------------------------------------------------------------


def _peer_max(items: Sequence[str]) -> dict[str, int | None]:
    out: dict[str, int | None] = {}
    for item in items:
        name, _, val = item.partition("=")
        get_peer(name)
        if not val:
            raise GlvoxError(f"--peer-max takes PEER=N, got {item!r}")
        if val.lower() == "none":
            out[name] = None
        else:
            try:
                out[name] = int(val)
            except ValueError:
                raise GlvoxError(f"--peer-max takes PEER=N with N an integer or 'none', got {item!r}") from None
    return out


def _meshes(args, preset: dict[str, Any], log: Callable[[str], None]) -> list[str]:
    """The plan's meshes, resolved; a preset's absent shared mesh is replaced by its fallback."""
    resolved = []
    for m in args.meshes or preset.get("meshes") or []:
        try:
            resolved.append(resolve_mesh(m))
        except GlvoxError as exc:
            alt = preset.get("fallback", {}).get(m)
            if alt is None or args.meshes:
                raise
            log(f"using {alt} in place of {m}: {exc}")
            resolved.append(alt)
    return resolved


def plan_from(args, log: Callable[[str], None]) -> Plan:
    preset = BENCH_PRESETS.get(args.preset or "", {})
    sizes = args.sizes or preset.get("sizes")
    if not (args.meshes or preset.get("meshes")) or not sizes:
        raise GlvoxError("give --preset quick|full, or --meshes and -r/--sizes")
    meshes = _meshes(args, preset, log)
    if any(n < 1 for n in sizes):
        raise GlvoxError(f"grid sizes must be positive, got {sizes}")
    contenders = glvox_contenders(args.methods, variants=not args.no_variants)
    contenders += peer_contenders(args.peers, log)
    return Plan(meshes=meshes, sizes=sorted(set(sizes)), contenders=contenders,
                repeat=args.repeat or preset.get("repeat", BENCH_REPEAT),
                budget=args.budget or preset.get("budget", BENCH_BUDGET),
                check_max=args.check_max, peer_max=_peer_max(args.peer_max))


def machine_info(plan: Plan) -> dict[str, Any]:
    m = harness.machine()
    m["peers"] = {c.peer: get_peer(c.peer).version() for c in plan.contenders if c.is_peer}
    # other work on a shared machine moves absolute times; say how busy it was
    m["load_average_start"] = list(os.getloadavg())
    return m


# ---------------------------------------------------------------------------
# the command
# ---------------------------------------------------------------------------


def _against(args, log, progress) -> int:
    """``--against REV``: exit 3 when a cell regressed (:mod:`.ab`)."""
    plan = plan_from(args, log)
    plan.repeat = args.repeat or AB_REPEAT
    ab_rows, text = ab.run_against(plan, args.against, REGRESSION_TOLERANCE, progress)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "ab.md").write_text(text + "\n")
        log(f"wrote {out / 'ab.md'}")
    print(text)
    return 3 if any(r.get("regressed") for r in ab_rows) else 0


def _confirm(plan: Plan, rows: list[dict[str, Any]], baseline: dict[str, Any], log,
             progress: Progress) -> dict[str, Any]:
    """The regression check, with suspects measured again (twice the rounds, each keeping its best)."""
    check = regression.check(rows, baseline["rows"])
    if check["regressions"]:
        suspects = {g["key"] for g in check["regressions"]}
        log(f"possible regressions in {sorted(suspects)}: measuring them again")
        again = Plan(plan.meshes, plan.sizes, [c for c in plan.contenders if c.key in suspects],
                     repeat=2 * plan.repeat, budget=2 * plan.budget, check_max=0, peer_max=plan.peer_max)
        regression.keep_best(rows, run_plan(again, progress=progress))
        check["regressions"] = regression.check_regressions(rows, baseline["rows"], check["factor"])
    return check


def _cold_starts(plan: Plan, progress: Progress) -> list[dict[str, Any]]:
    methods = list(dict.fromkeys(c.method for c in plan.contenders if c.method is not None))
    progress.total += len(methods)
    colds = []
    for m in methods:
        progress.status(f"cold start of {m} in a fresh process")
        colds.append(cold_start(m, plan.meshes[0], min(plan.sizes)))
        progress.update()
    return colds


def _end_to_end(args, log, progress) -> int:
    """``--end-to-end [FOLDER]``: whole jobs per file (:mod:`.endtoend`)."""
    n = (args.sizes or [64])[0]
    files = endtoend.files_of(args.end_to_end or None)
    jobs = endtoend.contenders(args.methods, args.peers, n, log)
    repeat = args.repeat or BENCH_REPEAT
    load = os.getloadavg()
    times = endtoend.run(files, jobs, repeat, progress)
    text = endtoend.report(times, n, repeat)
    text += (f"\n\nLoad average (1 min) {load[0]:.2f} at the start, {os.getloadavg()[0]:.2f} at the end "
             f"({os.cpu_count()} CPUs).")
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "end_to_end.md").write_text(text + "\n")
        (out / "end_to_end.json").write_text(json.dumps({"n": n, "repeat": repeat, "times_s": times}, indent=1))
        log(f"wrote {out / 'end_to_end.md'}")
    print(text)
    return 0


def _sdf(args, log) -> int:
    """``--sdf``: signed distance fields against the SDF peers (:mod:`.sdf_bench`)."""
    load = os.getloadavg()[0]
    rows = sdf_bench.run(list(args.meshes), sorted(set(args.sizes)), args.repeat or 1, log)
    text = sdf_bench.report(rows, (load, os.getloadavg()[0]))
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "sdf_bench.md").write_text(text + "\n")
        (out / "sdf_bench.json").write_text(json.dumps(rows, indent=1))
        log(f"wrote {out / 'sdf_bench.md'}")
    print(json.dumps(rows, indent=1) if args.json else text)
    return 0


def main(args) -> int:
    """``glvox bench`` with parsed ``args`` (:func:`glvox.study.options.add_bench_arguments`);
    exit status 3 when ``--check`` or ``--against`` finds a regression."""
    def log(msg: str) -> None:
        if not args.quiet:
            print(msg, file=sys.stderr, flush=True)

    t_start = time.perf_counter()
    get_peer("cuda-voxelizer").configure(getattr(args, "cuda_voxelizer", None))
    if args.end_to_end is not None:
        return _end_to_end(args, log, Stages(quiet=args.quiet))
    if getattr(args, "sdf", False):  # a Namespace built by hand may lack it
        return _sdf(args, log)
    if args.against:
        code = _against(args, log, Stages(quiet=args.quiet))
        log(f"done in {time.perf_counter() - t_start:.0f} s")
        return code
    plan = plan_from(args, log)
    check_path = regression.baseline_path(args.check) if args.check else None
    baseline = regression.load_baseline(check_path) if check_path else None
    save_path = Path(args.save_baseline) if args.save_baseline else None
    machine = machine_info(plan)
    log(f"{len(plan.contenders)} contenders x {len(plan.meshes)} meshes x sizes {list(plan.sizes)}; "
        f"renderer {machine['gl']['renderer']}")
    with Progress(0, unit="cell", enabled=not args.quiet) as progress:  # run_plan adds its cells
        rows = run_plan(plan, log=log, progress=progress)
        check = _confirm(plan, rows, baseline, log, progress) if baseline is not None else None
        machine["load_average_end"] = list(os.getloadavg())
        colds = _cold_starts(plan, progress) if args.cold_start else None
    result = {"machine": machine, "plan": {"meshes": list(plan.meshes), "sizes": list(plan.sizes),
                                           "repeat": plan.repeat, "budget": plan.budget, "preset": args.preset},
              "rows": rows, "cold_start": colds, "seconds": time.perf_counter() - t_start}
    text = report(rows, machine, plan, check, check_path, colds)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "results.json").write_text(json.dumps(result, indent=1))
        (out / "bench.md").write_text(text)
        log(f"wrote {out / 'bench.md'} and {out / 'results.json'}")
    if save_path:
        save_path.write_text(json.dumps(result, indent=1))
        log(f"wrote the baseline {save_path}")
    print(json.dumps(result, indent=1) if args.json else text)
    log(f"done in {time.perf_counter() - t_start:.0f} s")
    return 3 if check and check["regressions"] else 0

