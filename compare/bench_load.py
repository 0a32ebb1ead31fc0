"""Mesh loading: ``glvox.load_mesh`` against Open3D's ``read_triangle_mesh``, per file and per format.

Both read every shared mesh (``GLVOX_MESHES``) in interleaved rounds (the
order alternates file by file, so load from elsewhere lands on both); best
and median milliseconds per file, then the sum of the best times per format.
glvox's time includes its validation (NaN, indices, zero-area triangles);
the watertight verdict, decided on first read, is timed in its own column
(``+ closed``: ``load_mesh(p).watertight``, as a solid method or the batch
manifest reads it).  Open3D only reads.

Usage::

    python compare/bench_load.py                 # 5 rounds
    python compare/bench_load.py --repeat 9 --files stanford_bunny_bun_zipper.ply
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import glvox
from glvox.datasets import SHARED_MESHES, mesh_dir


def _format(path: str) -> str:
    suffix = os.path.splitext(path)[1].lower()
    if suffix in (".ply", ".stl"):
        with open(path, "rb") as f:
            head = f.read(512)
        binary = b"binary" in head.split(b"end_header")[0] if suffix == ".ply" else not head.lstrip().startswith(b"solid")
        return f"{suffix} {'binary' if binary else 'ASCII'}"
    return suffix


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--files", nargs="+", default=list(SHARED_MESHES))
    args = ap.parse_args()
    import open3d as o3d  # lazy: an optional peer (glvox[peers])

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    paths = [str(mesh_dir() / f) for f in args.files if (mesh_dir() / f).is_file()]
    readers = {"glvox": glvox.load_mesh, "closed": lambda p: glvox.load_mesh(p).watertight,
               "open3d": o3d.io.read_triangle_mesh}
    times = {k: {p: [] for p in paths} for k in readers}
    print(f"load average {os.getloadavg()[0]:.2f}; best / median ms of {args.repeat} interleaved rounds")
    for rnd in range(args.repeat + 1):  # round 0: page cache and first calls, untimed
        for i, p in enumerate(paths):
            order = list(readers)[(rnd + i) % 3:] + list(readers)[:(rnd + i) % 3]  # each goes first in turn
            for k in order:
                t0 = time.perf_counter()
                readers[k](p)
                if rnd:
                    times[k][p].append(time.perf_counter() - t0)
    print("| file | glvox | glvox + closed | Open3D | glvox / Open3D (best) | + closed / Open3D |\n"
          "|---|---|---|---|---|---|")
    formats: dict[str, list[str]] = {}
    for p in paths:
        g, c, o = times["glvox"][p], times["closed"][p], times["open3d"][p]
        print(f"| {os.path.basename(p)} | {min(g) * 1e3:.1f} / {statistics.median(g) * 1e3:.1f} | "
              f"{min(c) * 1e3:.1f} / {statistics.median(c) * 1e3:.1f} | "
              f"{min(o) * 1e3:.1f} / {statistics.median(o) * 1e3:.1f} | {min(g) / min(o):.2f} | "
              f"{min(c) / min(o):.2f} |")
        formats.setdefault(_format(p), []).append(p)
    print("\n| format | files | glvox ms | glvox + closed ms | Open3D ms | glvox / Open3D | + closed / Open3D |\n"
          "|---|---|---|---|---|---|---|")
    for fmt, ps in sorted(formats.items()) + [("all", paths)]:
        g, c, o = (sum(min(times[k][p]) for p in ps) for k in readers)
        print(f"| {fmt} | {len(ps)} | {g * 1e3:.1f} | {c * 1e3:.1f} | {o * 1e3:.1f} | {g / o:.2f} | {c / o:.2f} |")
    print(f"load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
