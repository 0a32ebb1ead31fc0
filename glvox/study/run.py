"""``glvox compare``: presets, the command line, and the whole run.

    glvox compare --preset quick -o results/quick
    glvox compare --preset paper -o results/paper
    glvox compare -m ss-conservative scanline-ilv --meshes stanford_bunny_bun_zipper.ply -r 64 128 256

A run writes into its output folder: ``machine.json`` (renderer, versions),
``results.jsonl`` (one row per cell, appended as cells finish: rerunning the
same command resumes), ``results.csv`` and ``results.json`` (tidy, all
rows), ``tables.md``, ``plots/*.png`` and ``pictures/*.png``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path
from typing import Any, Sequence

import glvox
from glvox.errors import GlvoxError, NotWatertightWarning
from glvox.methods import get_method, method_names, run_method

from . import harness, report

#: Presets: methods (None = every registered one), meshes, sizes, repeats.
PRESETS: dict[str, dict[str, Any]] = {
    "quick": {"meshes": ["stanford_bunny_bun_zipper.ply", "cad_rocker_arm.obj"],
              "sizes": [32, 64, 128], "repeat": 3, "check_max": 128},
    "paper": {"meshes": ["stanford_bunny_bun_zipper.ply", "stanford_dragon_vrip_res2.ply",
                         "stanford_armadillo_libigl_86k.obj", "stanford_happy_buddha_113k.obj",
                         "cad_rocker_arm.obj", "cad_fandisk.off", "depth_reduced_diamond_lattice.stl",
                         "depth_gyroid_tpms_sheet.stl"],
              "sizes": [128, 256, 512, 1024], "repeat": 3, "check_max": 256,
              # the float64 CPU references are checks, not contenders, past this size
              "cpu_max": 256},
}

#: Picture resolution cap: renders and slices are made at min(largest size, this).
PICTURE_MAX = 128


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--preset", choices=sorted(PRESETS), default=None,
                   help="quick: every method, two shared meshes, up to 128^3; paper: the papers' sizes "
                        "up to 1024^3 on eight shared meshes")
    p.add_argument("-m", "--methods", nargs="+", default=None, help="registered method names (default all)")
    p.add_argument("--meshes", nargs="+", default=None,
                   help="mesh files, names in GLVOX_MESHES, or gen:torus|sphere|box|bunny-like")
    p.add_argument("-r", "--sizes", nargs="+", type=int, default=None, help="grid resolutions N (N^3)")
    p.add_argument("--repeat", type=int, default=None, help="timed warm runs per cell (median reported)")
    p.add_argument("--check-max", type=int, default=None,
                   help=f"largest N checked against the CPU references (default {harness.CHECK_MAX})")
    p.add_argument("-o", "--out", default="results", help="output folder (resumed if it has results)")
    p.add_argument("--force", action="store_true", help="recompute every cell, ignoring earlier results")
    p.add_argument("--no-pictures", action="store_true", help="skip the renders and slice images")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def plan_from(args) -> harness.Plan:
    preset = dict(PRESETS.get(args.preset or "", {}))
    methods = args.methods or preset.get("methods") or method_names()
    meshes = args.meshes or preset.get("meshes")
    sizes = args.sizes or preset.get("sizes")
    if not meshes or not sizes:
        raise GlvoxError("give --preset quick|paper, or --meshes and -r/--sizes")
    for m in methods:
        get_method(m)  # unknown names: one clear error listing the known ones
    plan = harness.Plan(methods=list(methods), meshes=[harness.resolve_mesh(m) for m in meshes],
                        sizes=sorted(set(sizes)), repeat=args.repeat or preset.get("repeat", 5),
                        check_max=args.check_max or preset.get("check_max", harness.CHECK_MAX),
                        cpu_max=preset.get("cpu_max"))
    return plan


def pictures(plan: harness.Plan, rows, out: Path, log) -> list[Path]:
    """Renders of one surface and one solid result per mesh (mesh edges drawn over
    the surface), and slices where each approximate method disagrees with its reference."""
    from glvox.gl.context import get_context

    from .render import disagreement_slice, render_voxels, save_png, save_slice_png

    ctx = get_context()
    pic = out / "pictures"
    pic.mkdir(exist_ok=True)
    n = min(max(plan.sizes), PICTURE_MAX)
    paths = []
    surface = next((m for m in ("ss-conservative", "scanline-rlv") if m in plan.methods), None)
    solid = next((m for m in ("ss-solid", "ss-solid-tiled", "eisemann-solid") if m in plan.methods), None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotWatertightWarning)
        for mesh_path in plan.meshes:
            mesh = glvox.load_mesh(mesh_path)
            spec = glvox.grid_for(mesh, n)
            stem = Path(mesh_path).stem.replace(":", "_")
            for name, overlay in ((surface, True), (solid, False)):
                if name is None or (get_method(name).info.kind == "solid" and not mesh.watertight):
                    continue
                g = run_method(name, mesh, spec)
                img = render_voxels(ctx, g, mesh=mesh if overlay and mesh.n_triangles < 60000 else None)
                paths.append(save_png(img, pic / f"{stem}_{name}_{n}.png"))
            for name in plan.methods:
                info = get_method(name).info
                if info.exact or not info.reference or info.kind not in ("surface", "solid"):
                    continue
                if info.kind == "solid" and not mesh.watertight:
                    continue
                try:
                    g = run_method(name, mesh, spec)
                    ref = run_method(info.reference, mesh, spec, allow_open=True)
                except GlvoxError as exc:
                    log(f"no slice for {name} on {stem}: {exc}")
                    continue
                if g.equal(ref):
                    continue  # nothing to show: the method agrees with its reference here
                img, k = disagreement_slice(g, ref)
                c = g.compare(ref)
                title = (f"{Path(mesh_path).name} at {n}^3, slice z = {k}\n{name} against {info.reference}: "
                         f"{c.n_missing} missing, {c.n_extra} extra in the whole grid")
                paths.append(save_slice_png(img, pic / f"{stem}_slice_{name}_vs_{info.reference}_{n}_z{k}.png",
                                            name, info.reference, title))
    return paths


def main(args) -> int:
    def log(msg: str) -> None:
        if not args.quiet:
            print(msg, file=sys.stderr)

    plan = plan_from(args)
    out = Path(args.out)
    t0 = time.perf_counter()
    log(f"{len(plan.cells())} cells: {len(plan.methods)} methods x {len(plan.meshes)} meshes x "
        f"sizes {plan.sizes}, {plan.repeat} timed runs each -> {out}")
    rows = harness.run_plan(plan, out, force=args.force, quiet=args.quiet, log=log)
    machine = json.loads((out / "machine.json").read_text())
    harness.write_csv(rows, out / "results.csv")
    (out / "results.json").write_text(json.dumps({"machine": machine, "rows": rows}, indent=1))
    written = report.write_all(rows, machine, out)
    if not args.no_pictures:
        written += pictures(plan, rows, out, log)
    bad = [r for r in rows if r["status"] == "error"]
    log(f"done in {time.perf_counter() - t0:.0f} s: {len(rows)} cells, {len(bad)} errors; "
        f"wrote {out / 'tables.md'}, {out / 'results.csv'}, {len(written) - 1} plots and pictures")
    return 0


def cli(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="glvox compare", description=__doc__.splitlines()[0])
    add_arguments(p)
    return main(p.parse_args(argv))
