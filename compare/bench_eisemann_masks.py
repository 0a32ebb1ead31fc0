"""Eisemann & Decoret: mask texture vs bit arithmetic in the fragment shader,
per-stage times, and how much of the conservative surface the OR pass reaches.

    python compare/bench_eisemann_masks.py [--sizes 128 256 512] [--repeat 5]
                                           [--meshes stanford_armadillo_libigl_86k.obj ...]
    python compare/bench_eisemann_masks.py --vary coverage
    python compare/bench_eisemann_masks.py --fraction [--sizes 128]

The first form times eisemann-solid (XOR) and eisemann-surface (OR) with
``masks=bits`` and ``masks=texture``, the two variants interleaved run by run
so that load from other processes hits both alike, and prints the median wall
time of the ``render`` stages (where the masks are made), of the whole run,
and the per-stage medians of the first variant.  ``--vary coverage`` does the
same for ``coverage=exact`` against ``coverage=raster`` (the price of deciding
coverage exactly).  ``--fraction`` prints, per
shared mesh, the voxels of eisemann-surface against reference-conservative
(the share of the conservative surface that sampling at column centers
reaches) along each axis (default: every shared mesh).  Meshes are paths or
names in GLVOX_MESHES (default ../shared/meshes beside the checkout).  Prints
markdown tables.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings

import glvox
from glvox.errors import NotWatertightWarning
from glvox.gl.context import get_context
from glvox.methods import run_method
from glvox.datasets import SHARED_MESHES, resolve_mesh

DEFAULT_MESHES = ["stanford_armadillo_libigl_86k.obj", "stanford_bunny_bun_zipper.ply",
                  "stanford_dragon_vrip_res2.ply"]
STAGES = ("transform", "setup", "render", "pack", "readback")


def stage_sums(grid) -> dict[str, float]:
    """Wall ms per stage name (render and pack summed over tiles and passes)."""
    out: dict[str, float] = {}
    for s in grid.run.timings.stages:
        out[s.name] = out.get(s.name, 0.0) + s.wall_s * 1e3
    return out


VARIANTS = {"masks": ("bits", "texture"), "coverage": ("exact", "raster")}


def timings(args) -> None:
    ctx = get_context()
    a, b = VARIANTS[args.vary]
    print(f"<!-- {ctx.renderer}; {ctx.version}; wall ms, median of {args.repeat} warm runs, "
          f"{args.vary}={a} and {args.vary}={b} interleaved -->")
    print(f"| model | grid | method | render {a} | render {b} | {b}/{a} | total {a} | "
          f"total {b} | stages ({a}): " + " / ".join(STAGES) + " |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in args.meshes:
        mesh = glvox.load_mesh(resolve_mesh(name))
        for n in args.sizes:
            spec = glvox.grid_for(mesh, n)
            for method in ("eisemann-solid", "eisemann-surface"):
                runs = {a: [], b: []}
                for variant in runs:  # warm-up: compile, upload, allocate
                    run_method(method, mesh, spec, allow_open=True, **{args.vary: variant})
                for _ in range(args.repeat):
                    for variant in runs:
                        t0 = time.perf_counter()
                        g = run_method(method, mesh, spec, allow_open=True, **{args.vary: variant})
                        runs[variant].append(((time.perf_counter() - t0) * 1e3, stage_sums(g)))
                med = {v: (statistics.median(w for w, _ in r),
                           statistics.median(s["render"] for _, s in r)) for v, r in runs.items()}
                stages = " / ".join(f"{statistics.median(s.get(k, 0.0) for _, s in runs[a]):.1f}"
                                    for k in STAGES)
                print(f"| {name} | {n}^3 | {method} | {med[a][1]:.1f} | {med[b][1]:.1f} | "
                      f"{med[b][1] / med[a][1]:.2f} | {med[a][0]:.1f} | {med[b][0]:.1f} | {stages} |",
                      flush=True)


def fraction(args) -> None:
    print("| model | grid | reference-conservative | eisemann-surface x / y / z | share x / y / z | "
          "outside the conservative surface |")
    print("|---|---|---|---|---|---|")
    for name in args.meshes:
        mesh = glvox.load_mesh(resolve_mesh(name))
        for n in args.sizes:
            spec = glvox.grid_for(mesh, n)
            ref = run_method("reference-conservative", mesh, spec).dense()
            counts, shares, outside = [], [], 0
            for axis in (0, 1, 2):
                g = run_method("eisemann-surface", mesh, spec, axis=axis).dense()
                outside += int((g & ~ref).sum())  # ties at most (tests/test_eisemann.py)
                counts.append(int(g.sum()))
                shares.append(f"{100.0 * g.sum() / ref.sum():.1f}%")
            print(f"| {name} | {n}^3 | {int(ref.sum())} | {' / '.join(map(str, counts))} | "
                  f"{' / '.join(shares)} | {outside} |", flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=None)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--meshes", nargs="+", default=None)
    ap.add_argument("--vary", choices=sorted(VARIANTS), default="masks",
                    help="the option whose two values are timed against each other")
    ap.add_argument("--fraction", action="store_true",
                    help="the OR surface's share of the conservative surface instead of timings")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", NotWatertightWarning)
    if args.fraction:
        args.sizes = args.sizes or [128]
        args.meshes = args.meshes or list(SHARED_MESHES)
        fraction(args)
    else:
        args.sizes = args.sizes or [128, 256, 512]
        args.meshes = args.meshes or DEFAULT_MESHES
        timings(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
