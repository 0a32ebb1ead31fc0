"""Peak memory of writing a voxelized surface as .binvox and .npz, this tree against another.

    python compare/bench_writer_memory.py [--mesh stanford_bunny_bun_zipper.ply] [--sizes 512 1024]
                                          [--before REV_OR_DIR] [--formats .binvox .npz]

The mesh's ``ss-conservative`` surface at each SIZE^3 is voxelized once (in
this process) and its packed words saved to a temporary folder.  Each write
then runs in a fresh child process that loads the words into a
``VoxelGrid(words=...)`` (as a method returns it), resets the kernel's
peak-RSS mark (``/proc/self/clear_refs``), calls ``glvox.save`` and reports
``VmHWM`` (the peak resident memory) minus the resident memory before the
write: what the writer needs beyond the packed result.  ``tracemalloc``'s
peak (numpy registers its buffers with it) is printed beside it.  With
``--before``, the same children also run the glvox of another tree (a git
revision, extracted with ``git archive``, or a folder holding ``glvox/``),
so the table shows before and after.  The files each tree writes are
compared byte for byte (npz: each member's uncompressed bytes, as zip
headers carry the time).  Linux only (``/proc``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

CHILD = r"""
import json, sys, time, tracemalloc
import numpy as np
from glvox.grid import GridSpec
from glvox.results import VoxelGrid
from glvox import io

import glvox.io
assert glvox.io.__file__.startswith(sys.argv[4]), (glvox.io.__file__, sys.argv[4])
words_path, meta_path, out = sys.argv[1:4]
meta = json.loads(open(meta_path).read())
grid = VoxelGrid(words=np.load(words_path), spec=GridSpec(meta["dims"], meta["origin"], meta["h"]))

def status(key):
    return next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith(key + ":")) * 1024

open("/proc/self/clear_refs", "w").write("5")  # VmHWM := VmRSS
rss = status("VmRSS")
tracemalloc.start()
t = time.perf_counter()
io.save(grid, out)
seconds = time.perf_counter() - t
_, traced = tracemalloc.get_traced_memory()
print(json.dumps({"rss": rss, "hwm": status("VmHWM"), "traced": traced, "seconds": seconds}))
"""


def tree_of(before: str, tmp: Path) -> Path:
    """A folder holding the glvox package of ``before`` (a folder, or a git revision of this repo)."""
    if (Path(before) / "glvox").is_dir():
        return Path(before).resolve()
    dest = tmp / "before"
    dest.mkdir()
    tar = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", before, "glvox"],
                         check=True, capture_output=True).stdout
    tarfile.open(fileobj=__import__("io").BytesIO(tar)).extractall(dest, filter="data")
    return dest


def child(tree: Path, words: Path, meta: Path, out: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    # -P: not the working folder first on sys.path, so PYTHONPATH picks the tree
    p = subprocess.run([sys.executable, "-P", "-c", CHILD, str(words), str(meta), str(out), str(tree)], env=env,
                       capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"child for {tree} failed:\n{p.stderr}")
    return json.loads(p.stdout.strip().splitlines()[-1])


def same_output(a: Path, b: Path) -> bool:
    if a.suffix == ".npz":
        with zipfile.ZipFile(a) as za, zipfile.ZipFile(b) as zb:
            return (za.namelist() == zb.namelist()
                    and all(za.read(n) == zb.read(n) for n in za.namelist()))
    return a.read_bytes() == b.read_bytes()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mesh", default="stanford_bunny_bun_zipper.ply")
    ap.add_argument("--sizes", nargs="+", type=int, default=[512, 1024])
    ap.add_argument("--formats", nargs="+", default=[".binvox", ".npz"])
    ap.add_argument("--before", help="git revision or folder of the glvox to compare against")
    args = ap.parse_args()

    import numpy as np

    import glvox
    from glvox.datasets import resolve_mesh

    mib = 2.0 ** 20
    with tempfile.TemporaryDirectory(prefix="glvox-writer-mem-") as tmp_name:
        tmp = Path(tmp_name)
        trees = {"after": ROOT}
        if args.before:
            trees = {"before": tree_of(args.before, tmp), **trees}
        mesh = glvox.load_mesh(resolve_mesh(args.mesh))
        print(f"{args.mesh}, ss-conservative surface; load average {os.getloadavg()[0]:.2f}; "
              f"extra = peak RSS (VmHWM) during glvox.save minus RSS before it, MiB; "
              f"traced = tracemalloc peak, MiB")
        print("| N | format | packed MiB | " + " | ".join(f"{t} extra | {t} traced | {t} s" for t in trees)
              + " | same bytes |")
        print("|---|---|---|" + "---|---|---|" * len(trees) + "---|")
        for n in args.sizes:
            grid = glvox.voxelize(mesh, resolution=n, method="ss-conservative")
            words, meta = tmp / f"w{n}.npy", tmp / f"m{n}.json"
            np.save(words, np.ascontiguousarray(grid.words()))
            meta.write_text(json.dumps({"dims": list(grid.dims), "origin": grid.origin.tolist(),
                                        "h": grid.voxel_size}))
            packed = grid.words().nbytes / mib
            del grid
            for suffix in args.formats:
                cells, outs = [], []
                for name, tree in trees.items():
                    out = tmp / f"{name}{n}{suffix}"
                    r = child(tree, words, meta, out)
                    cells += [f"{(r['hwm'] - r['rss']) / mib:.0f}", f"{r['traced'] / mib:.0f}", f"{r['seconds']:.2f}"]
                    outs.append(out)
                same = all(same_output(outs[0], o) for o in outs[1:]) if len(outs) > 1 else "-"
                print(f"| {n} | {suffix} | {packed:.0f} | " + " | ".join(cells) + f" | {same} |", flush=True)
                for o in outs:
                    o.unlink()
        print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
