"""Table 1 of Schwarz & Seidel 2010 on this machine: surface voxelization times
(ms, warm, median of repeats) of the ss-conservative variants and ss-6sep, voxel
counts, and the 1D/2D/3D case percentages, for shared meshes and grid sizes.

    python compare/table1_ss_surface.py [--sizes 128 256 512 1024] [--repeat 5]
                                        [--meshes stanford_bunny_bun_zipper.ply ...]

Meshes are paths or names in GLVOX_MESHES (default ../shared/meshes beside the
checkout; glvox.datasets).
Prints a markdown table laid out like the paper's (mesh x grid rows): for a
mesh that stands for one of the paper's models (glvox.study.paper_figures),
each glvox row (source: this GL renderer) is followed by the paper's row
(source: Schwarz & Seidel 2010 on the GTX 285); the paper's 6-separating
column is its specialized realization (ss-6sep's), its pipeline column Zhang
et al. 2007's conservative voxelization (not in glvox).
"""

from __future__ import annotations

import argparse
import sys

import glvox
from glvox.gl.context import get_context
from glvox.study.harness import timed
from glvox.datasets import resolve_mesh
from glvox.study.paper_figures import SS_GPU, SS_MODELS, SS_TABLE1, fmt, ss_model

DEFAULT_MESHES = ["stanford_bunny_bun_zipper.ply", "stanford_dragon_vrip_res2.ply"]


def paper_row(name: str, n: int) -> str | None:
    """The paper's Table 1 row for the model the shared mesh ``name`` stands for at ``n``^3, or None."""
    model = ss_model(name)
    p = SS_TABLE1.get(model, {}).get(n) if model else None
    if p is None:
        return None
    tris = SS_MODELS[name.rsplit("/", 1)[-1]][1]
    return (f"| paper: {model} ({tris:,} tris) | {n}^3 | Schwarz & Seidel 2010, {SS_GPU} | {fmt(p['pipeline'])} | "
            f"{fmt(p['simple'])} | {fmt(p['specialized'])} | {fmt(p['sorted'])} | {p['voxels_k']}k | "
            f"{'/'.join(f'{c}%' for c in p['cases'])} | {fmt(p['sep6_specialized'])} | {p['sep6_voxels_k']}k |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[128, 256, 512, 1024])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--meshes", nargs="+", default=DEFAULT_MESHES)
    args = ap.parse_args(argv)
    ctx = get_context()
    print(f"<!-- glvox: {ctx.renderer}; {ctx.version}; wall ms (GPU ms), median of {args.repeat} warm runs. "
          f"paper: Schwarz & Seidel 2010 Table 1, {SS_GPU}, ms -->")
    print("| model | grid | source | pipeline | simple | specialized | sorted | #voxels | 1D/2D/3D | 6-sep | "
          "#voxels 6-sep |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name in args.meshes:
        mesh = glvox.load_mesh(resolve_mesh(name))
        for n in args.sizes:
            spec = glvox.grid_for(mesh, n)
            cells, grid = [], None
            for variant in ("simple", "specialized", "sorted"):
                t = timed("ss-conservative", mesh, spec, args.repeat, variant=variant)
                grid = t.result
                cells.append(f"{t.wall_ms:.1f} ({t.gpu_ms:.1f})")
            pct = "/".join(f"{p:.0f}%" for p in grid.run.stats["case_percent_1d_2d_3d"])
            six = timed("ss-6sep", mesh, spec, args.repeat)
            print(f"| {name} ({mesh.n_triangles:,} tris) | {n}^3 | glvox, {ctx.renderer} | - | {' | '.join(cells)} | "
                  f"{grid.count / 1e3:.0f}k | {pct} | {six.wall_ms:.1f} ({six.gpu_ms:.1f}) | "
                  f"{six.result.count / 1e3:.0f}k |", flush=True)
            row = paper_row(name, n)
            if row:
                print(row, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
