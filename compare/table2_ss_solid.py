"""Table 2 of Schwarz & Seidel 2010 on this machine: solid voxelization times
(ms, warm, median of repeats) of the pipeline baseline (eisemann-solid, when
registered), the triangle-parallel ss-solid and the tile-based ss-solid-tiled
with its breakdown (T_pairs, T_sort, T_tiles), the number of (tile, triangle)
pairs and the average triangles per active tile.

    python compare/table2_ss_solid.py [--sizes 128 256 512 1024] [--repeat 5]
                                      [--meshes stanford_bunny_bun_zipper.ply ...]

The bunny and the dragons are open meshes (the paper used them anyway): they
run with allow_open, so the grids are parities of crossings, which costs the
same as a closed mesh.  Meshes are paths or names in GLVOX_MESHES (default
../shared/meshes beside the checkout).  Prints a markdown table: for a mesh
that stands for one of the paper's models (glvox.study.paper_figures), each
glvox row (source: this GL renderer) is followed by the paper's row (source:
Schwarz & Seidel 2010 on the GTX 285; its pipeline column is Eisemann &
Decoret 2008).
"""

from __future__ import annotations

import argparse
import sys
import warnings

import glvox
from glvox.errors import NotWatertightWarning
from glvox.gl.context import get_context
from glvox.methods import method_names
from glvox.study.harness import timed
from glvox.datasets import resolve_mesh
from glvox.study.paper_figures import SS_GPU, SS_MODELS, SS_TABLE2, fmt, ss_model

DEFAULT_MESHES = ["stanford_bunny_bun_zipper.ply", "stanford_dragon_vrip_res2.ply"]


def stage_ms(grid, names):
    return sum(s.gpu_s or 0.0 for s in grid.run.timings.stages if s.name in names) * 1e3


def paper_row(name: str, n: int) -> str | None:
    """The paper's Table 2 row for the model the shared mesh ``name`` stands for at ``n``^3, or None."""
    model = ss_model(name)
    p = SS_TABLE2.get(model, {}).get(n) if model else None
    if p is None:
        return None
    tris = SS_MODELS[name.rsplit("/", 1)[-1]][1]
    times = " | ".join(fmt(p[k]) for k in ("pipeline", "tri_parallel", "t_total", "t_pairs", "t_sort", "t_tiles"))
    return (f"| paper: {model} ({tris:,} tris) | {n}^3 | Schwarz & Seidel 2010, {SS_GPU} | {times} | "
            f"{p['pairs_k']}k | {fmt(p['tris'], 1)} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[128, 256, 512, 1024])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--meshes", nargs="+", default=DEFAULT_MESHES)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", NotWatertightWarning)
    ctx = get_context()
    pipeline = "eisemann-solid" if "eisemann-solid" in method_names() else None
    print(f"<!-- glvox: {ctx.renderer}; {ctx.version}; wall ms (GPU ms), median of {args.repeat} warm runs; "
          f"T_pairs = classify + pairs, T_tiles = compact + tiles (GPU ms). paper: Schwarz & Seidel 2010 "
          f"Table 2, {SS_GPU}, ms -->")
    print("| model | grid | source | pipeline | tri-parallel | tiled T_total | T_pairs | T_sort | T_tiles | #pairs "
          "| #tris |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name in args.meshes:
        mesh = glvox.load_mesh(resolve_mesh(name))
        for n in args.sizes:
            spec = glvox.grid_for(mesh, n)
            cells = []
            for method in (pipeline, "ss-solid", "ss-solid-tiled"):
                if method is None:
                    cells.append("-")
                    continue
                t = timed(method, mesh, spec, args.repeat, allow_open=True)
                cells.append(f"{t.wall_ms:.1f} ({t.gpu_ms:.1f})")
            g = t.result
            st = g.run.stats
            cells += [f"{stage_ms(g, ('classify', 'pairs')):.1f}",
                      f"{stage_ms(g, ('sort',)):.1f}", f"{stage_ms(g, ('compact', 'tiles')):.1f}",
                      f"{st['pairs'] / 1e3:.0f}k", f"{st['triangles_per_active_tile']:.1f}"]
            print(f"| {name} ({mesh.n_triangles:,} tris) | {n}^3 | glvox, {ctx.renderer} | {' | '.join(cells)} |",
                  flush=True)
            row = paper_row(name, n)
            if row:
                print(row, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
