"""``glvox bench``'s report: the ratio table, the targets, every cell, where the time goes, cold starts.

Pure functions of the bench's rows (:mod:`glvox.study.bench`); markdown out.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

from glvox.tolerances import REGRESSION_TOLERANCE

from .plan import CALIBRATION, Plan

#: Published figures for scale (not measured here): cuda_voxelizer, Schwarz &
#: Seidel conservative surface voxelization of the Stanford bunny (~70k
#: triangles), as quoted in glvox issue 9.
PUBLISHED = {
    "source": "cuda_voxelizer (Schwarz & Seidel conservative surface, Stanford bunny, ~70k triangles)",
    "cpu": {"hardware": "i7-8750H, 12 threads", "ms": {256: 118, 512: 309, 1024: 1048}},
    "gpu": {"hardware": "GTX 1050 Ti", "ms": {256: 0.6, 512: 1.8, 1024: 8.6}},
}


def _ms(v) -> str:
    if v is None:
        return "-"
    return f"{v:.0f}" if v >= 100 else f"{v:.1f}" if v >= 1 else f"{v:.2f}"


def _load(v) -> str:
    return "/".join(f"{x:.1f}" for x in v)


def _ratio(v) -> str:
    if v is None:
        return "-"
    return f"{v:.3f} ({1 / v:.1f}x faster)" if v < 1 else f"{v:.2f} ({v:.1f}x slower)"


def _ordered(rows: Sequence[dict]) -> list[dict]:
    """Rows by mesh (run order), kind (surface first), glvox before peers, then N and run order."""
    meshes = list(dict.fromkeys(r["mesh"] for r in rows))
    return sorted(rows, key=lambda r: (meshes.index(r["mesh"]), r["group"] != "surface", r["peer"], r["n"]))


def cell_tables(rows: Sequence[dict]) -> str:
    """One markdown table per (mesh, N, group): every contender's times and agreement."""
    out = []
    cells: dict[tuple, list[dict]] = {}
    for r in sorted(_ordered(rows), key=lambda r: r["n"]):
        cells.setdefault((r["mesh"], r["n"], r["group"]), []).append(r)
    meshes = list(dict.fromkeys(r["mesh"] for r in rows))
    for (mesh, n, group), rs in sorted(cells.items(), key=lambda kv: (meshes.index(kv[0][0]), kv[0][1],
                                                                       kv[0][2] != "surface")):
        tri = rs[0]["triangles"]
        ref = next((r.get("reference") for r in rs if r.get("reference") and not r["peer"]), None)
        refv = next((r.get("reference_voxels") for r in rs if r.get("reference_voxels") is not None), None)
        head = f"#### {mesh} ({tri:,} triangles{'' if rs[0]['watertight'] else ', open'}), {n}^3, {group}"
        if refv is not None:
            head += f" (reference {ref}: {refv:,} voxels)"
        out += [head, "",
                "| contender | median ms | min ms | runs | cold ms | GPU ms | overhead ms | voxels | missing "
                "| extra | not ties | IoU | vs fastest peer |",
                "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in rs:
            label = f"peer {r['method']}" if r["peer"] else r["key"]
            if r["status"] != "ok":
                out.append(f"| {label} | {r['status']}: {r['error']} |" + " |" * 11)
                continue
            agree = [f"{r[k]:,}" if r.get(k) is not None else "-" for k in ("missing", "extra", "not_ties")]
            iou = f"{r['iou']:.6f}" if r.get("iou") is not None else "-"
            conv = f" (+{_ms(r['convert_ms'])} convert)" if r["peer"] else ""
            vs = _ratio(r.get("ratio")) + (f" vs {r['fastest_peer']}" if r.get("fastest_peer") else "")
            mode = " (bimodal)" if r.get("bimodal") else ""
            out.append(f"| {label} | {_ms(r['wall_ms'])}{conv} | {_ms(r['min_ms'])}{mode} | {r['runs']} | "
                       f"{_ms(r['cold_ms'])} | {_ms(r.get('gpu_ms'))} | {_ms(r.get('overhead_ms'))} | "
                       f"{r['voxels']:,} | {' | '.join(agree)} | {iou} | {vs if not r['peer'] else ''} |")
        out.append("")
    return "\n".join(out)


def ratio_table(rows: Sequence[dict]) -> str:
    """Method x size, per mesh: ratio to the fastest peer of its kind (median / median, and best run /
    best peer run); peers: median and best ms, flagged when bimodal."""
    sizes = sorted({r["n"] for r in rows})
    out = ["| mesh | kind | method | " + " | ".join(f"{n}^3" for n in sizes) + " |",
           "|---|---|---|" + "---|" * len(sizes)]
    by: dict[tuple, dict[int, dict]] = {}
    for r in _ordered(rows):
        by.setdefault((r["mesh"], r["group"], r["key"], r["peer"]), {})[r["n"]] = r
    for (mesh, group, key, is_peer), cells in by.items():
        vals = []
        for n in sizes:
            r = cells.get(n)
            if r is None:
                vals.append("")
            elif r["status"] != "ok":
                vals.append(r["status"])
            elif is_peer:
                flag = " bimodal" if r.get("bimodal") else ""
                vals.append(f"{_ms(r['wall_ms'])} ms (best {_ms(r['min_ms'])}){flag}")
            elif r.get("ratio") is None:
                vals.append(f"{_ms(r['wall_ms'])} ms (no peer)")
            else:
                vals.append(f"{r['ratio']:.3f}, best {r['ratio_best']:.3f} ({_ms(r['wall_ms'])} ms)")
        label = f"peer {key[5:]}" if is_peer else key
        out.append(f"| {mesh} | {group} | {label} | " + " | ".join(vals) + " |")
    return "\n".join(out) + "\n"


def time_table(rows: Sequence[dict]) -> str:
    """Where each glvox method's time goes: stage medians (GPU time from timestamp
    queries, wall for CPU stages such as readback), the wall time outside every
    stage (validation, uniforms, result objects: Python overhead), the cold run
    and the shader compilation inside it."""
    out = ["| mesh | N | method | median ms | GPU ms | stages (ms) | outside stages ms | cold ms (compile) |",
           "|---|---|---|---|---|---|---|---|"]
    for r in _ordered(rows):
        if r["peer"] or r["status"] != "ok":
            continue
        stages = ", ".join(f"{k} {_ms(v)}" for k, v in r.get("stages_ms", {}).items())
        out.append(f"| {r['mesh']} | {r['n']} | {r['key']} | {_ms(r['wall_ms'])} | {_ms(r.get('gpu_ms'))} | "
                   f"{stages} | {_ms(r.get('overhead_ms'))} | {_ms(r['cold_ms'])} ({_ms(r.get('compile_ms'))}) |")
    return "\n".join(out) + "\n"


def _surface_target(rows: Sequence[dict]) -> tuple[str, bool | None, str]:
    """ss-conservative (default variant) against Open3D at every size, and exact."""
    lines, met, measured = [], True, False
    for r in rows:
        if r["key"] != "ss-conservative" or r["status"] != "ok":
            continue
        o3d = (r.get("ratios") or {}).get("open3d")
        if o3d is None:
            continue
        measured = True
        exact = r.get("not_ties")
        ok = o3d < 1 and exact in (0, None)
        met &= ok
        peer = next((p for p in rows if p["key"] == "peer:open3d" and p["mesh"] == r["mesh"]
                     and p["n"] == r["n"] and p["status"] == "ok"), None)
        best = f"; best runs {r['min_ms']:.0f} vs {peer['min_ms']:.0f} ms" if peer else ""
        lines.append(f"{r['mesh']} {r['n']}^3: {r['wall_ms']:.0f} ms vs Open3D {r['wall_ms'] / o3d:.0f} ms "
                     f"(ratio {o3d:.3f}{best}), "
                     + ("not checked" if exact is None else f"{exact} mismatches that are not ties")
                     + ("" if ok else "  <-- NOT MET"))
    return ("ss-conservative (default variant) faster than Open3D at every grid size, and exact",
            met if measured else None, "\n".join(lines) or "Open3D not measured")


def _solid_target(rows: Sequence[dict]) -> tuple[str, bool | None, str]:
    """The fastest exact solid method against the fastest solid peer at 256^3 and above."""
    lines, met, measured = [], True, False
    cells: dict[tuple, list[dict]] = {}
    for r in rows:
        if r["group"] == "solid" and r["n"] >= 256 and r["status"] == "ok":
            cells.setdefault((r["mesh"], r["n"]), []).append(r)
    for (mesh, n), rs in cells.items():
        peers = [r for r in rs if r["peer"]]
        exact = [r for r in rs if not r["peer"] and r.get("exact") and r.get("not_ties", 0) == 0]
        if not peers or not exact:
            continue
        measured = True
        best, peer = min(exact, key=lambda r: r["wall_ms"]), min(peers, key=lambda r: r["wall_ms"])
        speedup = peer["wall_ms"] / best["wall_ms"]
        ok = speedup >= 10
        met &= ok
        b_min, p_min = min(r["min_ms"] for r in exact), min(r["min_ms"] for r in peers)
        lines.append(f"{mesh} {n}^3: {best['key']} {best['wall_ms']:.0f} ms vs {peer['method']} "
                     f"{peer['wall_ms']:.0f} ms: {speedup:.1f}x (best runs: {p_min / b_min:.1f}x)"
                     + ("" if ok else "  <-- NOT MET"))
    return ("fastest exact solid method at least 10x faster than the fastest solid peer at 256^3 and above",
            met if measured else None, "\n".join(lines) or "no solid cell at 256^3 or above")


def targets(rows: Sequence[dict]) -> list[tuple[str, bool | None, str]]:
    """The issue's speed targets, evaluated on ``rows``: (target, met or None when not measured, detail)."""
    return [_surface_target(rows), _solid_target(rows)]


def published_note() -> str:
    p = PUBLISHED
    cpu = ", ".join(f"{v} ms at {n}^3" for n, v in p["cpu"]["ms"].items())
    gpu = ", ".join(f"{v} ms at {n}^3" for n, v in p["gpu"]["ms"].items())
    return (f"For scale, published and not measured here: {p['source']}: CPU ({p['cpu']['hardware']}) {cpu}; "
            f"GPU ({p['gpu']['hardware']}) {gpu}.")


def cold_table(colds: Sequence[dict]) -> str:
    """A row per method of :func:`glvox.study.coldstart.cold_start`'s answers."""
    out = ["| method | start + import ms | context ms | mesh load ms | first call ms (GLSL compile) | second call ms |",
           "|---|---|---|---|---|---|"]
    for c in colds:
        if "error" in c:
            out.append(f"| {c['method']} | error: {c['error']} | | | | |")
        else:
            out.append(f"| {c['method']} | {_ms(c['import_ms'])} | {_ms(c['context_ms'])} | {_ms(c['load_ms'])} | "
                       f"{_ms(c['first_ms'])} ({_ms(c['compile_ms'])}) | {_ms(c['second_ms'])} |")
    return "\n".join(out) + "\n"


def _header(rows: Sequence[dict], machine: dict[str, Any], plan: Plan) -> list[str]:
    gl = machine.get("gl", {})
    peers = ", ".join(f"{k} {v}" for k, v in machine.get("peers", {}).items()) or "none installed"
    calib = [r["wall_ms"] for r in rows if r["group"] == CALIBRATION and r["status"] == "ok"]
    budget = f"at most {plan.budget:g} s of runs each per cell" if plan.budget is not None else "no time budget"
    return ["# glvox bench", "",
            f"Renderer: {gl.get('renderer')} ({gl.get('version')}, {gl.get('backend')}); "
            f"{machine.get('cpu_count')} CPUs; glvox {machine.get('glvox')}; peers: {peers}."
            + (f" Load average (1, 5, 15 min) at the start {_load(machine['load_average_start'])}, at the end "
               f"{_load(machine['load_average_end'])}." if "load_average_end" in machine else ""),
            f"Times are wall clock, the median of up to {plan.repeat} warm runs per contender taken in "
            f"interleaved rounds ({budget}); ratio = glvox median / "
            "median of the fastest peer of the same kind, below 1 is faster."
            + (f" A fixed GL workload timed in every round (`shaders/testing/busy.comp`, the machine factor of "
               f"the regression check) took {_ms(min(calib))}-{_ms(max(calib))} ms (median per cell)."
               if calib else ""), ""]


def regression_lines(check: dict[str, Any], baseline_path: Path | None) -> list[str]:
    """The verdict of :func:`glvox.study.regression.check` as a list item."""
    factor = check["factor"]
    f = f"{factor:.2f}" if factor else "none (no common calibration or peer cell)"
    tol = f"{REGRESSION_TOLERANCE:.0%}"
    if check["common"] == 0:
        return [f"- **not measured**: no method regresses by more than {tol}: no glvox cell of this run is in "
                f"{baseline_path} (other meshes or sizes?)", ""]
    if check["regressions"]:
        out = [f"- **NOT MET**: no method regresses by more than {tol} against {baseline_path} (machine factor, "
               f"applied when above 1: {f}):"]
        out += [f"  - {g['key']} on {g['mesh']} {g['n']}^3: best {g['base_ms']:.1f} -> {g['now_ms']:.1f} ms "
                f"(x{g['raw']:.2f}, x{g['normalized']:.2f} after the machine factor)" for g in check["regressions"]]
        return out + [""]
    return [f"- **MET**: no method regresses by more than {tol} against {baseline_path} (machine factor, applied "
            f"when above 1: {f})", ""]


def best_surface_gpu(rows: Sequence[dict], mesh: Any, n: int) -> tuple[float, str] | None:
    """The least median GPU time (all of a call's stages) of ``ss-conservative`` and its variants
    on ``mesh`` at ``n``^3 in ``rows``, with the variant's key; None where none was timed."""
    timed = [(r["gpu_ms"], r["key"]) for r in rows
             if r.get("method") == "ss-conservative" and r.get("gpu_ms") is not None
             and r["mesh"] == mesh and r["n"] == n]
    return min(timed) if timed else None


def peer_stats_table(rows: Sequence[dict], everything: Sequence[dict] = ()) -> str:
    """Per row with ``peer_stats`` (cuda_voxelizer): its process and its own kernel time, beside
    glvox's GPU time for the same cell (the best of ``ss-conservative``'s variants among
    ``everything``) and their ratio, and its voxels against glvox's ss-conservative on its own
    cube (glvox/study/peer_cuda.py)."""
    out = ["Wall = the whole process (start, PLY read, CUDA init, voxelization, binvox write); kernel = "
           "its own printed GPU time; glvox GPU = every GPU stage of the fastest ss-conservative variant "
           "in the same cell (median), and its ratio to that kernel.  Counts on its cube (1 + 2/10001 of "
           "glvox's, same center) against glvox's ss-conservative there.", "",
           "| mesh | N | wall ms | kernel ms | glvox GPU ms | glvox / kernel | device | its voxels | glvox voxels "
           "| IoU | missing | extra |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        s = r["peer_stats"]
        ours = best_surface_gpu(everything, r["mesh"], r["n"])
        kernel = s.get("kernel_ms")
        ratio = f"{ours[0] / kernel:.2f}" if ours and kernel else "-"
        glvox_gpu = f"{_ms(ours[0])} ({ours[1]})" if ours else "-"
        out.append(f"| {Path(str(r['mesh'])).name} | {r['n']} | {_ms(r.get('wall_ms'))} | {_ms(kernel)} | "
                   f"{glvox_gpu} | {ratio} | {s.get('device')} | {s.get('count')} | {s.get('glvox_count')} | "
                   f"{s.get('iou', 0):.6f} | {s.get('missing')} | {s.get('extra')} |")
    return "\n".join(out) + "\n"


def report(rows: Sequence[dict], machine: dict[str, Any], plan: Plan, check: dict[str, Any] | None = None,
           baseline_path: Path | None = None, colds: Sequence[dict] | None = None) -> str:
    """The whole bench.md: header, ratio table, targets (and the regression check), every cell,
    where the time goes, cold starts."""
    out = _header(rows, machine, plan)
    rows = [r for r in rows if r["group"] != CALIBRATION]
    out += ["## Ratio to the fastest peer of each kind", "", ratio_table(rows), "## Targets", ""]
    for name, met, detail in targets(rows):
        verdict = "not measured" if met is None else ("MET" if met else "NOT MET")
        out += [f"- **{verdict}**: {name}", "", "  " + detail.replace("\n", "\n  "), ""]
    if check is not None:
        out += regression_lines(check, baseline_path)
    out += [published_note(), "", "## Every cell", "", cell_tables(rows),
            "## Where the time goes", "", time_table(rows)]
    peer_stats = [r for r in rows if r.get("peer_stats")]
    if peer_stats:
        out += ["## cuda_voxelizer on its own cube", "", peer_stats_table(peer_stats, rows)]
    if colds:
        c0 = colds[0]
        out += ["## Cold start", "",
                f"A fresh process per method, Mesa's shader disk cache {'on' if c0.get('disk_cache') else 'off'}, "
                f"{Path(str(c0.get('mesh', ''))).name} at {c0.get('n')}^3:", "", cold_table(colds)]
    return "\n".join(out)
