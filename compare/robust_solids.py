"""The robust solids of issue 19 on this machine: how many flood-fill rounds
carve-solid needs per shared mesh, and carve-solid and vote-solid against
ss-solid, end to end (the whole run_method call, readback and numpy result
included) and on the GPU.

    python compare/robust_solids.py rounds [--sizes 64 128 256] [--close 0 4]
    python compare/robust_solids.py time [--sizes 128 256] [--repeat 7]
                                         [--meshes stanford_bunny_bun_zipper.ply ...]

``rounds``: every shared mesh (paths or names in GLVOX_MESHES, default
../shared/meshes beside the checkout), the rounds of x, y and z sweeps until
the exterior stops growing, the carved voxels and the flood's GPU ms.
``time``: wall ms (GPU ms in brackets), median of warm runs in one process,
the methods taking turns, with carve-solid's and vote-solid's ratios to
ss-solid and their stages.  Open meshes run ss-solid with allow_open (a
parity, which costs the same).  Prints markdown tables.
"""

from __future__ import annotations

import argparse
import statistics
import time
import warnings

import glvox
from glvox.errors import NotWatertightWarning
from glvox.gl.context import get_context
from glvox.methods import run_method
from glvox.datasets import SHARED_MESHES, mesh_dir, resolve_mesh

METHODS = ("ss-solid", "carve-solid", "vote-solid")
DEFAULT_MESHES = ["stanford_bunny_bun_zipper.ply", "stanford_armadillo_libigl_86k.obj"]


def stage_ms(grid, name):
    return sum((s.gpu_s or 0.0) for s in grid.run.timings.stages if s.name == name) * 1e3


def rounds(args) -> None:
    print("| mesh | tris | " + " | ".join(f"{n}^3 close={k}" for n in args.sizes for k in args.close) + " |")
    print("|---|---|" + "---|" * (len(args.sizes) * len(args.close)))
    for name in SHARED_MESHES:
        if not (mesh_dir() / name).is_file():
            continue
        mesh = glvox.load_mesh(resolve_mesh(name))
        cells = []
        for n in args.sizes:
            spec = glvox.grid_for(mesh, n)
            for k in args.close:
                run_method("carve-solid", mesh, spec, close=k)  # warm: compilation, buffers
                g = run_method("carve-solid", mesh, spec, close=k)
                cells.append(f"{g.run.stats['flood_rounds']} rounds, {g.count:,} vox, flood "
                             f"{stage_ms(g, 'flood'):.1f} ms")
        print(f"| {name} | {mesh.n_triangles:,} | " + " | ".join(cells) + " |")


def timing(args) -> None:
    print("| mesh | grid | " + " | ".join(f"`{m}` wall (GPU) ms" for m in METHODS)
          + " | carve / ss-solid | vote / ss-solid | carve stages (GPU ms) | carve rounds |")
    print("|---|---|" + "---|" * (len(METHODS) + 4))
    for name in args.meshes:
        mesh = glvox.load_mesh(resolve_mesh(name))
        for n in args.sizes:
            spec = glvox.grid_for(mesh, n)
            walls = {m: [] for m in METHODS}
            gpus = {m: [] for m in METHODS}
            last = {}
            for m in METHODS:
                run_method(m, mesh, spec, allow_open=True)  # cold run apart
            for r in range(args.repeat):
                for m in METHODS[r % len(METHODS):] + METHODS[:r % len(METHODS)]:  # take turns
                    t0 = time.perf_counter()
                    last[m] = run_method(m, mesh, spec, allow_open=True)
                    walls[m].append((time.perf_counter() - t0) * 1e3)
                    gpus[m].append(last[m].run.timings.gpu_s * 1e3)
            wall = {m: statistics.median(walls[m]) for m in METHODS}
            gpu = {m: statistics.median(gpus[m]) for m in METHODS}
            carve = last["carve-solid"]
            stages = ", ".join(f"{s.name} {s.gpu_s * 1e3:.1f}" for s in carve.run.timings.stages if s.gpu_s)
            print(f"| {name} | {n}^3 | " + " | ".join(f"{wall[m]:.1f} ({gpu[m]:.1f})" for m in METHODS)
                  + f" | {wall['carve-solid'] / wall['ss-solid']:.1f}x | {wall['vote-solid'] / wall['ss-solid']:.1f}x"
                  + f" | {stages} | {carve.run.stats['flood_rounds']} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=["rounds", "time"])
    ap.add_argument("--sizes", type=int, nargs="+", default=None)
    ap.add_argument("--close", type=int, nargs="+", default=[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--meshes", nargs="+", default=DEFAULT_MESHES)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", NotWatertightWarning)
    ctx = get_context()
    print(f"<!-- {ctx.renderer}; {ctx.version} -->")
    if args.what == "rounds":
        args.sizes = args.sizes or [64, 128, 256]
        rounds(args)
    else:
        args.sizes = args.sizes or [128, 256]
        timing(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
