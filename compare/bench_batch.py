"""Meshes per second of ``glvox batch`` on a generated dataset (or any folder: ``--keep``), by worker count.

Each configuration is a fresh ``glvox batch ... --json`` process (cold Python,
cold GL context and shader cache, new worker processes), writing into an empty
output folder, as a user would run it; the configurations take turns run by
run.  Reported per configuration (median of ``--repeat`` runs):

* ``wall``: the command's wall time (imports, worker start, all meshes, shutdown);
* ``mesh/s``: meshes processed (voxelized or failed) per second of the batch's own
  elapsed time, worker start-up included (``processed_per_s`` of the summary);
  ``best``: the best run's;
* ``start-up``: starting the workers (0 in-process);
* ``per mesh``: mean seconds a worker spent on one mesh (manifest ``total_s``:
  load, voxelize, save), and its voxelize part.

Usage::

    python compare/bench_batch.py                       # 200 meshes, -r 32, ss-conservative
    python compare/bench_batch.py -n 400 -r 64 -m ss-solid --workers 0 1 2 --repeat 3
    python compare/bench_batch.py --lp-threads 1        # llvmpipe with one thread per context
    python compare/bench_batch.py --keep "$GLVOX_MESHES" -r 64 --workers 0 2   # the shared meshes
    python compare/bench_batch.py --workers 0 2 --against 476e070   # side by side with a revision
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from glvox.datasets import checkout_root
from glvox.study.ab import child_env, extract_revision
from glvox.testing.datasets import synthetic_dataset


def run_once(data: Path, out: Path, args, workers: int, env, cwd: Path) -> dict:
    """One fresh ``glvox batch`` process; with ``-S`` the glvox of ``env``'s PYTHONPATH
    (a revision's tree: :func:`glvox.study.ab.child_env`) is the one imported."""
    cmd = [sys.executable, "-S", "-m", "glvox", "batch", str(data), "-o", str(out), "-r", str(args.resolution),
           "-m", args.method, "--format", args.format, "--workers", str(workers), "--json"]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=3600, cwd=cwd)
    wall = time.perf_counter() - t0
    if p.returncode not in (0, 3):
        raise SystemExit(f"glvox batch failed ({p.returncode}): {p.stderr}")
    s = json.loads(p.stdout)
    with open(s["manifest"], newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["status"] == "done"]
    per_mesh = statistics.fmean(float(r["total_s"]) for r in rows)
    vox = statistics.fmean(float(r["voxelize_s"]) for r in rows)
    return {"wall": wall, "rate": s["processed_per_s"], "startup": s["startup_s"],
            "elapsed": s["elapsed_s"], "per_mesh": per_mesh, "voxelize": vox,
            "done": s["done"], "failed": s["failed"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("-n", type=int, default=200, help="meshes in the generated dataset")
    ap.add_argument("-r", "--resolution", type=int, default=32)
    ap.add_argument("-m", "--method", default="ss-conservative")
    ap.add_argument("--format", default="npz", choices=["npz", "binvox"])
    ap.add_argument("--workers", type=int, nargs="+", default=[0, 1, 2],
                    help="worker counts; 0 = in-process, no Dask")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--lp-threads", type=int, default=None,
                    help="LP_NUM_THREADS for llvmpipe in every process (default: Mesa's, one per core)")
    ap.add_argument("--keep", type=Path, default=None, help="generate the dataset here and keep it")
    ap.add_argument("--against", metavar="REV", default=None,
                    help="also run glvox batch of this git revision (git archive), taking turns with this checkout")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory(prefix="glvox-bench-batch-") as tmp:
        trees = {"": checkout_root()}
        if args.against:
            trees[f"{args.against} "] = extract_revision(args.against, Path(tmp) / "before")
        envs = {}
        for label, src in trees.items():
            envs[label] = child_env(src)
            if args.lp_threads is not None:
                envs[label]["LP_NUM_THREADS"] = str(args.lp_threads)
            found = subprocess.run([sys.executable, "-S", "-c", "import glvox; print(glvox.__file__)"],
                                   capture_output=True, text=True, env=envs[label], cwd=tmp).stdout.strip()
            if Path(src).resolve() not in Path(found).resolve().parents:
                raise SystemExit(f"a batch for {src} would import glvox from {found!r}")
        data = (args.keep or Path(tmp) / "data").resolve()
        if not data.is_dir():
            files = synthetic_dataset(data, args.n)
        else:
            files = None
        what = f"{args.n} meshes + broken files" if files else f"{sum(1 for _ in data.iterdir())} files, reused"
        print(f"dataset: {data} ({what}); "
              f"glvox batch -r {args.resolution} -m {args.method} --format {args.format}; "
              f"{os.cpu_count()} CPUs, LP_NUM_THREADS={args.lp_threads or 'default'}; "
              f"median of {args.repeat}")
        print(f"{'workers':>22} {'wall s':>8} {'mesh/s':>8} {'best':>8} {'start-up s':>10} {'per mesh ms':>12} "
              f"{'voxelize ms':>12} {'mesh/s excl. start-up':>22}")
        configs = [(tree, w) for tree in trees for w in args.workers]
        runs: dict[tuple, list[dict]] = {c: [] for c in configs}
        for i in range(args.repeat):  # configurations take turns, each first in turn: load drift lands on all
            k = i % len(configs)
            for tree, w in configs[k:] + configs[:k]:
                out = Path(tmp) / f"out-{len(tree)}-{w}-{i}"
                runs[tree, w].append(run_once(data, out, args, w, envs[tree], Path(tmp)))
        for tree, w in configs:
            rs = runs[tree, w]
            med = {k: statistics.median(r[k] for r in rs) for k in rs[0]}
            best = max(r["rate"] for r in rs)
            processed = med["done"] + med["failed"]
            steady = processed / max(med["elapsed"] - med["startup"], 1e-9)
            label = tree + ("0 (in-process)" if w == 0 else str(w))
            print(f"{label:>22} {med['wall']:8.2f} {med['rate']:8.1f} {best:8.1f} {med['startup']:10.2f} "
                  f"{med['per_mesh'] * 1e3:12.1f} {med['voxelize'] * 1e3:12.1f} {steady:22.1f}", flush=True)


if __name__ == "__main__":
    main()
