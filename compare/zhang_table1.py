"""Zhang et al. 2018 experiments: Table 1 (operation counts), Table 3 (voxel counts), timings.

Table 1 (default): an equilateral triangle voxelized at 32^3, rotated about y
and about z in 15 degree steps; the comparisons and additions of the
instrumented CPU scanline implementation (:func:`glvox.reference.scanline.scanline_surface`
with ``counts=``) next to those of the Schwarz & Seidel triangle/box test,
counted here the way the paper counts them, and the paper's numbers.

    python compare/zhang_table1.py                      # Table 1
    python compare/zhang_table1.py --counts -r 256      # Table 3: ILV vs conservative (and ILV's lattice surface)
    python compare/zhang_table1.py --timing -r 128,256,512 --meshes stanford_bunny_bun_zipper.ply

The test triangle and the operation count of the S&S test (units, placement)
are :mod:`glvox.study.zhang`.  Meshes are names in GLVOX_MESHES (default
../shared/meshes beside the checkout; default: every shared mesh).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import glvox
from glvox.gl.context import get_context
from glvox.methods import method_names, run_method
from glvox.methods.scanline.voxelize import gpu_voxel_coords
from glvox.reference import conservative_surface
from glvox.reference.scanline import OpCounts, lattice_points, scanline_surface
from glvox.study.harness import timed
from glvox.datasets import SHARED_MESHES, resolve_mesh
from glvox.study.paper_figures import ZHANG_GPU, ZHANG_TABLE1, ZHANG_TABLE2_GPU
from glvox.study.zhang import ANGLES, RADIUS, N, ss_counts, triangle

#: Table 1 of the paper: (comparisons, additions) of SS10, Pan11, Ours per angle.
PAPER = ZHANG_TABLE1


def table1() -> None:
    print(f"Table 1: equilateral triangle (circumradius {RADIUS} voxels) at {N}^3; "
          "comparisons / additions")
    print("paper = Zhang et al. 2018 Table 1 (triangle size unknown); here = this script (CPU operation "
          "counts: no GPU)\n")
    head = (f"{'':>4} {'angle':>5} | {'SS10 paper':>15} {'SS10 here':>15} | {'Ours paper':>12} "
            f"{'ILV here':>12} {'RLV here':>12} | {'ILV voxels':>10} {'cons voxels':>11}")
    for axis in ("y", "z"):
        print(head)
        for deg in ANGLES:
            tri = triangle(axis, deg)
            ss = ss_counts(tri)
            ci, cr = OpCounts(), OpCounts()
            g = scanline_surface(tri[None], (N, N, N), "ilv", counts=ci)
            scanline_surface(tri[None], (N, N, N), "rlv", counts=cr)
            cons = conservative_surface(tri[None], (N, N, N))
            p_ss, _, p_ours = PAPER[axis][deg]
            print(f"{axis:>4} {deg:>5} | {p_ss[0]:>6} / {p_ss[1]:<6} {ss[0]:>6} / {ss[1]:<6} | "
                  f"{p_ours[0]:>5} / {p_ours[1]:<5} {ci.comparisons:>5} / {ci.additions:<5} "
                  f"{cr.comparisons:>5} / {cr.additions:<5} | {int(g.sum()):>10} {int(cons.sum()):>11}")
        print()


# ----------------------------------------------------------------------------
# Table 3 and timings (GPU methods; llvmpipe here)

def _meshes(arg: str | None) -> list[Path]:
    names = arg.split(",") if arg else SHARED_MESHES
    return [Path(resolve_mesh(m)) for m in names]


#: Shift of the lattice surface for its conservative count: small and generic,
#: so that no voxel is only touched (as for RLV on a generic mesh).
LATTICE_SHIFT = np.array([1e-3, 1e-6, 1e-9])


def table3(resolutions, meshes) -> None:
    """Voxel counts; "lattice" is the conservative count of ILV's lattice surface
    (every vertex moved to its voxel's centre, Alg. 1 GetVoxel), the part of
    ILV's error that no scanline strategy can avoid."""
    print("Table 3: voxel counts (scanline-ilv, scanline-rlv vs reference-conservative; "
          "lattice = conservative count of ILV's lattice surface)")
    print(f"{'mesh':<36} {'res':>5} {'conservative':>12} {'RLV':>10} {'ILV':>10} {'ILV err':>8} "
          f"{'lattice':>10} {'lat err':>8} {'ILV/lat':>8}")
    for path in meshes:
        mesh = glvox.load_mesh(path)
        for res in resolutions:
            spec = glvox.grid_for(mesh, res)
            cons = run_method("reference-conservative", mesh, spec).count
            rlv = run_method("scanline-rlv", mesh, spec).count
            ilv = run_method("scanline-ilv", mesh, spec).count
            lat_tris = lattice_points(gpu_voxel_coords(mesh, spec), spec.dims) + 0.5 + LATTICE_SHIFT
            lat = int(conservative_surface(lat_tris, spec.dims).sum())
            print(f"{path.name:<36} {res:>5} {cons:>12} {rlv:>10} {ilv:>10} {100 * (ilv - cons) / cons:>+7.2f}% "
                  f"{lat:>10} {100 * (lat - cons) / cons:>+7.2f}% {100 * (ilv - lat) / lat:>+7.2f}%", flush=True)


def paper_table2(resolutions) -> list[str]:
    """The GPU column of the paper's Table 2 at ``resolutions``: Pan11 (SAT-based, the
    ss-conservative column's kin) and the paper's integer scanline (scanline-ilv's)."""
    lines = [f"paper: Zhang et al. 2018 Table 2, GPU column, {ZHANG_GPU}, ms (Pan11 / Ours = ILV); "
             "their meshes, not the shared ones"]
    for model, rows in ZHANG_TABLE2_GPU.items():
        cells = [f"{rows[r][0]:>7} / {rows[r][1]:<7}" if r in rows else f"{'-':>17}" for r in resolutions]
        lines.append(f"{model:<32} " + " ".join(f"{r:>5}: {c}" for r, c in zip(resolutions, cells)))
    return lines


def timing(resolutions, meshes, repeats: int) -> None:
    methods = [m for m in ("ss-conservative", "scanline-rlv", "scanline-slv", "scanline-ilv")
               if m in method_names()]
    print("\n".join(paper_table2(resolutions)) + "\n")
    print(f"glvox: GPU time (sum of timer-query stages, best of {repeats} warm runs), ms; {get_context().renderer}")
    print(f"{'mesh':<32} {'res':>5} " + " ".join(f"{m:>16}" for m in methods))
    for path in meshes:
        mesh = glvox.load_mesh(path)
        for res in resolutions:
            spec = glvox.grid_for(mesh, res)
            row = []
            for m in methods:
                row.append(f"{timed(m, mesh, spec, repeats).gpu_min_ms:>16.1f}")
            print(f"{path.name:<32} {res:>5} " + " ".join(row), flush=True)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--counts", action="store_true", help="Table 3: ILV vs conservative voxel counts")
    p.add_argument("--timing", action="store_true", help="GPU times against ss-conservative")
    p.add_argument("-r", "--resolutions", default="256", help="comma-separated, e.g. 128,256,512")
    p.add_argument("--meshes", default=None, help="comma-separated shared mesh file names (default: all)")
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args(argv)
    res = [int(r) for r in a.resolutions.split(",")]
    t0 = time.perf_counter()
    if a.counts:
        table3(res, _meshes(a.meshes))
    elif a.timing:
        timing(res, _meshes(a.meshes), a.repeats)
    else:
        table1()
    print(f"({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
