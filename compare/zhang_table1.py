"""Zhang et al. 2018 experiments: Table 1 (operation counts), Table 3 (voxel counts), timings.

Table 1 (default): an equilateral triangle voxelized at 32^3, rotated about y
and about z in 15 degree steps; the comparisons and additions of the
instrumented CPU scanline implementation (:func:`glvox.reference.scanline.scanline_surface`
with ``counts=``) next to those of the Schwarz & Seidel triangle/box test,
counted here the way the paper counts them, and the paper's numbers.

    python compare/zhang_table1.py                      # Table 1
    python compare/zhang_table1.py --counts -r 256      # Table 3: ILV vs conservative (and ILV's lattice surface)
    python compare/zhang_table1.py --timing -r 128,256,512 --meshes stanford_bunny_bun_zipper.ply

Units (the paper's, Sec. 5): an S&S sub-test (one edge function of a 2D
projection) is 1 comparison and 2 additions (and 2 multiplications, not
counted); a scanline voxel step is k - 1 comparisons and k additions for k
moving axes (2D: 1 and 2), an Eq. 9 end candidate 3 comparisons and 1
addition.  Set-up (normals, sorting, products) is counted for neither.

The paper does not give the triangle's size or position; here it is
inscribed in the grid: circumradius :data:`RADIUS` voxels around the grid
center, in the yz plane at 0 degrees (x = 16.5, inside one voxel slab, so
S&S takes its 2D path as the paper's 0 degree row implies), one vertex
along (0, 1, 1), so that its rotations about y and about z are mirror images
of each other (the paper's "Ours" columns are identical for y and z).  The
S&S count follows the specialized test of S&S Sec. 3.2: bounding-box voxels
whose box meets the triangle's bounding box; a box one voxel thick along one
axis is the 2D case (3 edge tests per voxel, stopping at the first that
fails), one voxel thick along two axes the 1D case (no test); otherwise, per
column along the dominant axis, 3 edge tests in the dominant plane, then for
each voxel of the column range the plane can reach, the 6 edge tests of the
other two planes (stopping at the first failure).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from glvox.reference import conservative_surface  # noqa: E402
from glvox.reference.scanline import OpCounts, scanline_surface  # noqa: E402

N = 32
RADIUS = 15.0
CENTER = np.array([16.5, 16.5, 16.5])
ANGLES = (0, 15, 30, 45, 60, 75, 90)

#: Table 1 of the paper: (comparisons, additions) of SS10, Pan11, Ours per angle.
PAPER = {
    "y": {0: ((2483, 4966), (0, 0), (838, 1111)), 15: ((6356, 12712), (3806, 7612), (863, 1236)),
          30: ((8177, 16354), (5343, 10686), (1061, 1687)), 45: ((7835, 15666), (5523, 11046), (1027, 1744)),
          60: ((8151, 16302), (5246, 10492), (1068, 1701)), 75: ((6357, 12750), (3786, 7572), (863, 1236)),
          90: ((2483, 4966), (0, 0), (839, 1113))},
    "z": {0: ((2483, 4966), (0, 0), (838, 1111)), 15: ((5899, 11798), (3490, 6980), (863, 1236)),
          30: ((6204, 12408), (3940, 7880), (1061, 1687)), 45: ((8162, 16324), (5358, 10716), (1027, 1744)),
          60: ((6204, 12408), (3988, 7976), (1068, 1701)), 75: ((5899, 11798), (3502, 7004), (863, 1236)),
          90: ((2483, 4966), (0, 0), (839, 1113))},
}


def triangle(axis: str, degrees: float) -> np.ndarray:
    """The test triangle (3, 3) in voxel space, rotated about ``axis`` through the grid center."""
    u = np.array([0.0, 1.0, 1.0]) / math.sqrt(2.0)   # first vertex direction, in the yz plane
    v = np.array([0.0, -1.0, 1.0]) / math.sqrt(2.0)
    pts = [RADIUS * (math.cos(a) * u + math.sin(a) * v) for a in (0.0, 2 * math.pi / 3, 4 * math.pi / 3)]
    t = math.radians(degrees)
    c, s = math.cos(t), math.sin(t)
    R = {"y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
         "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]
    return np.array([CENTER + R @ p for p in pts])


# ----------------------------------------------------------------------------
# Schwarz & Seidel, instrumented

_PLANES = ((1, 2, 0), (2, 0, 1), (0, 1, 2))  # (a, b, normal axis) of the yz, zx, xy projections


def _edges(tri: np.ndarray, n: np.ndarray, plane) -> list[tuple[float, float, float]]:
    """The three edge functions (n_a, n_b, d) of the projection, conservative offsets (S&S Eq. 2-3)."""
    a, b, w = plane
    sgn = 1.0 if n[w] >= 0 else -1.0
    out = []
    for i in range(3):
        e = tri[(i + 1) % 3] - tri[i]
        na, nb = -e[b] * sgn, e[a] * sgn
        d = -(na * tri[i][a] + nb * tri[i][b]) + max(0.0, na) + max(0.0, nb)
        out.append((na, nb, d))
    return out


def ss_counts(tri: np.ndarray, dims=(N, N, N)) -> tuple[int, int]:
    """Sub-tests of the specialized S&S test on one triangle: (comparisons, additions)."""
    n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    lo = np.maximum(np.floor(tri.min(0)).astype(int), 0)
    hi = np.minimum(np.floor(tri.max(0)).astype(int), np.asarray(dims) - 1)
    thick = hi - lo + 1
    tests = 0

    def passes(fs, p, q):
        nonlocal tests
        for na, nb, d in fs:
            tests += 1
            if na * p + nb * q + d < 0.0:
                return False
        return True

    if (thick == 1).sum() >= 2:  # 1D: every bounding-box voxel, no test
        return 0, 0
    if (thick == 1).sum() == 1:  # 2D: the projection along the thin axis only
        w = int(np.argmax(thick == 1))
        plane = [p for p in _PLANES if p[2] == w][0]
        fs = _edges(tri, n, plane)
        a, b, _ = plane
        for i in range(lo[a], hi[a] + 1):
            for j in range(lo[b], hi[b] + 1):
                passes(fs, i, j)
        return tests, 2 * tests
    w = int(np.argmax(np.abs(n)))
    plane = [p for p in _PLANES if p[2] == w][0]
    others = [p for p in _PLANES if p[2] != w]
    fs = _edges(tri, n, plane)
    f_other = [_edges(tri, n, p) for p in others]
    a, b, _ = plane
    for i in range(lo[a], hi[a] + 1):
        for j in range(lo[b], hi[b] + 1):
            if not passes(fs, i, j):
                continue
            # the plane's w over the column's square, and the voxels it reaches
            ws = [tri[0][w] - (n[a] * (x - tri[0][a]) + n[b] * (y - tri[0][b])) / n[w]
                  for x in (i, i + 1) for y in (j, j + 1)]
            k0 = max(lo[w], math.floor(min(ws)))
            k1 = min(hi[w], math.floor(max(ws)))
            for k in range(k0, k1 + 1):
                v = {a: i, b: j, w: k}
                ok = True
                for (pa, pb, _), f in zip(others, f_other):
                    if not passes(f, v[pa], v[pb]):
                        ok = False
                        break
    return tests, 2 * tests


def table1() -> None:
    print(f"Table 1: equilateral triangle (circumradius {RADIUS} voxels) at {N}^3; "
          "comparisons / additions")
    print("paper = Zhang et al. 2018 Table 1 (triangle size unknown); here = this script\n")
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
    folder = Path(os.environ.get("GLVOX_MESHES", ROOT.parent / "shared" / "meshes"))
    if arg:
        return [folder / m for m in arg.split(",")]
    sys.path.insert(0, str(ROOT / "tests"))
    from conftest import SHARED_MESHES
    return [folder / m for m in SHARED_MESHES]


#: Shift of the lattice surface for its conservative count: small and generic,
#: so that no voxel is only touched (as for RLV on a generic mesh).
LATTICE_SHIFT = np.array([1e-3, 1e-6, 1e-9])


def table3(resolutions, meshes) -> None:
    """Voxel counts; "lattice" is the conservative count of ILV's lattice surface
    (every vertex moved to its voxel's centre, Alg. 1 GetVoxel), the part of
    ILV's error that no scanline strategy can avoid."""
    import glvox
    from glvox.methods import run_method
    from glvox.methods.scanline import gpu_voxel_coords
    from glvox.reference.scanline import lattice_points

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


def timing(resolutions, meshes, repeats: int) -> None:
    import glvox
    from glvox.gl.context import get_context
    from glvox.methods import method_names, run_method

    methods = [m for m in ("ss-conservative", "scanline-rlv", "scanline-slv", "scanline-ilv")
               if m in method_names()]
    print(f"GPU time (sum of timer-query stages, best of {repeats} warm runs), ms; {get_context().renderer}")
    print(f"{'mesh':<32} {'res':>5} " + " ".join(f"{m:>16}" for m in methods))
    for path in meshes:
        mesh = glvox.load_mesh(path)
        for res in resolutions:
            spec = glvox.grid_for(mesh, res)
            row = []
            for m in methods:
                run_method(m, mesh, spec)  # cold: compile and upload
                best = min(run_method(m, mesh, spec).run.timings.gpu_s for _ in range(repeats))
                row.append(f"{best * 1e3:>16.1f}")
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
