"""Which ``ss-conservative`` variant is fastest, by grid size and triangle density.

Every variant (simple, specialized, sorted) on each mesh and size, in
interleaved warm rounds (the variants take turns, the order rotating), best
and median wall time of the whole ``run_method`` call.  Prints one row per
cell with ``F / N^2`` (triangles per voxel of a grid face: the density that
decides how many voxels a triangle's bounding box holds), the times, and
the variant :func:`glvox.methods.ss.surface.default_variant` picks.

Usage::

    python compare/ss_variants.py                      # 5 shared meshes, 64^3 to 1024^3
    python compare/ss_variants.py --sizes 128 256 --meshes stanford_bunny_bun_zipper.ply --repeat 7
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import glvox
from glvox.datasets import resolve_mesh
from glvox.methods import run_method
from glvox.methods.ss.surface import default_variant

MESHES = ["cad_featuretype.stl", "cad_fandisk.off", "stanford_bunny_bun_zipper.ply",
          "stanford_armadillo_libigl_86k.obj", "stanford_dragon_vrip_res2.ply"]
VARIANTS = ("simple", "specialized", "sorted")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--meshes", nargs="+", default=MESHES)
    ap.add_argument("--sizes", nargs="+", type=int, default=[64, 128, 256, 512, 1024])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}; best (median) ms of {args.repeat} interleaved runs")
    print(f"{'mesh':34s} {'F':>7s} {'N':>5s} {'F/N^2':>7s} " + " ".join(f"{v:>18s}" for v in VARIANTS)
          + f" {'fastest':>12s} {'picked':>12s} {'picked/best':>11s}")
    for name in args.meshes:
        mesh = glvox.load_mesh(resolve_mesh(name))
        for n in args.sizes:
            spec = glvox.grid_for(mesh, n)
            times = {v: [] for v in VARIANTS}
            for v in VARIANTS:  # warm-up: compilation and buffers
                run_method("ss-conservative", mesh, spec, variant=v)
            for rnd in range(args.repeat):
                order = VARIANTS[rnd % 3:] + VARIANTS[:rnd % 3]
                for v in order:
                    t0 = time.perf_counter()
                    run_method("ss-conservative", mesh, spec, variant=v)
                    times[v].append(time.perf_counter() - t0)
            best = {v: min(t) for v, t in times.items()}
            fastest = min(best, key=best.get)
            picked = default_variant(mesh.n_triangles, spec.dims)
            cells = " ".join(f"{best[v] * 1e3:8.1f} ({statistics.median(times[v]) * 1e3:7.1f})" for v in VARIANTS)
            print(f"{name:34s} {mesh.n_triangles:7d} {n:5d} {mesh.n_triangles / n**2:7.3f} {cells} "
                  f"{fastest:>12s} {picked:>12s} {best[picked] / best[fastest]:11.2f}", flush=True)
    print(f"load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
