"""Table 3 of Schwarz & Seidel 2010 on this machine: ss-octree's sparse solid
voxelization, time per stage (GPU ms, warm, median of repeats), share of
stored level-0 nodes and octree size, per model and binary grid size.

    python compare/table3_ss_octree.py [--sizes 512 1024 2048 4096] [--repeat 3]
                                       [--meshes stanford_bunny_bun_zipper.ply ...] [--no-walls]

Rows as in the paper (the scalar-valued grid is the level-0 coverage, a
quarter of the binary resolution); below them glvox's extras: wall-clock
total, transform and readback, the octree against the dense bit grid, the
nodes per level, the walls and the active level-1 nodes.  Sizes are MiB
(2^20 bytes) of the node arrays as stored (Morton codes and child, parent
and x-neighbour pointers as uint32, 8 bytes of sub-grid per level-0 node, a
byte of inside flag per node above), not counting the coverage counts.

The bunny and the dragons are open meshes (the paper used them anyway): they
run with allow_open, and by default with walls (the octree then decodes to
ss-solid's parity result; --no-walls gives the paper's algorithm and fewer
nodes).  Meshes are paths or names in GLVOX_MESHES (default ../shared/meshes
beside the checkout).  Prints a markdown table; beside each glvox column of
a mesh that stands for one of the paper's models (glvox.study.paper_figures)
at one of its sizes, the paper's column (Schwarz & Seidel 2010 on the GTX
285; its sizes in MB, glvox's in MiB; its rows only).
"""

from __future__ import annotations

import argparse
import sys
import warnings

import glvox
from glvox.errors import NotWatertightWarning
from glvox.gl.context import get_context
from glvox.study.harness import timed
from glvox.datasets import resolve_mesh
from glvox.study.paper_figures import SS_GPU, SS_TABLE3, SS_TABLE3_SIZES, fmt, ss_model

DEFAULT_MESHES = ["stanford_bunny_bun_zipper.ply", "stanford_dragon_vrip_res2.ply",
                  "stanford_armadillo_libigl_86k.obj"]
STAGES = [("Determine active level-1 nodes", "active nodes"), ("Construct octree", "construct"),
          ("Voxelize into octree", "voxelize"), ("Propagate inside/outside", "propagate"),
          ("Compute coverage factor", "coverage")]


def paper_column(name: str, n: int) -> dict[str, str] | None:
    """The paper's Table 3 column (row label -> cell) for the model the shared mesh ``name``
    stands for at ``n``^3, or None."""
    model = ss_model(name)
    if model is None or n not in SS_TABLE3_SIZES or model not in SS_TABLE3["Total (the five stages)"]:
        return None
    i = SS_TABLE3_SIZES.index(n)
    col = {"Scalar-valued grid size": f"{n // 4}^3"}
    for row, models in SS_TABLE3.items():
        v = models[model][i]
        col[row] = f"{v:.2f}%" if row == "Stored level-0 nodes" else f"{v} MB" if row == "Octree size" else fmt(v)
    return col


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[512, 1024, 2048, 4096])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--meshes", nargs="+", default=DEFAULT_MESHES)
    ap.add_argument("--no-walls", action="store_true", help="the paper's algorithm on open meshes")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", NotWatertightWarning)
    ctx = get_context()
    cols, rows = [], {}

    def put(row, value):
        rows.setdefault(row, []).append(value)

    for name in args.meshes:
        mesh = glvox.load_mesh(resolve_mesh(name))
        for n in args.sizes:
            spec = glvox.grid_for(mesh, n)
            t = timed("ss-octree", mesh, spec, args.repeat, allow_open=True, walls=not args.no_walls)
            wall, stage, o = t.wall_ms, t.stages_ms, t.result
            mem, st = o.memory(), o.run.stats
            cols.append(f"{name.split('.')[0]} {n}^3")
            put("Scalar-valued grid size", f"{-(-n // 4)}^3")
            put("Total (the five stages)", f"{sum(stage[s] for _, s in STAGES):.1f}")
            for label, s in STAGES:
                put(label, f"{stage[s]:.1f}")
            put("Stored level-0 nodes", f"{mem['level0_percent']:.2f}%")
            put("Octree size", f"{mem['total'] / 2**20:.1f} MiB")
            put("wall clock, whole run", f"{wall:.1f}")
            put("transform / readback", f"{stage['transform']:.1f} / {stage['readback']:.1f}")
            put("dense bit grid", f"{mem['dense'] / 2**20:.0f} MiB ({mem['percent_of_dense']:.1f}% of it)")
            put("active level-1 nodes", f"{st['active_level1_nodes']:,}")
            put("nodes per level (0..top)", " / ".join(f"{k:,}" for k in mem["nodes"]))
            put("walls (open boundary edges)", f"{st['walls']}")
            print(f"<!-- done {cols[-1]}: {wall:.0f} ms -->", file=sys.stderr, flush=True)
            paper = paper_column(name, n)
            if paper is not None:
                cols.append(f"paper: {ss_model(name)} {n}^3")
                for row in rows:
                    put(row, paper.get(row, "-"))
    print(f"<!-- glvox: {ctx.renderer}; {ctx.version}; GPU ms (timestamp queries), median of {args.repeat} warm "
          f"runs; walls {'off' if args.no_walls else 'on'}. paper columns: Schwarz & Seidel 2010 Table 3, "
          f"{SS_GPU}, ms -->")
    print("| | " + " | ".join(cols) + " |")
    print("|---" * (len(cols) + 1) + "|")
    for row, vals in rows.items():
        print(f"| {row} | " + " | ".join(vals) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
