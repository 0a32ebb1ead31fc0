"""``glvox compare``'s tables and plots, from the runner's rows.

Markdown tables are laid out like the papers' (mesh x grid rows, method
columns); plots are PNG files drawn with matplotlib's Agg backend (no display).
A method or peer has one line style (:func:`style_for`) in every plot; in the
bar charts methods are the bars' places and the colours are the meshes'.
"""

from __future__ import annotations

import zlib
from collections import OrderedDict
from pathlib import Path
from typing import Any, Sequence

from glvox.methods import get_method, method_names

from .peers import PEERS


def _label(r: dict[str, Any]) -> str:
    opts = r.get("options") or {}
    return r["method"] + (f" ({', '.join(f'{k}={v}' for k, v in opts.items())})" if opts else "")


def _grid(rows: Sequence[dict[str, Any]]):
    """(row keys in order, column labels in order, {(row key, column): row})."""
    keys: OrderedDict = OrderedDict()
    cols: OrderedDict = OrderedDict()
    cells = {}
    for r in rows:
        rk = (r["mesh"], r["triangles"], r["n"])
        keys[rk] = None
        cols[_label(r)] = None
        cells[(rk, _label(r))] = r
    return list(keys), list(cols), cells


def _table(rows, fmt, title: str, note: str = "") -> str:
    keys, cols, cells = _grid(rows)
    out = [f"### {title}", ""]
    if note:
        out += [note, ""]
    out.append("| model | grid | " + " | ".join(f"`{c}`" for c in cols) + " |")
    out.append("|---|---|" + "---|" * len(cols))
    for rk in keys:
        mesh, tris, n = rk
        vals = []
        for c in cols:
            r = cells.get((rk, c))
            vals.append("" if r is None else (r["status"] if r["status"] != "ok" else fmt(r)))
        out.append(f"| {mesh} ({tris:,} tris) | {n}^3 | " + " | ".join(vals) + " |")
    return "\n".join(out) + "\n"


def _ms(v) -> str:
    return "-" if v is None else (f"{v:.0f}" if v >= 100 else f"{v:.2f}" if v < 1 else f"{v:.1f}")


#: What a time served from a cache carries in the tables (the row's ``cached``).
CACHED_MARK = " *cached*"

#: The tables' note on :data:`CACHED_MARK`.
CACHED_NOTE = ("*cached*: the timed runs reused a result computed before (reference-gwn keeps the winding "
               "field per mesh and grid), so the time is not the computation's; `cold_ms` in the CSV is the "
               "first run's, uncached unless `cold_cached`. Cached rows are left out of the timing plots.")


def _cached(r: dict[str, Any]) -> str:
    return CACHED_MARK if r.get("cached") else ""


def timing_series(rows: Sequence[dict[str, Any]], mesh: str) -> dict[str, list[tuple[int, float]]]:
    """What :func:`plot_times` draws for ``mesh``: per method label, (N, ms) sorted by N, GPU
    time where measured else wall; rows that did not run and rows whose time came from a
    cache (``cached``) left out, so a reused result never passes for a fast method."""
    series: dict[str, list[tuple[int, float]]] = {}
    for r in rows:
        if r["mesh"] != mesh or r["status"] != "ok" or r.get("cached"):
            continue
        t = r["gpu_ms"] if r.get("gpu_ms") else r.get("wall_ms")
        if t is not None:
            series.setdefault(_label(r), []).append((r["n"], t))
    return {label: sorted(pts) for label, pts in series.items()}


def summary_table(rows) -> str:
    """One row per method at the largest size: time, voxels and agreement per mesh."""
    ok = [r for r in rows if r["status"] in ("ok", "skipped")]
    if not ok:
        return ""
    n = max(r["n"] for r in ok)
    at = [r for r in ok if r["n"] == n]
    meshes = list(dict.fromkeys(r["mesh"] for r in at))
    labels = list(dict.fromkeys(_label(r) for r in at))
    out = [f"### Summary at {n}^3: GPU ms (wall for CPU references) / voxels / IoU against the reference", "",
           *([CACHED_NOTE, ""] if any(r.get("cached") for r in at) else []),
           "| method | kind | " + " | ".join(meshes) + " |", "|---|---|" + "---|" * len(meshes)]
    for lb in labels:
        cells, kind = [], ""
        for m in meshes:
            r = next((r for r in at if r["mesh"] == m and _label(r) == lb), None)
            if r is None:
                cells.append("")
                continue
            kind = r["kind"]
            if r["status"] != "ok":
                cells.append("skipped (open mesh)" if "watertight" in (r["error"] or "") else r["status"])
                continue
            t = r.get("gpu_ms") if r.get("gpu_ms") is not None else r.get("wall_ms")
            c = f"{_ms(t)} ms{_cached(r)}"
            if r.get("voxels") is not None:
                c += f" / {r['voxels']:,}"
            if r.get("iou") is not None:
                c += f" / {r['iou']:.4f}" + (f" ({r['not_ties']} not ties)" if r.get("not_ties") else "")
            cells.append(c)
        out.append(f"| `{lb}` | {kind} | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def time_table(rows) -> str:
    note = ("GPU time sums the stages' GL_TIMESTAMP intervals; CPU references have wall time only. "
            "Cold runs (with shader compilation) are in the CSV (`cold_ms`, `compile_ms`).")
    if any(r.get("cached") for r in rows):
        note += " " + CACHED_NOTE
    return _table(rows, lambda r: f"{_ms(r.get('wall_ms'))} ({_ms(r.get('gpu_ms'))}){_cached(r)}",
                  "Time (ms): wall (GPU), median of warm runs", note)


def count_table(rows) -> str:
    def fmt(r):
        v = r.get("voxels")
        if v is None:
            return "-"
        s = f"{v / 1e3:.1f}k" if v >= 1000 else str(v)
        if r.get("iou") is not None:
            s += f" / {r['iou']:.4f}"
            if r.get("not_ties"):
                s += f" / **{r['not_ties']} not ties**"
        return s
    return _table(rows, fmt, "Voxels / IoU against the exact reference",
                  "IoU is against the method's registered reference (`glvox methods`); mismatches are "
                  "counted as *not ties* when they are not proven float ties. Blank IoU: grid above "
                  "the check limit.")


def error_table(rows) -> str:
    checked = [r for r in rows if r.get("iou") is not None]
    if not checked:
        return ""
    return _table(checked, lambda r: f"{r['missing']} / {r['extra']}",
                  "Missing / extra voxels against the exact reference")


def separability_table(rows) -> str:
    sep = [r for r in rows if r.get("leaks_26") is not None]
    if not sep:
        return ""
    return _table(sep, lambda r: f"{r['leaks_26']} / {r['leaks_6']}",
                  "Separability on closed meshes: inside voxels reached from outside by 26- / 6-paths "
                  "of empty voxels (0 / 0: 26-separating; >0 / 0: 6-separating only)")


def stage_table(rows) -> str:
    staged = [r for r in rows if r["status"] == "ok" and r.get("stages_ms")]
    if not staged:
        return ""
    out = ["### Stages (ms, GPU where timed, median)", "",
           "| method | model | grid | stages |", "|---|---|---|---|"]
    for r in staged:
        parts = ", ".join(f"{k} {_ms(v)}" for k, v in r["stages_ms"].items())
        out.append(f"| `{_label(r)}` | {r['mesh']} | {r['n']}^3 | {parts} |")
    return "\n".join(out) + "\n"


def tiled_table(rows) -> str:
    """Schwarz & Seidel Table 2's layout for ss-solid-tiled."""
    tiled = [r for r in rows if r["method"] == "ss-solid-tiled" and r["status"] == "ok"]
    if not tiled:
        return ""
    tri = {(r["mesh"], r["n"]): r for r in rows if r["method"] == "ss-solid" and r["status"] == "ok"}
    out = ["### Tile-based solid voxelization (Schwarz & Seidel Table 2)", "",
           "| model | grid | tri-parallel | T_total | T_pairs | T_sort | T_tiles | #pairs | #tris |",
           "|---|---|---|---|---|---|---|---|---|"]
    for r in tiled:
        s, st = r["stages_ms"], r["stats"]
        t = tri.get((r["mesh"], r["n"]))
        out.append(
            f"| {r['mesh']} | {r['n']}^3 | {_ms(t.get('gpu_ms')) if t else '-'} | {_ms(r.get('gpu_ms'))} | "
            f"{_ms(s.get('classify', 0) + s.get('pairs', 0))} | {_ms(s.get('sort'))} | "
            f"{_ms(s.get('compact', 0) + s.get('tiles', 0))} | {st.get('pairs', 0) / 1e3:.0f}k | "
            f"{st.get('triangles_per_active_tile', 0):.1f} |")
    return "\n".join(out) + "\n"


def octree_table(rows) -> str:
    """Schwarz & Seidel Table 3's layout for ss-octree (whatever memory stats it reports)."""
    octs = [r for r in rows if r["method"] == "ss-octree" and r["status"] == "ok"]
    if not octs:
        return ""
    keys = []
    for r in octs:
        keys += [k for k in r["stats"] if k not in keys and isinstance(r["stats"][k], (int, float))
                 and k not in ("triangles", "degenerate_dropped", "watertight")]
    out = ["### Sparse octree (Schwarz & Seidel Table 3)", "",
           "| model | grid | time | stages | " + " | ".join(keys) + " |",
           "|---|---|---|---|" + "---|" * len(keys)]
    for r in octs:
        stages = ", ".join(f"{k} {_ms(v)}" for k, v in r["stages_ms"].items())
        vals = [str(r["stats"].get(k, "")) for k in keys]
        out.append(f"| {r['mesh']} | {r['n']}^3 | {_ms(r.get('gpu_ms'))} | {stages} | " + " | ".join(vals) + " |")
    return "\n".join(out) + "\n"


def open_table(rows) -> str:
    """The open-mesh study (``--preset open``): every solid method against the plan's
    reference, per mesh at the largest size: IoU, missing / extra voxels, and the
    share of those mismatches lying where the winding number is uncertain."""
    study = [r for r in rows if r.get("uncertain_share") is not None and r.get("iou") is not None]
    if not study:
        return ""
    n = max(r["n"] for r in study)
    at = [r for r in study if r["n"] == n]
    meshes = list(dict.fromkeys(r["mesh"] for r in at))
    ref = at[0]["reference"]
    share = {m: next(r["uncertain_share"] for r in at if r["mesh"] == m) for m in meshes}
    out = [f"### Open meshes at {n}^3 against `{ref}`: IoU / missing / extra (share of the mismatches "
           f"in the uncertain band) / ms", "",
           "| method | " + " | ".join(meshes) + " |", "|---|" + "---|" * len(meshes),
           "| *uncertain share* | " + " | ".join(f"{share[m]:.4f}" for m in meshes) + " |"]
    for lb in dict.fromkeys(_label(r) for r in at):
        cells = []
        for m in meshes:
            r = next((r for r in at if r["mesh"] == m and _label(r) == lb), None)
            if r is None:
                cells.append("")
                continue
            t = r.get("gpu_ms") if r.get("gpu_ms") is not None else r.get("wall_ms")
            band = r.get("mismatch_uncertain")
            cells.append(f"{r['iou']:.4f} / {r['missing']:,} / {r['extra']:,}"
                         + (f" ({band:.2f})" if band is not None else "") + f" / {_ms(t)}{_cached(r)}")
        out.append(f"| `{lb}` | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def markdown(rows: Sequence[dict[str, Any]], machine: dict[str, Any]) -> str:
    gl = machine.get("gl", {})
    head = ["# glvox comparison", "",
            f"{gl.get('renderer', '?')}; OpenGL {gl.get('version', '?')}; glvox {machine.get('glvox')}, "
            f"moderngl {machine.get('moderngl')}, trimesh {machine.get('trimesh')}, "
            f"Python {machine.get('python')}, {machine.get('cpu_count')} CPUs.", ""]
    parts = [open_table(rows), summary_table(rows), time_table(rows), count_table(rows), error_table(rows), separability_table(rows),
             tiled_table(rows), octree_table(rows), stage_table(rows)]
    failed = [r for r in rows if r["status"] not in ("ok",)]
    if failed:
        parts.append("### Not run\n\n" + "\n".join(f"- `{_label(r)}` on {r['mesh']} at {r['n']}^3: "
                                                    f"{r['status']}: {r['error']}" for r in failed) + "\n")
    return "\n".join(head) + "\n".join(p for p in parts if p)


# -- plots -------------------------------------------------------------------------

#: matplotlib's tab20, dark hues then light ones (written out: no matplotlib to pick a style).
TAB20 = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
         "#17becf", "#aec7e8", "#ffbb78", "#98df8a", "#ff9896", "#c5b0d5", "#c49c94", "#f7b6d2", "#c7c7c7",
         "#dbdb8d", "#9edae5")
#: 9 markers: 9 and 20 are coprime, so the i-th name's (colour, marker) repeats only after 180 names.
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">")
#: Line styles by what runs: GPU methods solid, CPU references dashed, peers dotted; a label with
#: options dash-dotted.
LINESTYLES = {"gpu": "-", "cpu": "--", "peer": ":", "options": "-."}


def _style_names() -> list[str]:
    """Every name a plot can show, in a fixed order: registered methods, then peers, each sorted."""
    methods = sorted(method_names())
    return methods + sorted(p for p in PEERS if p not in methods)


def style_for(label: str) -> dict[str, str]:
    """The line style of a method or peer in every plot: distinct for every registered
    method and peer, the same for a name in every plot.

    Parameters
    ----------
    label : str
        A method or peer name, optionally with options as the tables write them
        (``'ss-solid (axis=1)'``).

    Returns
    -------
    dict
        matplotlib keywords ``color`` (a tab20 colour), ``marker`` and ``linestyle``.
        The i-th of the sorted methods, then peers, gets colour i mod 20 and marker
        i mod 9: pairwise distinct for up to 180 names.  A label with options keeps
        its method's colour with another marker and a dash-dotted line; a name glvox
        does not know gets a place from its CRC-32, stable across plots and runs.
    """
    names = _style_names()
    base, _, options = label.partition(" (")
    # an unknown name takes one of the places after the known ones (none left: any place)
    free = 180 - len(names)
    i = names.index(base) if base in names else (
        len(names) + zlib.crc32(base.encode()) % free if free > 0 else zlib.crc32(base.encode()) % 180)
    marker = i % len(MARKERS)
    if options:
        marker = (marker + 1 + zlib.crc32(options.encode()) % (len(MARKERS) - 1)) % len(MARKERS)
        line = LINESTYLES["options"]
    elif base in PEERS and base not in method_names():
        line = LINESTYLES["peer"]
    elif base in names:
        line = LINESTYLES["cpu" if get_method(base).info.pipeline == "cpu" else "gpu"]
    else:
        line = LINESTYLES["gpu"]
    return {"color": TAB20[i % 20], "marker": MARKERS[marker], "linestyle": line}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_times(rows, out: Path) -> list[Path]:
    """Time vs resolution per method on log axes, one figure per mesh (:func:`timing_series`:
    times served from a cache left out)."""
    plt = _plt()
    paths = []
    for mesh in dict.fromkeys(r["mesh"] for r in rows):
        series = timing_series(rows, mesh)
        if not series:
            continue
        fig, ax = plt.subplots(figsize=(8, 5.5))
        for label, pts in series.items():
            ax.plot([p[0] for p in pts], [p[1] for p in pts], label=label, **style_for(label))
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("grid resolution N (N^3 voxels)")
        ax.set_ylabel("time per run, ms (GPU; wall for CPU references)")
        ax.set_title(f"{mesh}: time vs resolution")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
        fig.tight_layout()
        p = out / f"time_{Path(mesh).stem.replace(':', '_')}.png"
        fig.savefig(p, dpi=110)
        plt.close(fig)
        paths.append(p)
    return paths


def plot_counts(rows, out: Path) -> Path | None:
    """Voxel counts per method and mesh at the largest resolution."""
    plt = _plt()
    ok = [r for r in rows if r["status"] == "ok" and r.get("voxels") is not None]
    if not ok:
        return None
    n = max(r["n"] for r in ok)
    ok = [r for r in ok if r["n"] == n]
    meshes = list(dict.fromkeys(r["mesh"] for r in ok))
    labels = list(dict.fromkeys(_label(r) for r in ok))
    fig, ax = plt.subplots(figsize=(max(8, 0.45 * len(labels) * len(meshes)), 5))
    width = 0.8 / max(1, len(meshes))
    for i, mesh in enumerate(meshes):
        vals = [next((r["voxels"] for r in ok if r["mesh"] == mesh and _label(r) == lb), 0) for lb in labels]
        ax.bar([j + i * width for j in range(len(labels))], vals, width, label=mesh)
    ax.set_xticks([j + 0.4 - width / 2 for j in range(len(labels))])
    ax.set_xticklabels(labels, rotation=60, ha="right", fontsize=8)
    ax.set_ylabel("voxels set")
    ax.set_title(f"voxel counts at {n}^3")
    ax.legend(fontsize=8)
    fig.tight_layout()
    p = out / "voxel_counts.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p


def plot_errors(rows, out: Path) -> Path | None:
    """Missing + extra voxels as a fraction of the reference, per method and mesh."""
    plt = _plt()
    ok = [r for r in rows if r.get("iou") is not None]
    if not ok:
        return None
    n = max(r["n"] for r in ok)
    ok = [r for r in ok if r["n"] == n]
    meshes = list(dict.fromkeys(r["mesh"] for r in ok))
    labels = list(dict.fromkeys(_label(r) for r in ok))
    fig, ax = plt.subplots(figsize=(max(8, 0.45 * len(labels) * len(meshes)), 5))
    width = 0.8 / max(1, len(meshes))
    floor = 1e-7
    for i, mesh in enumerate(meshes):
        vals = []
        for lb in labels:
            r = next((r for r in ok if r["mesh"] == mesh and _label(r) == lb), None)
            vals.append(max(floor, (r["missing"] + r["extra"]) / max(1, r["reference_voxels"])) if r else 0)
        ax.bar([j + i * width for j in range(len(labels))], vals, width, label=mesh)
    ax.set_yscale("log")
    ax.axhline(floor, color="k", lw=0.5)
    ax.set_xticks([j + 0.4 - width / 2 for j in range(len(labels))])
    ax.set_xticklabels(labels, rotation=60, ha="right", fontsize=8)
    ax.set_ylabel(f"(missing + extra) / reference voxels (floor {floor:g} = exact)")
    ax.set_title(f"error against the exact references at {n}^3")
    ax.legend(fontsize=8)
    fig.tight_layout()
    p = out / "errors.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p


def write_all(rows, machine, out: Path) -> list[Path]:
    """tables.md and the plots into ``out``; returns the paths written."""
    out = Path(out)
    (out / "tables.md").write_text(markdown(rows, machine))
    paths = [out / "tables.md"]
    plots = out / "plots"
    plots.mkdir(exist_ok=True)
    paths += plot_times(rows, plots)
    paths += [p for p in (plot_counts(rows, plots), plot_errors(rows, plots)) if p is not None]
    return paths


