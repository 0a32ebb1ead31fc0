"""This checkout against a git revision, around the voxelization: loading, end to end, readback, cold start.

    python compare/before_after.py --against 476e070              # every part
    python compare/before_after.py --against main --parts load e2e --repeat 9

Two child processes (:mod:`compare.before_after_child`), one importing glvox
from ``git archive REV`` ("before"), one from this checkout ("after"), as
``glvox bench --against`` runs them (:mod:`glvox.study.ab`), take turns file
by file or run by run with Open3D timed in this process, so load from
elsewhere lands on every side.  Parts (the tables of README "Loading,
readback, cold start, workers"):

* ``load``: ``load_mesh`` per shared mesh and per format, against Open3D's
  ``read_triangle_mesh``; best / median ms;
* ``e2e``: read + fit + ``ss-conservative`` at 64^3 + ``dense()`` per shared
  mesh, meshes/s, against Open3D (with and without its voxels as numpy);
* ``dense``: ``run_method``, its readback stage, ``dense()`` and ``points()``
  at 512^3 and 1024^3 (bunny ``ss-conservative``, armadillo ``ss-solid``),
  beside ``np.ones(nx * ny * nz, bool)`` in the same process: the bytes any
  dense result writes into fresh memory, the floor of ``dense()``;
* ``cold``: a fresh ``glvox voxelize cad_featuretype.stl -r 128`` process.

``glvox batch`` is measured by ``compare/bench_batch.py`` (one glvox at a time).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from glvox.datasets import SHARED_MESHES, checkout_root, mesh_dir
from glvox.study.ab import child_env, extract_revision
from glvox.study.endtoend import _open3d_job

CHILD = Path(__file__).with_name("before_after_child.py")
DENSE_CELLS = [("stanford_bunny_bun_zipper.ply", 512, "ss-conservative"),
               ("stanford_bunny_bun_zipper.ply", 1024, "ss-conservative"),
               ("stanford_armadillo_libigl_86k.obj", 512, "ss-solid"),
               ("stanford_armadillo_libigl_86k.obj", 1024, "ss-solid")]


class Side:
    def __init__(self, src: Path, workdir: Path):
        workdir.mkdir(parents=True, exist_ok=True)
        script = workdir / CHILD.name
        shutil.copyfile(CHILD, script)
        self.src = src
        self.p = subprocess.Popen([sys.executable, "-S", str(script)], stdin=subprocess.PIPE,
                                  stdout=subprocess.PIPE, text=True, env=child_env(src), cwd=workdir)
        ready = json.loads(self.p.stdout.readline())["ready"]
        if src not in Path(ready).resolve().parents:
            raise SystemExit(f"the child for {src} imported glvox from {ready}")

    def ask(self, **req) -> dict:
        self.p.stdin.write(json.dumps(req) + "\n")
        self.p.stdin.flush()
        return json.loads(self.p.stdout.readline())

    def close(self) -> None:
        self.p.stdin.close()
        self.p.wait()


def _fmt(ts) -> str:
    return f"{min(ts) * 1e3:.1f} / {statistics.median(ts) * 1e3:.1f}"


def _kind(name: str) -> str:
    path = mesh_dir() / name
    suffix = path.suffix.lower()
    if suffix == ".ply":
        return "PLY binary" if b"binary" in path.read_bytes()[:512].split(b"end_header")[0] else "PLY ASCII"
    if suffix == ".stl":
        return "STL ASCII" if path.read_bytes()[:512].lstrip().startswith(b"solid\n") else "STL binary"
    return suffix[1:].upper()


def _rounds(files, sides, repeat, one):
    """``one(side, path)`` seconds for each file and side, interleaved; round 0 untimed."""
    t = {s: {f: [] for f in files} for s in sides}
    for r in range(repeat + 1):
        for i, f in enumerate(files):
            k = (r + i) % len(sides)
            for s in sides[k:] + sides[:k]:
                if t[s][f] is None:
                    continue
                try:
                    sec = one(s, str(mesh_dir() / f))
                except Exception:  # noqa: BLE001 - a file a side cannot read
                    t[s][f] = None
                    continue
                if r:
                    t[s][f].append(sec)
    return t


def part_load(before: Side, after: Side, repeat: int) -> None:
    import open3d as o3d  # lazy: an optional peer

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    # "after + closed" also reads the watertight verdict, which "after" decides on first
    # read and "before" decided while loading
    sides = ["before", "after", "after + closed", "open3d"]

    def one(s, p):
        if s == "open3d":
            t0 = time.perf_counter()
            o3d.io.read_triangle_mesh(p)
            return time.perf_counter() - t0
        return (before if s == "before" else after).ask(op="load", path=p, closed=s.endswith("closed"))["s"]

    files = [f for f in SHARED_MESHES if (mesh_dir() / f).is_file()]
    t = _rounds(files, sides, repeat, one)
    print(f"\n## Loading, best / median ms of {repeat} interleaved rounds (load average {os.getloadavg()[0]:.2f})\n")
    print("| file | before | after | after + closed | Open3D |\n|---|---|---|---|---|")
    kinds: dict[str, list[str]] = {}
    for f in files:
        print(f"| {f} | " + " | ".join(_fmt(t[s][f]) for s in sides) + " |")
        kinds.setdefault(_kind(f), []).append(f)
    print("\n| format | files | before ms | after ms | after + closed ms | Open3D ms | after / Open3D | "
          "after + closed / Open3D |\n|---|---|---|---|---|---|---|---|")
    for k, fs in sorted(kinds.items()) + [("all", files)]:
        b, a, c, o = (sum(min(t[s][f]) for f in fs) * 1e3 for s in sides)
        print(f"| {k} | {len(fs)} | {b:.1f} | {a:.1f} | {c:.1f} | {o:.1f} | {a / o:.2f} | {c / o:.2f} |")


def part_e2e(before: Side, after: Side, repeat: int, n: int = 64) -> None:
    jobs = {"open3d": _open3d_job(n), "open3d, no numpy": _open3d_job(n, numpy_result=False)}
    sides = ["before", "after", *jobs]

    def one(s, p):
        if s in jobs:
            t0 = time.perf_counter()
            jobs[s](p)
            return time.perf_counter() - t0
        return (before if s == "before" else after).ask(op="e2e", path=p, n=n)["s"]

    files = [f for f in SHARED_MESHES if (mesh_dir() / f).is_file()]
    t = _rounds(files, sides, repeat, one)
    common = [f for f in files if all(t[s][f] for s in sides)]
    print(f"\n## End to end at {n}^3 over {len(common)} shared meshes every side read, best / median of "
          f"{repeat} rounds (load average {os.getloadavg()[0]:.2f})\n")
    print("| side | meshes/s best | meshes/s median |\n|---|---|---|")
    for s in sides:
        best, med = (sum(g(t[s][f]) for f in common) for g in (min, statistics.median))
        print(f"| {s} | {len(common) / best:.1f} | {len(common) / med:.1f} |")


def part_dense(before: Side, after: Side, repeat: int) -> None:
    print(f"\n## Readback, best ms of {repeat} interleaved runs (load average {os.getloadavg()[0]:.2f})\n")
    print("| mesh | N | method | side | run_method | readback stage | dense() | points() | dense() / readback | "
          "np.ones(nx ny nz) | dense() / np.ones |\n|---|---|---|---|---|---|---|---|---|---|---|")
    for mesh, n, method in DENSE_CELLS:
        res = {"before": [], "after": []}
        for r in range(repeat + 1):
            for name, side in ((("before", before), ("after", after)) if r % 2 else (("after", after), ("before", before))):
                out = side.ask(op="dense", path=str(mesh_dir() / mesh), n=n, method=method)
                if r and "error" not in out:
                    res[name].append(out)
        for name, rs in res.items():
            if rs:
                b = {k: min(x[k] for x in rs) * 1e3 for k in ("run_s", "readback_s", "dense_s", "points_s", "floor_s")}
                print(f"| {mesh} | {n} | {method} | {name} | {b['run_s']:.1f} | {b['readback_s']:.1f} | "
                      f"{b['dense_s']:.1f} | {b['points_s']:.1f} | {b['dense_s'] / b['readback_s']:.1f} | "
                      f"{b['floor_s']:.1f} | {b['dense_s'] / b['floor_s']:.2f} |", flush=True)


def part_cold(srcs: dict[str, Path], repeat: int, workdir: Path) -> None:
    t = {name: [] for name in srcs}
    for r in range(repeat):
        for name in (list(srcs) if r % 2 else list(srcs)[::-1]):
            cmd = [sys.executable, "-S", "-m", "glvox", "voxelize", str(mesh_dir() / "cad_featuretype.stl"),
                   "-r", "128", "-o", str(workdir / f"cold_{name}.npz"), "-q"]
            t0 = time.perf_counter()
            subprocess.run(cmd, check=True, env=child_env(srcs[name]), cwd=workdir)
            t[name].append(time.perf_counter() - t0)
    print(f"\n## Cold glvox voxelize cad_featuretype.stl -r 128, best / median s of {repeat} "
          f"(load average {os.getloadavg()[0]:.2f})\n")
    for name, ts in t.items():
        print(f"- {name}: {min(ts):.2f} / {statistics.median(ts):.2f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--against", required=True, metavar="REV", help="the 'before' git revision")
    ap.add_argument("--parts", nargs="+", default=["load", "e2e", "dense", "cold"],
                    choices=["load", "e2e", "dense", "cold"])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    root = checkout_root()
    if root is None:
        raise SystemExit("run this from a git checkout of glvox")
    with tempfile.TemporaryDirectory(prefix="glvox-before-after-") as tmp:
        tmp = Path(tmp)
        srcs = {"before": extract_revision(args.against, tmp / "before"), "after": root}
        before, after = Side(srcs["before"], tmp / "run-before"), Side(srcs["after"], tmp / "run-after")
        try:
            if "load" in args.parts:
                part_load(before, after, args.repeat)
            if "e2e" in args.parts:
                part_e2e(before, after, args.repeat)
            if "dense" in args.parts:
                part_dense(before, after, max(1, args.repeat - 2))
        finally:
            before.close()
            after.close()
        if "cold" in args.parts:
            part_cold(srcs, args.repeat + 1, tmp)


if __name__ == "__main__":
    main()
