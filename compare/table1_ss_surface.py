"""Table 1 of Schwarz & Seidel 2010 on this machine: surface voxelization times
(ms, warm, median of repeats) of the ss-conservative variants and ss-6sep, voxel
counts, and the 1D/2D/3D case percentages, for shared meshes and grid sizes.

    python compare/table1_ss_surface.py [--sizes 128 256 512 1024] [--repeat 5]
                                        [--meshes stanford_bunny_bun_zipper.ply ...]

Meshes are paths or names in GLVOX_MESHES (default ../shared/meshes beside the
checkout; glvox.datasets).
Prints a markdown table laid out like the paper's (mesh x grid rows).
"""

from __future__ import annotations

import argparse
import sys

import glvox
from glvox.gl.context import get_context
from glvox.study.harness import timed
from glvox.datasets import resolve_mesh

DEFAULT_MESHES = ["stanford_bunny_bun_zipper.ply", "stanford_dragon_vrip_res2.ply"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[128, 256, 512, 1024])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--meshes", nargs="+", default=DEFAULT_MESHES)
    args = ap.parse_args(argv)
    ctx = get_context()
    print(f"<!-- {ctx.renderer}; {ctx.version}; wall ms (GPU ms), median of {args.repeat} warm runs -->")
    print("| model | grid | simple | specialized | sorted | #voxels | 1D/2D/3D | 6-sep | #voxels 6-sep |")
    print("|---|---|---|---|---|---|---|---|---|")
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
            print(f"| {name} ({mesh.n_triangles:,} tris) | {n}^3 | {' | '.join(cells)} | "
                  f"{grid.count / 1e3:.0f}k | {pct} | {six.wall_ms:.1f} ({six.gpu_ms:.1f}) | "
                  f"{six.result.count / 1e3:.0f}k |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
