"""What the per-stage waits for the GPU cost a call: whole calls with and without them, side by side.

    python compare/bench_sync.py                                   # ss-conservative, ss-solid on the bunny
    python compare/bench_sync.py -m ss-conservative --meshes gen:torus -r 32 64 --repeat 21

Every glvox run times its stages, and by default each stage waits for the GPU
at its end (``glvox.gl.timing``): honest stage times, but the CPU and the GPU
then take turns, and a small grid's call is mostly those turns.  This script
runs each method, mesh and size with the waits and without them
(``glvox.gl.timing.stage_sync``), the two alternating call by call in one
process after a warm-up of each, and prints the median and best whole call of
each (``run_method`` as a user calls it, the packed result in host memory; the
parity solids with ``allow_open`` on an open mesh, as ``glvox bench`` runs them), their
ratio, and the unsynced run's GPU time (the sum of its stages' timer queries).
Both give the same voxels (checked).  On llvmpipe the calls without the
waits took 0.88-0.98 of the time (docs/performance.md); on a GPU the ratio is
what the waits cost there.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings

import numpy as np

from glvox import grid_for, load_mesh, run_method
from glvox.gl.timing import stage_sync

BUNNY = "stanford_bunny_bun_zipper.ply"


def measure(method: str, mesh, n: int, repeat: int) -> dict:
    """Medians and bests (ms) of whole calls with and without the per-stage waits."""
    spec = grid_for(mesh, n)
    call = {"allow_open": True}  # as glvox bench runs the parity solids on an open mesh
    walls: dict[bool, list[float]] = {True: [], False: []}
    gpu: list[float] = []
    words = {}
    for sync in (True, False):  # warm-up: compile, upload, allocate
        with stage_sync(sync):
            words[sync] = run_method(method, mesh, spec, **call).words()
    if not np.array_equal(words[True], words[False]):
        raise SystemExit(f"{method} on {mesh.name} at {n}^3: the voxels differ without the waits")
    for _ in range(repeat):
        for sync in (True, False):
            with stage_sync(sync):
                t0 = time.perf_counter()
                result = run_method(method, mesh, spec, **call)
                walls[sync].append(time.perf_counter() - t0)
            if not sync and result.run.timings.gpu_s is not None:
                gpu.append(result.run.timings.gpu_s)
    med = {s: statistics.median(v) * 1e3 for s, v in walls.items()}
    return {"synced_ms": med[True], "unsynced_ms": med[False], "synced_best_ms": min(walls[True]) * 1e3,
            "unsynced_best_ms": min(walls[False]) * 1e3, "ratio": med[False] / med[True],
            "gpu_ms": statistics.median(gpu) * 1e3 if gpu else None}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-m", "--methods", nargs="+", default=["ss-conservative", "ss-solid"])
    ap.add_argument("--meshes", nargs="+", default=[BUNNY], help="shared mesh names, paths or gen: meshes")
    ap.add_argument("-r", "--sizes", nargs="+", type=int, default=[64, 128, 256])
    ap.add_argument("--repeat", type=int, default=11, help="calls of each kind per cell")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")  # an open mesh's parity warning, once per call
    print("| method | mesh | N | with waits: median / best ms | without: median / best ms | "
          "without / with | GPU ms (stage queries) |")
    print("|---|---|---|---|---|---|---|")
    for name in args.meshes:
        mesh = load_mesh(name)
        for method in args.methods:
            for n in args.sizes:
                r = measure(method, mesh, n, args.repeat)
                gpu = "-" if r["gpu_ms"] is None else f"{r['gpu_ms']:.2f}"
                print(f"| {method} | {mesh.name} | {n} | {r['synced_ms']:.2f} / {r['synced_best_ms']:.2f} | "
                      f"{r['unsynced_ms']:.2f} / {r['unsynced_best_ms']:.2f} | {r['ratio']:.2f} | {gpu} |",
                      flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
