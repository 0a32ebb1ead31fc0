"""What carrying attributes costs: ``ss-conservative`` with and without them.

For each mesh and size, interleaved warm rounds of the plain surface and the
surface with ``attributes=triangle,color,normal,material`` (vertex normals),
end to end as a user waits (``glvox.voxelize`` from the file: loading, the
visuals and texture decode for the attributed run, GPU work, readback, the
numpy arrays) and the GPU stage times alone (kernel: the sum of the stages'
GPU timer queries).  Memory: the attribute arrays' bytes per set voxel and
in all, and the attribute pass's GPU buffers.

Usage::

    python compare/attributes_cost.py                          # fuze and coloured reference, 128^3-1024^3
    python compare/attributes_cost.py --sizes 128 256 --repeat 5
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import glvox
from glvox.datasets import resolve_mesh
from glvox.gl.context import get_context
from glvox.gpu.buffers import buffer_pool

MESHES = ["textured_fuze.obj", "colored_reference.obj"]
ATTRS = "triangle,color,normal,material"


def _kernel_ms(result) -> float:
    return 1e3 * sum(s.gpu_s or 0.0 for s in result.run.timings.stages)


def _once(path, n, attrs):
    t0 = time.perf_counter()
    g = glvox.voxelize(path, n, attributes=attrs, normals="vertex" if attrs else "face")
    return 1e3 * (time.perf_counter() - t0), _kernel_ms(g), g


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--meshes", nargs="+", default=MESHES)
    ap.add_argument("--sizes", nargs="+", type=int, default=[128, 256, 512, 1024])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}; median of {args.repeat} interleaved warm runs "
          "(one warm-up each first)")
    print(f"{'mesh':22s} {'N':>5s} {'voxels':>9s} {'plain ms':>9s} {'attr ms':>9s} {'ratio':>6s} "
          f"{'plain gpu':>9s} {'attr gpu':>9s} {'ratio':>6s} {'attr MiB':>8s} {'GPU MiB':>8s}")
    for name in args.meshes:
        path = str(resolve_mesh(name))
        for n in args.sizes:
            buffer_pool(get_context(), "attributes").release()  # this cell's buffers only, below
            _once(path, n, None), _once(path, n, ATTRS)  # warm-up: shaders compiled, buffers pooled
            plain, attr = [], []
            for _ in range(args.repeat):
                plain.append(_once(path, n, None))
                attr.append(_once(path, n, ATTRS))
            g = attr[-1][2]
            wall_p, wall_a = (statistics.median(r[0] for r in rs) for rs in (plain, attr))
            gpu_p, gpu_a = (statistics.median(r[1] for r in rs) for rs in (plain, attr))
            attr_mib = sum(a.nbytes for a in g.attributes.values()) / 2**20
            gpu_mib = buffer_pool(get_context(), "attributes").nbytes / 2**20
            print(f"{name:22s} {n:5d} {g.count:9d} {wall_p:9.1f} {wall_a:9.1f} {wall_a / wall_p:6.2f} "
                  f"{gpu_p:9.1f} {gpu_a:9.1f} {gpu_a / gpu_p:6.2f} {attr_mib:8.1f} {gpu_mib:8.1f}", flush=True)


if __name__ == "__main__":
    main()
