"""Write times and file sizes of the exports in the voxels' colours: .vox,
coloured points and cubes (PLY, GLB), and a picture (glvox render's path).

    python compare/bench_exports.py [--mesh stanford_bunny_bun_zipper.ply] [--sizes 256 512 1024]
                                    [--repeat 3] [--out DIR]

Each row is the mesh's conservative surface (``ss-conservative``) at SIZE^3
with a colour per voxel: a gradient over the grid plus noise (several
hundred thousand distinct colours, so .vox goes through the quantizer),
the layout of ``attributes['color']``.  "write" is the whole
``glvox.save`` a user waits for (set voxels, colours, quantizing, encoding,
the file); "quantize" is the palette alone; "render" a 960 x 720 picture
(``glvox.study.render.render_voxels``, the GL draw and read-back included).
Times are medians of REPEAT runs in seconds, sizes MiB (2^20 bytes).
Prints a markdown table.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

import glvox
from glvox.datasets import resolve_mesh
from glvox.formats.colors import quantize
from glvox.gl.context import get_context
from glvox.study.render import render_voxels

SUFFIXES = [".vox", ".points.ply", ".points.glb", ".cubes.ply", ".cubes.glb"]


def median_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def with_gradient(grid, seed: int = 0):
    """``grid`` carrying a colour per voxel: its position as RGB plus noise, opaque."""
    ijk = grid.indices()
    rng = np.random.default_rng(seed)
    rgb = ijk * (255.0 / max(grid.dims)) + rng.normal(0, 6, ijk.shape)
    colors = np.concatenate([np.clip(np.rint(rgb), 0, 255), np.full((len(ijk), 1), 255)], axis=1)
    grid.set_attributes({"color": colors.astype(np.uint8)})
    return grid


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="stanford_bunny_bun_zipper.ply")
    ap.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=None, help="folder for the files (default: a temporary one)")
    args = ap.parse_args()
    mesh = resolve_mesh(args.mesh)
    ctx = get_context()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        for n in args.sizes:
            g = with_gradient(glvox.voxelize(mesh, n, method="ss-conservative"))
            distinct = len(np.unique(g.attributes["color"].view("<u4")))
            label = f"{n}^3, {g.count:,} voxels, {distinct:,} colours"
            q = median_time(lambda: quantize(g.attributes["color"]), args.repeat)
            r = median_time(lambda: render_voxels(ctx, g), args.repeat)
            rows.append((label, "quantize (255)", q, None))
            rows.append((label, "render 960 x 720", r, None))
            for s in SUFFIXES:
                path = out / f"{Path(args.mesh).stem}_{n}{s}"
                w = median_time(lambda: glvox.save(g, path), args.repeat)
                rows.append((label, s, w, path.stat().st_size / 2 ** 20))
                print(rows[-1], flush=True)
    print("\n| result | export | seconds | MiB |\n|---|---|---|---|")
    for label, what, t, mib in rows:
        print(f"| {label} | {what} | {t:.3f} | {'' if mib is None else f'{mib:.2f}'} |")


if __name__ == "__main__":
    main()
