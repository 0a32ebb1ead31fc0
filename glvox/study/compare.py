"""``glvox compare``: every chosen method on every mesh and grid size, tables, plots and pictures.

    glvox compare --preset quick -o results/quick
    glvox compare --preset paper -o results/paper
    glvox compare -m ss-conservative scanline-ilv --meshes stanford_bunny_bun_zipper.ply -r 64 128 256

A thin layer over the study's runner (:mod:`glvox.study.harness`): the plan
holds every registered method (or ``-m``), solid methods are skipped on open
meshes, and each row gets the separability of surfaces on closed meshes
(:func:`separability`).  A run writes into its output folder:
``machine.json`` (renderer, versions), ``results.jsonl`` (one row per cell,
appended as each mesh and size finishes: rerunning the same command resumes,
skipping the cells whose row key is there), ``results.csv`` and
``results.json`` (tidy, all rows), ``tables.md``, ``plots/*.png`` and
``pictures/*.png``.
"""

from __future__ import annotations

import csv
import json
import os
import sys
import time
import warnings
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from glvox.errors import GlvoxError, NotWatertightWarning, SuspiciousResultWarning
from glvox.gl.context import get_context
from glvox.grid import grid_for, unpack_bits
from glvox.inspect import UNCERTAIN_BAND, uncertain_share
from glvox.mesh import load_mesh
from glvox.methods import get_method, method_names, run_method
from glvox.metrics import separation_leaks
from glvox.progress import Progress
from glvox.results.voxels import VoxelGrid

from . import harness, report
from ..datasets import resolve_mesh
from .options import CHECK_MAX, COMPARE_PRESETS
from .plan import Contender, Plan, row_key
from .render import disagreement_slice, render_voxels, save_png, save_slice_png

#: The result file of a run (one JSON object per line, appended per mesh and size).
RESULTS = "results.jsonl"

#: Picture resolution cap: renders and slices are made at min(largest size, this).
PICTURE_MAX = 128


def compare_plan(methods: Sequence[str], meshes: Sequence[str], sizes: Sequence[int], repeat: int = 5,
                 check_max: int | None = CHECK_MAX, cpu_max: int | None = None, *,
                 reference: str | None = None, open_solids: bool = False) -> Plan:
    """The plan of ``glvox compare``: ``methods`` (registered names) on resolved ``meshes``.

    Every timed run counts (no time budget); solid, sparse and LDI methods
    are skipped on open meshes, where inside is undefined, unless
    ``open_solids`` (they then run with ``allow_open``) or they are defined
    for any mesh.  ``reference``: every method is checked against it (the
    open-mesh study) instead of its own.
    """
    return Plan(meshes=list(meshes), sizes=sorted(set(sizes)), contenders=[Contender.of_method(m) for m in methods],
                repeat=repeat, check_max=check_max, cpu_max=cpu_max, open_solids=open_solids, reference=reference)


def preset_methods(preset: dict[str, Any]) -> list[str]:
    """A preset's methods: its list, else every registered method of its kinds (but its
    reference), else every registered method."""
    if preset.get("methods"):
        return list(preset["methods"])
    if preset.get("kinds"):
        return [m for k in preset["kinds"] for m in method_names(kind=k) if m != preset.get("reference")]
    return method_names()


def plan_from(args) -> Plan:
    preset = dict(COMPARE_PRESETS.get(args.preset or "", {}))
    methods = args.methods or preset_methods(preset)
    meshes = args.meshes or preset.get("meshes")
    sizes = args.sizes or preset.get("sizes")
    if not meshes or not sizes:
        raise GlvoxError(f"give --preset {'|'.join(sorted(COMPARE_PRESETS))}, or --meshes and -r/--sizes")
    return compare_plan(methods, [resolve_mesh(m) for m in meshes], sizes,
                        repeat=args.repeat or preset.get("repeat", 5),
                        check_max=preset.get("check_max", CHECK_MAX) if args.check_max is None else args.check_max,
                        cpu_max=preset.get("cpu_max"), reference=preset.get("reference"),
                        open_solids=preset.get("open_solids", False))


def separability(row: dict[str, Any], grid: VoxelGrid | None, refs: harness.References) -> None:
    """``leaks_26`` / ``leaks_6`` of a checked surface on a closed mesh: inside voxels
    (of reference-solid) reached from outside by 26- / 6-paths of empty voxels."""
    if grid is None or row["kind"] != "surface" or not refs.mesh.watertight or "iou" not in row:
        return
    surface = grid.dense()
    inside = unpack_bits(refs.words("reference-solid"), refs.spec.dims) & ~surface
    row["leaks_26"] = int(len(separation_leaks(surface, inside, 26)))
    row["leaks_6"] = int(len(separation_leaks(surface, inside, 6)))


def uncertainty(row: dict[str, Any], grid: VoxelGrid | None, refs: harness.References) -> None:
    """The open-mesh study (a plan checked against reference-gwn): ``uncertain_share``,
    the share of the solid whose exact winding number lies within 0.1 of 1/2 on this
    mesh and grid (:func:`glvox.inspect.uncertain_share`), and ``mismatch_uncertain``,
    the share of this row's mismatches with reference-gwn that lie in that band."""
    if grid is None or not str(row.get("reference", "")).startswith("reference-gwn"):
        return
    w = refs.field("reference-gwn", "winding")
    row["uncertain_share"] = uncertain_share(w)[1]
    diff = unpack_bits(grid.words() ^ refs.words("reference-gwn"), refs.spec.dims)
    n = int(diff.sum())
    row["mismatch_uncertain"] = float((diff & (np.abs(w - 0.5) < UNCERTAIN_BAND)).sum() / n) if n else None


# ---------------------------------------------------------------------------
# the result files
# ---------------------------------------------------------------------------


def load_rows(out: str | os.PathLike) -> list[dict[str, Any]]:
    """The rows in ``out/results.jsonl``; a line cut by an interruption is dropped (its cell runs again)."""
    path = Path(out) / RESULTS
    if not path.is_file():
        return []
    rows = []
    for line in path.read_text().splitlines():
        if line.strip():
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:
                continue
    return rows


def _end_cut_line(path: Path) -> None:
    """End a line an interrupted write left open, so that new rows start cleanly."""
    if path.is_file() and path.stat().st_size:
        with open(path, "rb") as f:
            f.seek(-1, os.SEEK_END)
            cut = f.read(1) != b"\n"
        if cut:
            with open(path, "a") as f:
                f.write("\n")


def write_csv(rows: Iterable[dict[str, Any]], path: Path) -> None:
    """A tidy CSV: one row per cell, nested fields as JSON strings."""
    rows = list(rows)
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: json.dumps(v) if isinstance(v, (dict, list)) else v for k, v in r.items()})


def run(plan: Plan, out: str | os.PathLike, *, force: bool = False, quiet: bool = False,
        log=lambda s: None) -> list[dict[str, Any]]:
    """Run every cell of ``plan`` missing from ``out`` and return all its rows, in plan order.

    Writes ``out/machine.json`` and appends the rows of each mesh and size
    to ``out/results.jsonl`` as soon as they are measured.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "machine.json").write_text(json.dumps(harness.machine(), indent=2))
    path = out / RESULTS
    if force and path.exists():
        path.unlink()
    rows = {row_key(r): r for r in load_rows(out)}
    cells = plan.cells()
    todo = [c for c in cells if c.key not in rows]
    if len(todo) < len(cells):
        log(f"resuming: {len(cells) - len(todo)} of {len(cells)} cells already in {out}")
    progress = Progress(len(todo), unit="cell", enabled=not quiet)
    _end_cut_line(path)
    with open(path, "a") as f:
        def write(new: list[dict[str, Any]]) -> None:
            for r in new:
                rows[row_key(r)] = r
                f.write(json.dumps(r) + "\n")
            f.flush()
            progress.update(len(new))

        with progress:
            harness.run_plan(plan, done=rows, on_rows=write, progress=progress.status,
                             analyses=[separability, uncertainty])
    return [rows[c.key] for c in cells if c.key in rows]


# ---------------------------------------------------------------------------
# pictures
# ---------------------------------------------------------------------------


def _renders(ctx, plan: Plan, mesh, spec, n: int, stem: str, pic: Path) -> list[Path]:
    """One surface and one solid result (mesh edges drawn over the surface)."""
    methods = [c.method for c in plan.contenders]
    surface = next((m for m in ("ss-conservative", "scanline-rlv") if m in methods), None)
    solid = next((m for m in ("ss-solid", "ss-solid-tiled", "eisemann-solid") if m in methods), None)
    paths = []
    for name, overlay in ((surface, True), (solid, False)):
        if name is None or (get_method(name).info.kind == "solid" and not mesh.watertight):
            continue
        g = run_method(name, mesh, spec)
        img = render_voxels(ctx, g, mesh=mesh if overlay and mesh.n_triangles < 60000 else None)
        paths.append(save_png(img, pic / f"{stem}_{name}_{n}.png"))
    return paths


def _slices(plan: Plan, mesh, spec, n: int, label: str, stem: str, pic: Path, log) -> list[Path]:
    """A slice where each approximate method disagrees with its reference; with the plan's
    own reference (the open-mesh study), where any method disagrees with it."""
    paths = []
    for c in plan.contenders:
        info = get_method(c.method).info
        reference = plan.reference or info.reference
        if (info.exact and not plan.reference) or not reference or info.kind not in ("surface", "solid"):
            continue
        if info.kind == "solid" and not mesh.watertight and not (plan.open_solids or info.any_mesh):
            continue
        try:
            g = run_method(c.method, mesh, spec, allow_open=plan.open_solids, **dict(c.options))
            ref = run_method(reference, mesh, spec, allow_open=True)
        except GlvoxError as exc:
            log(f"no slice for {c.method} on {stem}: {exc}")
            continue
        if g.equal(ref):
            continue  # nothing to show: the method agrees with its reference here
        img, k = disagreement_slice(g, ref)
        cmp = g.compare(ref)
        title = (f"{label} at {n}^3, slice z = {k}\n{c.method} against {reference}: "
                 f"{cmp.n_missing} missing, {cmp.n_extra} extra in the whole grid")
        paths.append(save_slice_png(img, pic / f"{stem}_slice_{c.method}_vs_{reference}_{n}_z{k}.png",
                                    c.method, reference, title))
    return paths


def pictures(plan: Plan, out: Path, log) -> list[Path]:
    """Renders and disagreement slices of every mesh at min(largest size, :data:`PICTURE_MAX`)."""
    ctx = get_context()
    pic = out / "pictures"
    pic.mkdir(exist_ok=True)
    n = min(max(plan.sizes), PICTURE_MAX)
    paths = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotWatertightWarning)
        warnings.simplefilter("ignore", SuspiciousResultWarning)  # kept in the row: stats["suspicious"]
        for mesh_path in plan.meshes:
            mesh = load_mesh(mesh_path)
            spec = grid_for(mesh, n)
            stem = Path(mesh_path).stem.replace(":", "_")
            paths += _renders(ctx, plan, mesh, spec, n, stem, pic)
            paths += _slices(plan, mesh, spec, n, Path(mesh_path).name, stem, pic, log)
    return paths


def main(args) -> int:
    """``glvox compare`` with parsed ``args`` (:func:`glvox.study.options.add_compare_arguments`)."""
    def log(msg: str) -> None:
        if not args.quiet:
            print(msg, file=sys.stderr)

    plan = plan_from(args)
    out = Path(args.out)
    t0 = time.perf_counter()
    log(f"{len(plan.cells())} cells: {len(plan.contenders)} methods x {len(plan.meshes)} meshes x "
        f"sizes {plan.sizes}, {plan.repeat} timed runs each -> {out}")
    rows = run(plan, out, force=args.force, quiet=args.quiet, log=log)
    machine = json.loads((out / "machine.json").read_text())
    write_csv(rows, out / "results.csv")
    (out / "results.json").write_text(json.dumps({"machine": machine, "rows": rows}, indent=1))
    written = report.write_all(rows, machine, out)
    if not args.no_pictures:
        written += pictures(plan, out, log)
    bad = [r for r in rows if r["status"] == "error"]
    log(f"done in {time.perf_counter() - t0:.0f} s: {len(rows)} cells, {len(bad)} errors; "
        f"wrote {out / 'tables.md'}, {out / 'results.csv'}, {len(written) - 1} plots and pictures")
    return 0
