"""Which voxels gwn-solid leaves to its per-voxel tree walk, and what would decide them.

    python compare/gwn_far_voxels.py --mesh messy_teapot_newell.obj -r 128
    python compare/gwn_far_voxels.py --mesh stanford_bunny_bun_zipper.ply -r 256 --sample 6000

On an open mesh the ``far`` stage (``shaders/gwn/field.comp``: the cluster tree
walked per row segment) takes more of a ``gwn-solid`` call than any other
(docs/methods/gwn.md).  It walks the blocks of 4 voxels that neither the caps'
bound, nor a brick's zeroth- or first-order record of F decided in the row
pass.  This script runs ``gwn-solid`` once, reads the segments the row pass
listed for the walk and the records of their bricks, and prints:

* the walked blocks by their brick's record: ``0`` F's bound over the brick was
  too loose there, ``2`` the -x split's was, ``1`` no such bound holds
  (boundary strips enter the brick along +x and along -x);
* for a sample of the walked voxels, the exact winding number (the direct sum,
  ``glvox.reference.winding.winding_direct``) and its distance from the
  threshold: near the threshold the walk is the work the voxel needs, far from
  it the bounds were too weak;
* ``|w_K|`` there, the winding number of the fans that close the boundary loops
  (``glvox.methods.gwn.caps``: ``w = C + C_K - w_K``, ``C + C_K`` an integer);
* the share of the walked voxels that a first-order record of ``w_K`` over
  cells of 8^3, 4^3 and 2^3 voxels would decide, in cells that no fan triangle
  and no loop edge enters (``w_K`` is smooth there, wherever the strips are):
  exact ``w_K`` at the cell's center, its gradient by central differences, and
  the second-derivative bound of ``gwn/bricks.comp`` (``min(2 l / g^3, 4 / g^2)
  / (4 pi)`` per loop edge of length ``l`` at distance ``g``).  An estimate
  (the gradient is numerical), not a proof: what such a record could be worth;
* the share of the walked blocks that the caps' own bound (``caps_decide`` of
  ``shaders/gwn/caps.glsl``, modelled in float64 by :func:`caps_bound`) would
  decide over the ball of a block's 4 voxel centers, and over that of its cell
  of 4^3 voxels: what testing the caps at those scales could decide, before
  its cost.

The passes keep their buffers for the last slab only, so the grid must run in
one slab (up to 256^3 on llvmpipe); the bricks must be on (an open mesh, a
field part of 200,000 voxels or more, boundary strips leaving at least half
of the brick columns free).
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import warnings

import numpy as np

import glvox
from glvox.grid import grid_for
from glvox.methods import run_method
from glvox.methods.gwn import field as gwn_field
from glvox.methods.gwn.caps import cap_margin, capped_mesh
from glvox.methods.gwn.plan import BRICK, SEGV
from glvox.methods.gwn.tree import boundary_loops
from glvox.reference.attributes import closest_points
from glvox.reference.winding import winding_direct
from glvox.tolerances import WINDING_TIE

CELLS = (8, 4, 2)


@contextlib.contextmanager
def captured_walk():
    """While open, records the part of the slab gwn-solid's walk covers (``box``,
    ``segs``) and the run's passes (``run``) as the run lists the walk's segments."""
    seen: dict = {}
    listed = gwn_field._Run._list_todo

    def spy(self, box, segs):
        seen.update(box=box, segs=segs, run=self)
        return listed(self, box, segs)

    gwn_field._Run._list_todo = spy
    try:
        yield seen
    finally:
        gwn_field._Run._list_todo = listed


def walked_blocks(run, box, segs, spec) -> tuple[np.ndarray, np.ndarray]:
    """The blocks the walk took: (B, 3) int64 first voxel (x, y, z) of each, and
    (B,) the record kind (``w`` of gwn/bricks.glsl) of its brick."""
    n = int(np.frombuffer(run.count.read(size=12), "<u4")[2])
    todo = np.frombuffer(run.pool._bufs["todo"].read(size=n * 8), "<u4").reshape(-1, 2).astype(np.int64)
    j0, nj, k0, nk = box
    rows = nj * nk
    ids, masks = todo[:, 0], todo[:, 1]
    j, k, seg = j0 + ids % rows % nj, k0 + ids % rows // nj, segs[0] + ids // rows
    bit = (masks[:, None] >> np.arange(SEGV)[None]) & 1
    which, block = np.nonzero(bit)
    first = np.stack([seg[which] * 4 * SEGV + 4 * block, j[which], k[which]], axis=1)
    first = first[first[:, 0] < spec.dims[0]]
    nbx, nby = -(-32 * spec.words_per_row // BRICK), -(-spec.dims[1] // BRICK)
    recs = np.frombuffer(run.pool._bufs["bricks"].read(), "<f4").reshape(-1, 8)
    b = first // BRICK
    kind = recs[(b[:, 2] * nby + b[:, 1]) * nbx + b[:, 0], 3].astype(int)
    return first, kind


def segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(M,) distances from the points ``p`` to the segments ``a b``, all (M, 3)."""
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


def pairwise(dist_fn, centers: np.ndarray, items: np.ndarray) -> np.ndarray:
    """(C, I) distances from each center to each item, by ``dist_fn`` on the pairs."""
    c = np.repeat(centers, len(items), axis=0)
    it = np.tile(items, (len(centers),) + (1,) * (items.ndim - 1))
    return dist_fn(c, it).reshape(len(centers), len(items))


def first_order_share(points, closed, fans, edges, threshold, size) -> tuple[float, float]:
    """(share of the cells free of fans and loop edges, share of ``points`` a
    first-order record of w_K over cells of ``size``^3 voxels decides)."""
    key = np.floor(points / size).astype(np.int64)
    cells, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inv = inv.ravel()
    center = cells * size + 0.5 * size
    r = 0.5 * np.sqrt(3.0) * size  # the ball around the cell
    to_fans = pairwise(lambda c, t: closest_points(t, c)[0], center, fans).min(axis=1) - r
    to_edges = pairwise(lambda c, e: segment_distance(c, e[:, 0], e[:, 1]), center, edges) - r
    free = (to_fans > 0.0) & (to_edges > 0.0).all(axis=1)
    g = np.where(to_edges > 0.0, to_edges, np.inf)
    length = np.linalg.norm(edges[:, 1] - edges[:, 0], axis=1)
    second = np.minimum(2.0 * length / g ** 3, 4.0 / g ** 2).sum(axis=1) / (4.0 * np.pi)
    wk = winding_direct(fans, center)
    h = 1e-3
    grad = np.stack([(winding_direct(fans, center + h * e) - winding_direct(fans, center - h * e)) / (2.0 * h)
                     for e in np.eye(3)], axis=1)
    d = points - center[inv]
    estimate = closed - (wk[inv] + np.einsum("ij,ij->i", grad[inv], d))
    bound = 0.5 * second[inv] * np.einsum("ij,ij->i", d, d) + 1e-4
    decided = free[inv] & (np.abs(estimate - threshold) > bound)
    return float(free.mean()), float(decided.mean())


def caps_bound(p0: np.ndarray, hd: float, vox: np.ndarray, capped) -> np.ndarray:
    """The bound of ``shaders/gwn/caps.glsl``'s ``caps_decide`` on ``|Omega_K|``
    (steradians) over the balls of radius ``hd`` about the points ``p0`` ((P, 3),
    voxel space), in float64 and without its float32 margins: per fan the least
    of the sum over its triangles of ``min(A / d^2, 2 pi)`` and, where no
    triangle and no loop edge comes within ``hd``, ``|Omega(p0)| + hd`` times
    the Biot-Savart bound over its loop; or the fans clear of the ball with
    their solid angles summed with their signs.  ``vox``: the capped mesh's
    vertices in voxel space."""
    each, signed_rest, omega_all = (np.zeros(len(p0)) for _ in range(3))
    start = capped.first
    for loop in capped.loops:
        t = vox[capped.mesh.faces[start:start + len(loop)]]  # (w_{i+1}, w_i, apex): (a, b) the loop's edge
        start += len(loop)
        a, b, c = t[:, 0], t[:, 1], t[:, 2]
        area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
        dt = pairwise(lambda q, tri: closest_points(tri, q)[0], p0, t) - hd
        crude = np.where(dt > 0.0, np.minimum(area / np.where(dt > 0.0, dt, 1.0) ** 2, 2.0 * np.pi), 2.0 * np.pi)
        g = pairwise(lambda q, e: segment_distance(q, e[:, 0], e[:, 1]), p0, np.stack([a, b], axis=1)) - hd
        apart = (dt > 0.0).all(axis=1) & (g > 0.0).all(axis=1)
        gs = np.where(g > 0.0, g, 1.0)
        grad = np.minimum(np.linalg.norm(b - a, axis=1) / gs ** 2, 4.0 / gs).sum(axis=1)
        omega = 4.0 * np.pi * winding_direct(t, p0)
        each += np.where(apart, np.minimum(crude.sum(axis=1), np.abs(omega) + grad * hd), crude.sum(axis=1))
        signed_rest += np.where(apart, grad * hd, crude.sum(axis=1))
        omega_all += np.where(apart, omega, 0.0)
    return np.minimum(each, signed_rest + np.abs(omega_all))


def report(mesh, n: int, sample: int, threshold: float = 0.5, seed: int = 0) -> list[str]:
    spec = grid_for(mesh, n)
    with captured_walk() as seen, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        grid = run_method("gwn-solid", mesh, spec, threshold=threshold)
    stats = grid.run.stats
    if stats.get("slabs", 0) != 1 or "run" not in seen:
        raise SystemExit(f"gwn-solid ran {stats.get('slabs')} slabs with bricks {bool(stats.get('bricks'))} on "
                         f"{mesh.name} at {n}^3: this script needs one slab with bricks (an open mesh, a smaller "
                         "or larger grid)")
    blocks, kind = walked_blocks(seen["run"], seen["box"], seen["segs"], spec)
    lines = [f"gwn-solid on {mesh.name} at {n}^3: {stats['bricks']} bricks, "
             f"{stats.get('cap_bricks', 0)} decided by the caps; the walk took {stats['field_segments']} "
             f"segments, {len(blocks)} blocks of 4 voxels",
             "", "| brick record | walked blocks | share |", "|---|---|---|"]
    names = {0: "0: F's bound too loose", 2: "2: the -x split's too loose", 1: "1: strips along +x and -x"}
    for w in (0, 2, 1):
        lines.append(f"| {names[w]} | {int((kind == w).sum())} | {(kind == w).mean():.3f} |")
    vox = (blocks[:, None, :] + np.stack([np.arange(4), np.zeros(4, int), np.zeros(4, int)], 1)[None]).reshape(-1, 3)
    vox = vox[vox[:, 0] < spec.dims[0]]
    rng = np.random.default_rng(seed)
    if len(vox) > sample:
        vox = vox[np.sort(rng.choice(len(vox), sample, replace=False))]
    points = vox + 0.5
    tris = spec.world_to_voxel(mesh.vertices)[mesh.faces]
    w = winding_direct(tris, points)
    bits = grid.dense()[vox[:, 0], vox[:, 1], vox[:, 2]]
    agree = float(((w >= threshold) == bits).mean())
    near = np.abs(w - threshold)
    lines += ["", f"{len(vox)} of the walked voxels (sampled), exact w against gwn-solid's bits: "
              f"{agree:.4f} agree (the rest are ties)",
              "", "| distance of w from the threshold under | 0.05 | 0.1 | 0.2 | 0.3 |", "|---|---|---|---|---|",
              "| share of the walked voxels | "
              + " | ".join(f"{(near < t).mean():.3f}" for t in (0.05, 0.1, 0.2, 0.3)) + " |"]
    loops = boundary_loops(mesh)
    if not loops.n_edges:
        return lines
    capped = capped_mesh(mesh, loops)
    cv = spec.world_to_voxel(capped.mesh.vertices)
    fans = cv[capped.mesh.faces[capped.first:]]
    edges = np.concatenate([np.stack([cv[np.roll(loop, -1)], cv[loop]], axis=1) for loop in capped.loops])
    wk = winding_direct(fans, points)
    closed = np.rint(w + wk)  # C + C_K, an integer
    q = np.quantile(np.abs(wk), [0.25, 0.5, 0.75, 0.95])
    lines += ["", f"|w_K| of the caps there: quartiles {q[0]:.3f} / {q[1]:.3f} / {q[2]:.3f}, 95% {q[3]:.3f}; "
              f"C + C_K integer within {np.abs(w + wk - closed).max():.1e}",
              "", "| first-order record of w_K over cells of | cells free of fans and loop edges | "
              "walked voxels it decides |", "|---|---|---|"]
    for size in CELLS:
        free, decided = first_order_share(points, closed, fans, edges, threshold, size)
        lines.append(f"| {size}^3 | {free:.3f} | {decided:.3f} |")
    # the caps' own bound over a walked block's ball and over its 4^3 cell's
    limit = 4.0 * np.pi * cap_margin(threshold, WINDING_TIE)
    pick = blocks if len(blocks) <= sample else blocks[np.sort(rng.choice(len(blocks), sample, replace=False))]
    lines += ["", "| the caps' bound over the ball of | walked blocks it decides |", "|---|---|"]
    for label, centers, hd in (("a block's 4 voxel centers", pick + (2.0, 0.5, 0.5), 1.5),
                               ("its cell of 4^3 voxels", pick // 4 * 4 + 2.0, 1.5 * np.sqrt(3.0))):
        lines.append(f"| {label} | {(caps_bound(centers, hd, cv, capped) < limit).mean():.3f} |")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mesh", default="messy_teapot_newell.obj", help="a mesh file, a shared mesh's name or gen:NAME")
    ap.add_argument("-r", "--size", type=int, default=128)
    ap.add_argument("--sample", type=int, default=3000, help="walked voxels checked against the direct sums")
    args = ap.parse_args(argv)
    print("\n".join(report(glvox.load_mesh(args.mesh), args.size, args.sample)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
