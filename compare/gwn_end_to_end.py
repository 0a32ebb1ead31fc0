"""gwn-solid against libigl's and Warp's winding numbers, end to end as a user waits.

    python compare/gwn_end_to_end.py [--sizes 128 256] [--repeat 3]
                                     [--meshes stanford_bunny_bun_zipper.ply stanford_armadillo_libigl_86k.obj]
                                     [--warp-max 128]

Per mesh and size, in one process, the contenders take turns (warm: each has
run once before the timed rounds; the median of ``--repeat`` rounds):

* ``gwn-solid``: ``glvox.load_mesh(path)``, ``glvox.grid_for``,
  ``glvox.voxelize(..., method="gwn-solid")`` and ``.dense()`` (a bool numpy
  array (nx, ny, nz)); beside it the kernel time (the GPU stages' timestamp sum);
* ``igl``: ``igl.read_triangle_mesh(path)``, the centers of the same grid,
  ``igl.fast_winding_number`` and ``>= 0.5`` reshaped to (nx, ny, nz);
* ``warp``: the same load, ``wp.Mesh(..., support_winding_number=True)`` on the
  CPU device, the kernel of ``glvox.study.peers.WarpWinding`` and ``.numpy()``.

Each ends with the same voxels up to the expansions' error near w = 1/2 (the
agreement with gwn-solid is printed).  Meshes are paths or names in
GLVOX_MESHES (glvox.datasets).  Prints a markdown table: end-to-end ms,
the ratio of each peer to gwn-solid, and gwn-solid's kernel ms.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from types import SimpleNamespace

import numpy as np

import glvox
from glvox.datasets import resolve_mesh
from glvox.study.peers import WarpWinding, _warp_kernel

DEFAULT_MESHES = ["stanford_bunny_bun_zipper.ply", "stanford_armadillo_libigl_86k.obj"]


def run_glvox(path: str, spec):
    g = glvox.voxelize(glvox.load_mesh(path), grid=spec, method="gwn-solid")
    return g.dense(), g.run.timings.gpu_s


def run_igl(path: str, spec):
    import igl  # lazy: an optional peer

    V, F = igl.read_triangle_mesh(path)
    nx, ny, nz = spec.dims
    axes = [spec.origin[a] + (np.arange(spec.dims[a]) + 0.5) * spec.voxel_size for a in range(3)]
    q = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    w = igl.fast_winding_number(np.ascontiguousarray(V), np.ascontiguousarray(F, np.int64), q)
    return (w >= 0.5).reshape(nx, ny, nz), None


def run_warp(path: str, spec):
    import igl  # lazy: the same loader as the libigl contender

    V, F = igl.read_triangle_mesh(path)
    peer = WarpWinding()
    native = peer.run(peer.prepare(SimpleNamespace(vertices=V, faces=F), spec))  # (nz, ny, nx) int8
    return native.transpose(2, 1, 0) != 0, None


CONTENDERS = {"gwn-solid": run_glvox, "igl": run_igl, "warp": run_warp}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[128, 256])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--meshes", nargs="+", default=DEFAULT_MESHES)
    ap.add_argument("--warp-max", type=int, default=128, help="largest N Warp runs at (one thread: slow)")
    args = ap.parse_args(argv)
    _warp_kernel()
    print("| mesh | N | gwn-solid ms (kernel ms) | igl ms | warp ms | igl / gwn | warp / gwn | "
          "voxels | differ igl / warp |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in args.meshes:
        path = resolve_mesh(name)
        for n in args.sizes:
            spec = glvox.grid_for(glvox.load_mesh(path), n)  # one placement for all, not timed
            names = [c for c in CONTENDERS if c != "warp" or n <= args.warp_max]
            times: dict[str, list[float]] = {c: [] for c in names}
            kernel, grids = [], {}
            for c in names:  # warm-up: compilation, caches
                grids[c] = CONTENDERS[c](path, spec)[0]
            for rnd in range(args.repeat):
                for c in names[rnd % len(names):] + names[:rnd % len(names)]:
                    t0 = time.perf_counter()
                    grid, k = CONTENDERS[c](path, spec)
                    times[c].append(time.perf_counter() - t0)
                    if k is not None:
                        kernel.append(k)
            med = {c: statistics.median(v) * 1e3 for c, v in times.items()}
            ref = grids["gwn-solid"]
            differ = [str(int((grids[c] != ref).sum())) if c in grids else "-" for c in ("igl", "warp")]
            warp = f"{med['warp']:.0f}" if "warp" in med else "-"
            warp_ratio = f"{med['warp'] / med['gwn-solid']:.1f}x" if "warp" in med else "-"
            print(f"| {name} | {n} | {med['gwn-solid']:.0f} ({statistics.median(kernel) * 1e3:.0f}) | "
                  f"{med['igl']:.0f} | {warp} | {med['igl'] / med['gwn-solid']:.1f}x | {warp_ratio} | "
                  f"{int(ref.sum()):,} | {' / '.join(differ)} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
