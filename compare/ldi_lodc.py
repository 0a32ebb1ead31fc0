"""Leung & Wang 2013 on this machine: layers and time against LOD-C (the paper's Fig. 6-7),
and the conservative LDI against depth peeling on many-layer meshes (Table II's comparison).

    python compare/ldi_lodc.py [--size 256] [--lod-c 8 16 32 64 128 256 512 1024 2048] [--axis 2]
                               [--repeat 3] [--meshes depth_reduced_diamond_lattice.stl gen:nest40 ...]
                               [--many gen:brush24:0 ...] [--skip lod_c|peel] [--json out.json]

Part 1 (Fig. 6-7): for each mesh and LOD-C, leung-wang-ldi's n_max (layers), samples, the
volume it encloses against the exact LDI's (reference-ldi: the crossings in float64; the
excess is what coarse cells add, Fig. 7's blue regions), and its time.  Part 2 (Table II):
leung-wang-ldi at LOD-C 1024 against peel-ldi (exact depth peeling, one raster pass per
layer, as in Table II's stencil and FreePipe columns: every layer is a pass here, no sort),
with the raster passes each makes.

Times are warm, median of --repeat runs: wall ms and the GPU ms of the timestamp queries
(on a software renderer the two agree).  Generated meshes: ``gen:nestK`` (K concentric
spherical shells: 4K crossings on the central rays), ``gen:brushK`` (K x K thin square
bristles along z: 2K crossings on rays along x or y); shared meshes come from GLVOX_MESHES
(default ../shared/meshes beside the checkout).  Open meshes run with allow_open.  Prints
markdown tables.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np

import glvox
from glvox.errors import NotWatertightWarning
from glvox.gl.context import get_context
from glvox.methods import run_method
from glvox.study.harness import timed
from glvox.datasets import resolve_mesh

DEFAULT_MESHES = ["depth_reduced_diamond_lattice.stl", "stanford_armadillo_libigl_86k.obj", "gen:nest40"]
DEFAULT_LOD_C = [8, 16, 32, 64, 128, 256, 512, 1024, 2048]
#: Table II's many-layer meshes here (axis: the direction with the most layers).
DEFAULT_MANY = ["depth_reduced_diamond_lattice.stl:2", "depth_cycloidal_drive.ply:2", "messy_tower_holes.obj:1",
                "gen:nest10:2", "gen:nest40:2", "gen:brush24:0", "gen:brush64:0"]


def nest(shells: int, subdivisions: int = 4):
    """``shells`` concentric spherical shells of equal thickness and gaps filling the unit ball."""
    import trimesh

    base = trimesh.creation.icosphere(subdivisions)
    step = 0.9 / (2 * shells)
    vs, fs = [], []
    for k in range(2 * shells):
        faces = base.faces if k % 2 == 0 else base.faces[:, ::-1]
        fs.append(faces + sum(len(v) for v in vs))
        vs.append(base.vertices * (1.0 - k * step))
    return glvox.load_mesh((np.concatenate(vs), np.concatenate(fs)), name=f"nest{shells}")


def brush(k: int):
    """k x k square bristles along z (side 0.4 of their pitch), on no handle: 2k crossings per row."""
    import trimesh

    vs, fs = [], []
    for i in range(k):
        for j in range(k):
            b = trimesh.creation.box(bounds=[[i, j, 0.0], [i + 0.4, j + 0.4, 4.0 * k]])
            fs.append(b.faces + sum(len(v) for v in vs))
            vs.append(b.vertices)
    return glvox.load_mesh((np.concatenate(vs), np.concatenate(fs)), name=f"brush{k}")


def load(name: str):
    if name.startswith("gen:nest"):
        return nest(int(name[len("gen:nest"):]))
    if name.startswith("gen:brush"):
        return brush(int(name[len("gen:brush"):]))
    return glvox.load_mesh(resolve_mesh(name))


def part1(args, ctx, rows):
    print(f"\n### Layers and time against LOD-C ({args.size}^2 rays along {'xyz'[args.axis]}; {ctx.renderer})\n")
    print("| model | triangles | LOD-C | n_max (exact) | samples | volume excess | wall ms | GPU ms |"
          " Phase 1 / n_max / Phase 2 GPU ms |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in args.meshes:
        mesh = load(name)
        spec = glvox.grid_for(mesh, args.size)
        exact = run_method("reference-ldi", mesh, spec, allow_open=True, axis=args.axis)
        for lod_c in args.lod_c:
            t = timed("leung-wang-ldi", mesh, spec, args.repeat, allow_open=True, lod_c=lod_c, axis=args.axis)
            r, wall, gpu = t.result, t.wall_ms, t.gpu_ms
            st = {s.name: 0.0 for s in r.run.timings.stages}
            for s in r.run.timings.stages:
                st[s.name] += (s.gpu_s or 0.0) * 1e3
            p1 = sum(v for k, v in st.items() if k.startswith(("t1", "t2", "transform", "setup")))
            p2 = st.get("depths", 0.0) + st.get("store", 0.0)
            excess = (r.volume - exact.volume) / exact.volume if exact.volume else float("nan")
            print(f"| {mesh.name} | {mesh.n_triangles} | {lod_c} | {r.n_max} ({exact.n_max}) | {r.samples} | "
                  f"{excess:+.2%} | {wall:.0f} | {gpu:.0f} | {p1:.0f} / {st.get('count', 0.0):.0f} / {p2:.0f} |")
            rows.append({"part": "lod_c", "mesh": mesh.name, "triangles": mesh.n_triangles, "size": args.size,
                         "lod_c": lod_c, "n_max": r.n_max, "exact_n_max": exact.n_max, "samples": r.samples,
                         "volume": r.volume, "exact_volume": exact.volume, "wall_ms": wall, "gpu_ms": gpu,
                         "stages_gpu_ms": st})
            sys.stdout.flush()


def part2(args, ctx, rows):
    print(f"\n### Conservative LDI (LOD-C 1024) against depth peeling ({args.size}^2 rays; {ctx.renderer})\n")
    print("| model | triangles | axis | n_max LW (exact) | LW wall ms | LW raster passes | peel wall ms | "
          "peel raster passes | peel / LW |")
    print("|---|---|---|---|---|---|---|---|---|")
    for item in args.many:
        name, _, axis = item.rpartition(":")
        if not axis.isdigit():
            name, axis = item, "2"
        axis = int(axis)
        try:
            mesh = load(name)
        except glvox.GlvoxError as exc:
            print(f"| {name} | - | {axis} | skipped: {exc} |||||")
            continue
        spec = glvox.grid_for(mesh, args.size)
        lw = timed("leung-wang-ldi", mesh, spec, args.repeat, allow_open=True, lod_c=1024, axis=axis)
        peel = timed("peel-ldi", mesh, spec, args.repeat, allow_open=True, axis=axis)
        lw, lw_wall, peel, peel_wall = lw.result, lw.wall_ms, peel.result, peel.wall_ms
        lw_passes = lw.run.stats["draws"]
        print(f"| {mesh.name} | {mesh.n_triangles} | {'xyz'[axis]} | {lw.n_max} ({peel.n_max}) | {lw_wall:.0f} | "
              f"{lw_passes} | {peel_wall:.0f} | {peel.run.stats['passes']} | {peel_wall / lw_wall:.2f} |")
        rows.append({"part": "peel", "mesh": mesh.name, "triangles": mesh.n_triangles, "size": args.size,
                     "axis": axis, "n_max": lw.n_max, "exact_n_max": peel.n_max, "lw_wall_ms": lw_wall,
                     "lw_passes": lw_passes, "peel_wall_ms": peel_wall, "peel_passes": peel.run.stats["passes"]})
        sys.stdout.flush()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=256, help="rays per side (grid resolution)")
    ap.add_argument("--lod-c", type=int, nargs="+", default=DEFAULT_LOD_C)
    ap.add_argument("--axis", type=int, choices=(0, 1, 2), default=2, help="part 1 ray axis")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--meshes", nargs="+", default=DEFAULT_MESHES, help="part 1 meshes")
    ap.add_argument("--many", nargs="+", default=DEFAULT_MANY, help="part 2 meshes, NAME:AXIS")
    ap.add_argument("--skip", choices=["lod_c", "peel"], action="append", default=[])
    ap.add_argument("--json", help="also write the rows as JSON")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", NotWatertightWarning)
    ctx = get_context()
    rows: list = []
    print(f"<!-- {ctx.renderer}; {ctx.version}; warm runs, median of {args.repeat} -->")
    if "lod_c" not in args.skip:
        part1(args, ctx, rows)
    if "peel" not in args.skip:
        part2(args, ctx, rows)
    if args.json:
        Path(args.json).write_text(json.dumps({"renderer": ctx.renderer, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
