"""Table 1 of Schwarz & Seidel 2010 on this machine: surface voxelization times
(ms, warm, median of repeats) of the ss-conservative variants and ss-6sep, voxel
counts, and the 1D/2D/3D case percentages, for shared meshes and grid sizes.

    python compare/table1_ss_surface.py [--sizes 128 256 512 1024] [--repeat 5]
                                        [--meshes stanford_bunny_bun_zipper.ply ...]

The meshes come from GLVOX_MESHES (default ../shared/meshes beside the checkout).
Prints a markdown table laid out like the paper's (mesh x grid rows).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import glvox
from glvox.gl.context import get_context
from glvox.methods import run_method

DEFAULT_MESHES = ["stanford_bunny_bun_zipper.ply", "stanford_dragon_vrip_res2.ply"]


def mesh_dir() -> Path:
    env = os.environ.get("GLVOX_MESHES")
    return Path(env) if env else Path(__file__).resolve().parents[2] / "shared" / "meshes"


def timed(name, mesh, spec, repeat, **opts):
    run_method(name, mesh, spec, **opts)  # warm-up: compile, upload, allocate
    walls, gpus, last = [], [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        last = run_method(name, mesh, spec, **opts)
        walls.append(time.perf_counter() - t0)
        gpus.append(last.run.timings.gpu_s or 0.0)
    return statistics.median(walls) * 1e3, statistics.median(gpus) * 1e3, last


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
        mesh = glvox.load_mesh(mesh_dir() / name)
        for n in args.sizes:
            spec = glvox.grid_for(mesh, n)
            cells, grid = [], None
            for variant in ("simple", "specialized", "sorted"):
                wall, gpu, grid = timed("ss-conservative", mesh, spec, args.repeat, variant=variant)
                cells.append(f"{wall:.1f} ({gpu:.1f})")
            pct = "/".join(f"{p:.0f}%" for p in grid.run.stats["case_percent_1d_2d_3d"])
            wall6, gpu6, six = timed("ss-6sep", mesh, spec, args.repeat)
            print(f"| {name} ({mesh.n_triangles:,} tris) | {n}^3 | {' | '.join(cells)} | "
                  f"{grid.count / 1e3:.0f}k | {pct} | {wall6:.1f} ({gpu6:.1f}) | {six.count / 1e3:.0f}k |",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
