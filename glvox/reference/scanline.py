"""Projected optimal scanline voxelization (Zhang et al. 2018), CPU implementation.

This is the exact CPU counterpart of ``shaders/scanline/voxelize.comp``: the
same algorithm, step for step, in Python scalars (which is why this module is
long: it mirrors the shader function by function, so the two can be read and
diffed side by side).  It serves as the reference
the GPU methods ``scanline-rlv``, ``scanline-slv`` and ``scanline-ilv`` are
checked against, and it counts comparisons and additions for the paper's
Table 1 (``compare/zhang_table1.py``).

Conventions: the paper's lattice and glvox's voxel space
---------------------------------------------------------
The paper puts grid points (voxel centers) on Z^3: voxel P = (X, Y, Z) is
the cube ``[X - 1/2, X + 1/2]^3`` and a point p lies in voxel
``floor(p + 1/2)`` (Sec. 4).  glvox's voxel (i, j, k) is ``[i, i+1] x
[j, j+1] x [k, k+1]`` (docs/design.md).  So paper coordinates are voxel-space
coordinates minus 1/2, and **voxel indices are the same numbers**: paper
``floor(x + 1/2)`` = glvox ``floor(x)``.  Consequently

- the paper's slicing planes ``Z_0 + i + 1/2`` are the integer planes
  ``w = k`` of voxel space (voxel faces);
- the paper's "grid point of P" (ILV's approximation of an end point) is the
  voxel center ``P + 1/2`` here; ILV works on the integer indices P only, so
  no half appears anywhere in the integer path;
- a point on a voxel face belongs to the voxel above it (``floor``), as in
  the paper.

Everything below works in voxel space on (T, 3, 3) triangles, like
:mod:`glvox.reference.surface`, and returns a dense (nx, ny, nz) bool grid.

Line voxelization (Sec. 4.1)
----------------------------
- **RLV** (:func:`rlv_line`): Amanatides-Woo stepping from ``floor(p)`` to
  ``floor(q)``, one axis per step; at a tie of step distances (the segment
  passes through a voxel edge or corner) the lowest axis index steps first.
  A 6-connected path.
- **SLV** (:func:`slv_line`): the super cover, every voxel whose closed box
  meets the segment.  The paper picks "all the voxels incident to the
  singular point"; here a point of the segment is *singular* when it lies on
  a voxel face that the segment does not cross there: on two or more faces at
  once (a voxel edge or corner), on a face plane the segment lies in, or an
  end point on a face.  All voxels incident to a singular point are taken,
  so SLV is exactly the set of voxels the closed segment touches.
- **ILV** (:func:`ilv_line`): Eq. 3-4 / Alg. 1 ``MarkLineILV`` on the
  integer end voxels, all arithmetic in integers.  Two details the paper's
  Alg. 1 leaves open are fixed: M over the *non-zero* deltas only (with a zero
  delta the paper's scale s = 2|dX||dY||dZ| is 0 and every L ties at 0, so
  Alg. 1 would step a constant axis forever; every 2D scanline has dZ = 0),
  and ties of L (the centre-to-centre segment passes a voxel edge or corner;
  the paper: "pick an arbitrary voxel candidate") follow one infinitesimal
  shift of the whole lattice (:func:`tie_order`: at a tie of axes i < j, i
  steps first iff it moves up).  So every line passes every voxel corner on
  the same side, whatever its direction, and the reverse of a line is its
  exact reverse.  (The first version stepped the lowest axis first from the
  lexicographically smaller end; lines meeting at a vertex then passed a
  corner on different sides, which cost up to 2.3 % more voxels on the dense
  scans, dragon res2 at 256^3.)

Triangle voxelization (Sec. 4.2, Alg. 1)
----------------------------------------
Per triangle: the three edges are line-voxelized (vertex voxels are their
end voxels); the dominant axis w of the normal (ties: z, then y, then x) is
the slicing axis, a and b = (w+1) % 3, (w+2) % 3 the other two; the triangle
is cut by the planes w = k into slices, each slice is scanned in 2D (fixed
layer k) by scanlines parallel to its base edges.

- **Float path (RLV, SLV).**  Base edges are iso-w lines of the triangle;
  their projections are parallel with in-plane normal g = (n_a, n_b).  The
  sweep coordinate is s = g . (p - p0) on the projection (computed from
  in-plane coordinates, which keeps it well conditioned for nearly flat
  triangles); the plane w = k is s = -n_w (k - w0).  Theorem 4.1 / Eq. 5
  bound the projected spacing by d^ = (|g_a| + |g_b|) / |g|, i.e. the
  s-spacing by |g_a| + |g_b|.  Each layer's s-range is cut into the fewest
  equal intervals no wider than :data:`SCANLINE_SLACK` times that bound
  (the paper steps by exactly d^ from one base edge; the count of scanlines
  is the same, the spacing is evened out and kept 0.1 % inside the bound so
  that float rounding cannot open a gap).  Each scanline runs from the long
  edge (lowest to highest s vertex) to the two short edges, and is
  line-voxelized in the slice's layer.  A triangle exactly parallel to the
  slicing plane (n_a = n_b = 0) is one slice scanned along a (g = (1, 0)).
  RLV slices layers ``floor(w_min) .. floor(w_max)``; SLV also the layer
  below a vertex or edge lying exactly on a plane w = k (it touches it).
  RLV takes the grid's maximum faces as part of its last voxels
  (:func:`cell`): with the papers' fit the mesh's extreme faces lie exactly
  there, and ``floor`` would give them to voxels outside the grid.
- **Integer path (ILV).**  The triangle is replaced by its lattice triangle
  (the end voxels P0, P1, P2, Alg. 1 ``GetVoxel``) and everything is integer:
  the dominant axis comes from the lattice normal (so CPU and GPU agree bit
  for bit); vertices are sorted on w (ties: lexicographic); the side-edge
  voxel chains V_A (P0 -> P2) and V_B (P0 -> P1 -> P2, joined, footnote 2)
  are cut per layer; the first scanline joins the first entries of V_A and
  V_B; the next ends are found by Eq. 8-9 (walk forward while the entry is
  within d^ of the current scanline, stop at the first entry that fails and
  keep the previous one); every scanline is an ILV line.  Two corrections
  make the integer scan a cover of its lattice triangle (without them ILV
  left 26-tunnels in 5 of 10 closed test meshes at 64^3-256^3):

  * Eq. 8 is used with the strict inequality,
    ``|dY X' - dX Y' - C0| < |dX| + |dY|`` (d < d^), and the first entry is
    always taken.  With d = d^ allowed, a voxel fits between two scanlines
    touching both at corners only (the equality case of Theorem 4.1), and
    lines between grid points pass exactly through voxel corners all the
    time, where ILV steps to one side only.  (A unit step off an
    axis-parallel scanline is exactly d^, hence the first entry.)
  * The walk along V_B may stop at P1 but not pass it in one go: the region
    between two consecutive scanlines is within d^ of the first only if the
    sides between their ends are straight, and V_B bends at P1 (a U-turn of
    the chain there let an end jump over a whole bulge of the slice).

  Boundary
  treatment: when one chain runs out first, the slice's top base edge
  (from its last entry to the other chain's last entry) becomes its new side
  edge.  If both chains end in the same voxel (a triangular slice) the paper
  stops, "because the entire triangle interior has been voxelized"; that
  fails when the independent end choices of Eq. 8 let the scanlines rotate
  (one end racing along an edge nearly parallel to the scanline): a flat
  triangle of circumradius 15 voxels lost a 100-voxel wedge.  Here the
  exhausted side stays at its last entry and the other chain goes on to its
  end, a fan whose consecutive scanlines are again within d^ of each other.
  Where the current scanline is a single voxel (A = B, at a slice that
  starts at a vertex) Eq. 6 is 0/0: each chain advances one entry.

  Base-edge ties: the base edges (bottom scanline on the plane w = Z, top one
  on w = Z + 1, also as the new side edge of the boundary treatment) join
  the centres of the chains' crossing voxels, and pass voxel edges wherever
  those columns are diagonal neighbours, i.e. all the time on small
  triangles.  There a base edge steps into the candidate voxel whose column
  centre has the lattice plane nearer its slicing plane (twice the plane
  equation, in integers; equal: the shift rule above): the side on which the
  lattice triangle really meets that plane.  With the shift rule alone a base edge
  took the other side half of the time, a voxel the triangle does not reach
  in that layer, in both copies: +2.2 % voxels on a 82k-triangle sphere at
  256^3, +0.6-1.2 % on the dense scans.
  The paper's line equation below Eq. 6 has a sign slip (``b = dX`` should be
  ``-dX``); the distance formula and Eq. 8 it derives are used as printed.

An edge shared by two triangles gets the same voxels in both, and the result
does not depend on vertex order: float edges are always traversed from their
lexicographically smaller end; an ILV line is the exact reverse of its
reverse (see :func:`tie_order`; a base edge's tie rule depends only on the two
candidate voxels).

Thinner variants (Sec. 5, Fig. 9): ``tunnel``
---------------------------------------------
Each base edge between layers k-1 and k is voxelized twice: as the top
scanline of slice k-1 (in layer k-1) and as the bottom scanline of slice k
(layer k).  That doubling makes the result 26-tunnel-free; the paper thins
it by "eliminating some base edge voxelizations" without saying which.

- ``tunnel=26``: both copies (the paper's method).
- Float path (RLV, SLV), where the base edge lies exactly on the plane w = k:
  ``tunnel=6`` drops the bottom copy (Sec. 5: "eliminate the voxelization of
  the base edge in either of the two slices"); ``tunnel=18`` keeps a voxel of
  the bottom copy unless both of its in-layer 4-neighbours on the slice side
  of the base edge lie on the base edge's own path (the path arrives by the
  step leaving that side and departs by the step towards it,
  :func:`drop_corners`): a dropped voxel is then only edge- or
  corner-adjacent to the rest of layer k, which 26-paths pass and 18-paths
  do not.
- Integer path (ILV), whose base edges join chain voxels' centres, half a
  voxel off the plane w = k: each column of a base edge keeps the copy in the
  layer where the lattice plane lies at the column's centre (exactly one:
  the naive, 6-separating digitization) for ``tunnel=6``, and for
  ``tunnel=18`` also the copy in the layer where it lies at the centre of a
  4-neighbouring column (so that 4-adjacent columns overlap), see
  :func:`_keep_copy`.  Dropping the whole bottom copy, as for the float
  path, left 6-tunnels through ILV surfaces.

Measured (tests/test_scanline.py): 26 is 26-tunnel-free, 18 is
18-tunnel-free, 6 is 6-tunnel-free, each a strict subset of the one before
on curved meshes (equal on faces parallel to a coordinate plane, which have
no base edges); for ILV with respect to its lattice surface.

ILV and the mesh itself
-----------------------
ILV voxelizes the lattice surface S' (every vertex moved to its voxel's
centre, by at most 1/2 voxel per axis; 1/2 + 1/64 for a vertex snapped in
from just outside the grid, :data:`ILV_BOUNDARY_SNAP`), not the mesh S, so
its guarantees are about S'.  Against S:

- Separation.  A voxel centre c inside S and outside S' is swept by the
  straight-line motion S -> S', so S' passes through the interior of c's
  voxel (within 1/2 (1 - t) < 1/2 per axis of c): a cover of S' that is
  26-tunnel-free w.r.t. S' is also 26-tunnel-free w.r.t. S.  ILV is close to
  such a cover but not one (it misses a few of the voxels S' enters, e.g.
  149 of 22172 on gen:torus at 96^3, where its base edges leave the true
  cross-section), so this is not a proof; measured, ILV (tunnel 26) is
  26-tunnel-free w.r.t. the mesh on every closed test mesh at 40^3-160^3 and
  on 90 random rotations of the generated closed meshes at 32^3-100^3.  (The
  version with the shift tie rule but without the base-edge rule leaked 2
  voxels on gen:torus at 96^3.)  The thin ``tunnel=6`` variant, a naive
  digitization of S', is *not* 6-tunnel-free w.r.t. the mesh: 1-5 inside
  voxels reachable in about a fifth of those random runs, all between S and
  S' (gen:torus and gen:bunny-like at 96^3).
- Voxel count.  Rounding the vertices roughens the surface: the conservative
  count of S' (shifted by a tiny generic vector, so that no voxel is only
  touched) exceeds that of S by up to 3 % on the dense scans at 256^3
  (buddha, tower), and ILV's count is within a few tenths of a percent of
  that count of S' (compare/zhang_table1.py --counts).  The paper's Table 3
  bound (ILV within 2.5 % of the cover) therefore cannot hold for meshes
  whose lattice surface alone is further off; see tests/test_scanline.py.

Bad input
---------
Zero-area triangles (or lattice triangles for ILV) are voxelized as their
edges.  Triangles whose bounding box misses the grid are skipped; RLV/SLV
lines are clipped to the grid grown by one voxel (the same voxels inside the
grid, bounded work); ILV lines are not clipped (clipping would move their
lattice end points) and ILV needs every voxel index of a triangle that
meets the grid within +/- :data:`ILV_COORD_LIMIT`, so that its integer
products fit in int32 on the GPU; :class:`glvox.errors.LimitError` otherwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Callable, Sequence

import numpy as np

from ..errors import LimitError
from ..tolerances import DECISION_RTOL, ILV_BOUNDARY_SNAP, RLV_BOUNDARY_SNAP, SCANLINE_SLACK, TIE_EPS
from ._candidates import check_dims, check_tris

MODES = ("rlv", "slv", "ilv")
TUNNELS = (26, 18, 6)

#: Largest |voxel index| of a vertex of an ILV triangle that meets the grid.
#: ILV's largest integers are L <= 2 M = 2 |dA| |dB| and the lattice normal's
#: components, both below 2 * (2 * limit)^2 = 2.048e9 < 2^31 at 16000.
ILV_COORD_LIMIT = 16000



@dataclass
class OpCounts:
    """Operation counts of an instrumented run (the paper's Table 1 units).

    Attributes
    ----------
    comparisons, additions : int
        Totals.  A line step over k moving axes costs k - 1 comparisons (the
        minimum of k step distances) and k additions (the voxel index and the
        k - 1 other step distances; the stepped one is reset, Alg. 1 l. 20-23;
        the paper's "2 additions plus 1 comparison" per 2D scanline voxel).
        An end-point candidate of Eq. 9 costs 3 comparisons and 1 addition
        (Sec. 4.2); a base edge's tie decision 1 comparison and 2 additions
        (the two plane heights, kept incrementally).  Setup (sorting,
        normals, products M) is not counted, as in the paper.
    line_steps, edge_steps, scanline_steps : int
        Voxel steps of all lines, of which triangle edges and scanlines.
    end_candidates : int
        Eq. 9 evaluations (ILV).
    base_ties : int
        Base-edge tie decisions (ILV).
    scanlines : int
        Scanlines voxelized (base edges included).
    """

    comparisons: int = 0
    additions: int = 0
    line_steps: int = 0
    edge_steps: int = 0
    scanline_steps: int = 0
    end_candidates: int = 0
    base_ties: int = 0
    scanlines: int = 0

    def line(self, steps: int, moving: int, edge: bool) -> None:
        self.line_steps += steps
        if edge:
            self.edge_steps += steps
        else:
            self.scanline_steps += steps
        self.comparisons += steps * max(moving - 1, 0)
        self.additions += steps * moving

    def candidates(self, n: int) -> None:
        self.end_candidates += n
        self.comparisons += 3 * n
        self.additions += n

    def base_tie(self) -> None:
        self.base_ties += 1
        self.comparisons += 1
        self.additions += 2


Cell = tuple  # (i, j, k) ints


# ----------------------------------------------------------------------------
# lines

def tie_order(d: Sequence[int]) -> list[int]:
    """ILV's order of the moving axes at a tie of step distances, for direction d.

    The axes that move up, lowest first, then those that move down, highest
    first.  That is how the centre-to-centre segment crosses a voxel edge or
    corner after an infinitesimal shift of the whole lattice by (e1, e2, e3),
    e1 >> e2 >> e3 > 0: a shift of +e_i makes every x_i-face crossing earlier
    where the segment moves up along axis i and later where it moves down.
    Pairwise: at a tie of axes i < j, i steps first iff it moves up.  One
    shift for every line makes all lines through a voxel corner pass it on the
    same side, whatever their direction, so that lines meeting at a vertex, and
    the two directions of one line, agree.
    """
    return [i for i in range(3) if d[i] > 0] + [i for i in (2, 1, 0) if d[i] < 0]


def ilv_line(p: Sequence[int], q: Sequence[int], counts: OpCounts | None = None,
             edge: bool = True, order: Sequence[int] | None = None,
             tie: Callable[[Cell, Cell], int] | None = None) -> list[Cell]:
    """Integer-only line voxelization (Eq. 3-4, Alg. 1 ``MarkLineILV``).

    Parameters
    ----------
    p, q : (3,) int
        End voxels.
    order : (3,) int, optional
        Tie order (axes, first steps first).  Default :func:`tie_order`, with
        which ``ilv_line(q, p)`` is the exact reverse of ``ilv_line(p, q)``.
    tie : callable, optional
        ``tie(c1, c2)`` decides a tie of two axes (the line passes a voxel
        edge): < 0 steps into c1 (the candidate of the axis ``order`` puts
        first), > 0 into c2, 0 leaves it to ``order``.  A rule that depends on
        the two candidates only, symmetrically, keeps reversal exact.

    Returns
    -------
    list of (3,) int tuples
        The voxels from p to q inclusive, a 6-connected path of
        ``sum |q - p| + 1`` voxels.
    """
    cur = [int(p[0]), int(p[1]), int(p[2])]
    d = [int(q[i]) - cur[i] for i in range(3)]
    ad = [abs(x) for x in d]
    act = [i for i in range(3) if ad[i]]
    out = [tuple(cur)]
    if not act:
        return out
    step = [1 if x > 0 else -1 for x in d]
    m2 = [0, 0, 0]
    L = [0, 0, 0]
    for i in act:
        m = 1
        for j in act:
            if j != i:
                m *= ad[j]
        L[i] = m
        m2[i] = 2 * m
    left = ad[:]
    order = tie_order(d) if order is None else [i for i in order if ad[i]]
    n = sum(ad)
    for _ in range(n):
        best = -1
        for i in order:
            if left[i] and (best < 0 or L[i] < L[best]):
                best = i
        if tie is not None:
            tied = [i for i in order if i != best and left[i] and L[i] == L[best]]
            if len(tied) == 1:
                o = tied[0]
                c1, c2 = list(cur), list(cur)
                c1[best] += step[best]
                c2[o] += step[o]
                if counts is not None:
                    counts.base_tie()
                if tie(tuple(c1), tuple(c2)) > 0:
                    best = o
        lm = L[best]
        for i in act:
            L[i] -= lm
        L[best] = m2[best]
        cur[best] += step[best]
        left[best] -= 1
        out.append((cur[0], cur[1], cur[2]))
    if counts is not None:
        counts.line(n, len(act), edge)
    return out


def _floor(x) -> int:
    return math.floor(x)


def _is_int(x) -> bool:
    return x == math.floor(x)


def clip_segment(p: Sequence, q: Sequence, lo: Sequence, hi: Sequence):
    """The part of segment p-q inside the closed box [lo, hi], or None if it misses it.

    Works on Python floats and Fractions alike; the end points are recomputed
    from the original p and q only where they are cut.

    Returns
    -------
    (p', q') : two (3,) lists, or None
    """
    t0, t1 = 0, 1
    for i in range(3):
        d = q[i] - p[i]
        if d == 0:
            if p[i] < lo[i] or p[i] > hi[i]:
                return None
            continue
        ta = (lo[i] - p[i]) / d
        tb = (hi[i] - p[i]) / d
        if ta > tb:
            ta, tb = tb, ta
        if ta > t0:
            t0 = ta
        if tb < t1:
            t1 = tb
    if t0 > t1:
        return None
    a = p if t0 == 0 else [p[i] + t0 * (q[i] - p[i]) for i in range(3)]
    b = q if t1 == 1 else [p[i] + t1 * (q[i] - p[i]) for i in range(3)]
    return a, b


def cell(x, n: int, snap) -> int:
    """The voxel index of coordinate x on an axis of n voxels: ``floor(x)``, except
    that x within ``snap`` outside the grid belongs to the boundary voxel.

    ``floor`` gives a point on a voxel face to the voxel above it (the paper's
    convention); on the grid's maximum face there is none, and a face of the
    mesh lying there (the papers' fit puts the mesh's extreme faces exactly
    there) would be lost to the grid.
    """
    if n <= x <= n + snap:
        return n - 1
    if -snap <= x < 0:
        return 0
    return math.floor(x)


def rlv_line(p: Sequence, q: Sequence, counts: OpCounts | None = None,
             edge: bool = True, dims: Sequence[int] | None = None) -> list[Cell]:
    """Regular line voxelization (Amanatides & Woo stepping, Sec. 4.1).

    Parameters
    ----------
    p, q : (3,) float or Fraction
        End points in voxel space.

    Returns
    -------
    list of (3,) int tuples
        From ``floor(p)`` to ``floor(q)``, one axis per step (lowest axis
        first at ties), ``sum |floor(q) - floor(p)| + 1`` voxels.  With
        ``dims``, :func:`cell` instead of ``floor`` (the grid's maximum faces
        belong to its last voxels).
    """
    if dims is None:
        cur = [_floor(p[0]), _floor(p[1]), _floor(p[2])]
        end = [_floor(q[0]), _floor(q[1]), _floor(q[2])]
    else:
        cur = [cell(p[i], dims[i], RLV_BOUNDARY_SNAP) for i in range(3)]
        end = [cell(q[i], dims[i], RLV_BOUNDARY_SNAP) for i in range(3)]
    left = [0, 0, 0]
    step = [0, 0, 0]
    v = [q[i] - p[i] for i in range(3)]
    for i in range(3):
        e = end[i] - cur[i]
        left[i] = abs(e)
        step[i] = 1 if e > 0 else -1
    out = [tuple(cur)]
    act = [i for i in range(3) if left[i]]
    n = sum(left)
    for _ in range(n):
        best = -1
        tb = None
        for i in act:
            if left[i]:
                bound = cur[i] + 1 if step[i] > 0 else cur[i]
                t = (bound - p[i]) / v[i]
                if best < 0 or t < tb:
                    best, tb = i, t
        cur[best] += step[best]
        left[best] -= 1
        out.append((cur[0], cur[1], cur[2]))
    if counts is not None:
        counts.line(n, len(act), edge)
    return out


def _incident(coord, is_int: bool) -> tuple:
    f = _floor(coord)
    return (f - 1, f) if is_int else (f,)


def slv_line(p: Sequence, q: Sequence, counts: OpCounts | None = None,
             edge: bool = True) -> set[Cell]:
    """Super-cover line voxelization: every voxel whose closed box meets segment p-q.

    The union of the voxels incident to the end points and to every point
    where the segment meets a voxel face plane; where several planes are met
    at once (a singular point, equal step distances) all incident voxels are
    taken.  Exact for Fraction input.

    Returns
    -------
    set of (3,) int tuples
    """
    out: set[Cell] = set()
    for e in (p, q):
        xs = [_incident(e[i], _is_int(e[i])) for i in range(3)]
        for x in xs[0]:
            for y in xs[1]:
                for z in xs[2]:
                    out.add((x, y, z))
    v = [q[i] - p[i] for i in range(3)]
    cur = [0, 0, 0]
    plane = [0, 0, 0]
    left = [0, 0, 0]
    step = [0, 0, 0]
    const: list[tuple] = [(), (), ()]
    for i in range(3):
        if v[i] > 0:
            cur[i] = _floor(p[i])
            plane[i] = cur[i] + 1
            last = math.ceil(q[i]) - 1
            left[i] = max(0, last - plane[i] + 1)
            step[i] = 1
        elif v[i] < 0:
            cur[i] = math.ceil(p[i]) - 1
            plane[i] = cur[i]
            last = _floor(q[i]) + 1
            left[i] = max(0, plane[i] - last + 1)
            step[i] = -1
        else:
            const[i] = _incident(p[i], _is_int(p[i]))
    act = [i for i in range(3) if left[i]]
    n = sum(left)
    events = 0
    while True:
        tmin = None
        for i in act:
            if left[i]:
                t = (plane[i] - p[i]) / v[i]
                if tmin is None or t < tmin:
                    tmin = t
        if tmin is None:
            break
        events += 1
        sets = []
        crossing = []
        for i in range(3):
            if step[i] == 0:
                sets.append(const[i])
            elif left[i] and (plane[i] - p[i]) / v[i] == tmin:
                crossing.append(i)
                sets.append((cur[i], cur[i] + step[i]))
            else:
                sets.append((cur[i],))
        for x in sets[0]:
            for y in sets[1]:
                for z in sets[2]:
                    out.add((x, y, z))
        for i in crossing:
            cur[i] += step[i]
            plane[i] += step[i]
            left[i] -= 1
    if counts is not None:
        counts.line(n, len(act), edge)
    return out


# ----------------------------------------------------------------------------
# helpers shared by both paths

def dominant_axis(n: Sequence) -> int:
    """Index of the largest |n| component; ties prefer z, then y, then x."""
    ax, ay, az = abs(n[0]), abs(n[1]), abs(n[2])
    if az >= ax and az >= ay:
        return 2
    if ay >= ax:
        return 1
    return 0


def _cross(u, v):
    return (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])


def side_values(da, db, h: tuple) -> tuple:
    """Values of a unit step along a and along b for a scanline of direction (da, db).

    The scanline's normal (-db, da), oriented to the side ``h`` (the in-plane
    direction of increasing w, where the slice lies beyond its bottom base
    edge); a step's value is its component along that normal.
    """
    pa, pb = -db, da
    if pa * h[0] + pb * h[1] < 0:
        pa, pb = -pa, -pb
    return pa, pb


def drop_corners(cells: list[Cell], a: int, b: int, pa, pb) -> list[Cell]:
    """The ``tunnel=18`` bottom base edge: drop the voxels whose two in-layer
    4-neighbours on the slice side both lie on the path itself.

    ``cells`` is a 4-connected path in one layer (steps along a or b only); a
    step along a (b) with sign s is worth ``pa * s`` (``pb * s``), see
    :func:`side_values`.  A voxel is dropped when the path arrives by a step of
    negative value (its predecessor is on the slice side) and leaves by one of
    positive value (so is its successor).  End voxels are kept.
    """
    if len(cells) < 3:
        return cells
    keep = [cells[0]]
    for i in range(1, len(cells) - 1):
        c, prev, nxt = cells[i], cells[i - 1], cells[i + 1]
        arr = pa * (c[a] - prev[a]) + pb * (c[b] - prev[b])
        dep = pa * (nxt[a] - c[a]) + pb * (nxt[b] - c[b])
        if not (arr < 0 < dep):
            keep.append(c)
    keep.append(cells[-1])
    return keep


def _skip(lo: Sequence, hi: Sequence, dims: Sequence[int]) -> bool:
    """True when the box [lo, hi] (voxel space) meets no voxel of the grid."""
    return any(hi[i] < 0 or lo[i] > dims[i] for i in range(3))


# ----------------------------------------------------------------------------
# float ties of the thin variants

@dataclass
class _TieRecorder:
    """Collects the voxels where two float runs of a scanline method may differ.

    ``eps``: distance (voxels) below which a line's point counts as on a voxel
    face; ``rel``: relative size below which a float decision (dominant axis,
    a triangle parallel to the slicing plane, the scanline count) counts as
    tied.
    """

    eps: float
    rel: float
    cells: list = field(default_factory=list)

    def box(self, ranges) -> None:
        for x in ranges[0]:
            for y in ranges[1]:
                for z in ranges[2]:
                    self.cells.append((x, y, z))

    def near_points(self, p, q) -> None:
        """Voxels around the points of segment p-q within eps of two face planes at
        once, and around its end points within eps of a face plane (the points
        where a traversal's choice can flip under rounding)."""
        eps = self.eps

        def near(c):
            r = round(c)
            return abs(c - r) <= eps, r

        def rng(c):
            ok, r = near(c)
            return (r - 1, r) if ok else (math.floor(c),)

        for e in (p, q):
            if any(near(e[i])[0] for i in range(3)):
                self.box([rng(e[i]) for i in range(3)])
        v = [q[i] - p[i] for i in range(3)]
        for i in range(3):
            if v[i] == 0:
                continue
            lo, hi = sorted((p[i], q[i]))
            for m in range(math.ceil(lo), math.floor(hi) + 1):
                t = (m - p[i]) / v[i]
                x = [p[j] + t * v[j] for j in range(3)]
                if any(near(x[j])[0] for j in range(3) if j != i):
                    ranges = [rng(x[j]) if j != i else (m - 1, m) for j in range(3)]
                    self.box(ranges)


# ----------------------------------------------------------------------------
# float path: RLV and SLV

def _float_triangle(P, dims, slv: bool, tunnel: int, mark: Callable, counts, half, slack,
                    rec: _TieRecorder | None = None):
    lo = [min(P[0][i], P[1][i], P[2][i]) for i in range(3)]
    hi = [max(P[0][i], P[1][i], P[2][i]) for i in range(3)]
    if _skip(lo, hi, dims):
        return
    box_lo = (-1, -1, -1)
    box_hi = (dims[0] + 1, dims[1] + 1, dims[2] + 1)

    def full(p, q, edge):
        c = clip_segment(p, q, box_lo, box_hi)
        if c is None:
            return None
        return slv_line(c[0], c[1], counts, edge) if slv else rlv_line(c[0], c[1], counts, edge, dims)

    def line(p, q, edge):
        cells = full(p, q, edge)
        if cells is not None:
            mark(cells)
            if rec is not None:
                rec.near_points(p, q)

    for i, j in ((0, 1), (1, 2), (2, 0)):
        p, q = (P[i], P[j]) if tuple(P[i]) <= tuple(P[j]) else (P[j], P[i])
        line(p, q, True)
    e1 = [P[1][i] - P[0][i] for i in range(3)]
    e2 = [P[2][i] - P[0][i] for i in range(3)]
    n = _cross(e1, e2)
    if n[0] == 0 and n[1] == 0 and n[2] == 0:
        return
    w = dominant_axis(n)
    a, b = (w + 1) % 3, (w + 2) % 3
    ga, gb = n[a], n[b]
    flat = ga == 0 and gb == 0
    tied_triangle = False
    if rec is not None:
        # rounding of the normal can change the dominant axis or flatness: the
        # whole slicing differs, so every voxel the triangle can set is tied
        size = rec.rel * max(abs(x) for x in e1) * max(abs(x) for x in e2) * 4
        m = sorted(abs(x) for x in n)
        tied_triangle = m[2] - m[1] <= size or (not flat and abs(ga) + abs(gb) <= size)
    if flat:
        ga, gb = ga + 1, gb  # keep the number type (Fraction or float)
    S = [ga * (P[i][a] - P[0][a]) + gb * (P[i][b] - P[0][b]) for i in range(3)]
    order = sorted(range(3), key=lambda i: (S[i], i))
    q0, q1, q2 = (P[i] for i in order)
    s0, s1, s2 = (S[i] for i in order)
    if s2 <= s0:
        return  # projection degenerate in float: the edges are all there is
    wmin, wmax = lo[w], hi[w]
    if slv:
        kfirst, klast = math.ceil(wmin) - 1, _floor(wmax)
    else:
        kfirst = cell(wmin, dims[w], RLV_BOUNDARY_SNAP)
        klast = cell(wmax, dims[w], RLV_BOUNDARY_SNAP)
    ds_max = (abs(ga) + abs(gb)) * slack
    nw, w0 = n[w], P[0][w]
    # in-plane direction of increasing w: the side where slice k lies beyond its bottom base
    h = (1, 0) if flat else ((-ga, -gb) if nw > 0 else (ga, gb))

    def clamp(s):
        return s0 if s < s0 else (s2 if s > s2 else s)

    def ends(s):
        t = (s - s0) / (s2 - s0)
        t = 0 if t < 0 else (1 if t > 1 else t)
        A = (q0[a] + t * (q2[a] - q0[a]), q0[b] + t * (q2[b] - q0[b]))
        if s < s1:
            t = (s - s0) / (s1 - s0)
            t = 0 if t < 0 else (1 if t > 1 else t)
            B = (q0[a] + t * (q1[a] - q0[a]), q0[b] + t * (q1[b] - q0[b]))
        else:
            t = 0 if s2 == s1 else (s - s1) / (s2 - s1)
            t = 0 if t < 0 else (1 if t > 1 else t)
            B = (q1[a] + t * (q2[a] - q1[a]), q1[b] + t * (q2[b] - q1[b]))
        return A, B

    tied_layers = set()
    if rec is not None and abs(wmin - round(wmin)) <= rec.eps:
        # which layer is first (and so keeps its bottom base edge) is tied
        tied_layers |= {round(wmin) - 1, round(wmin), round(wmin) + 1}
    for k in range(max(kfirst, 0), min(klast, dims[w] - 1) + 1):
        if flat:
            s_start, s_end = s0, s2
        else:
            s_start = clamp(-nw * (k - w0))
            s_end = clamp(-nw * (k + 1 - w0))
        span = s_end - s_start
        N = math.ceil(abs(span) / ds_max) if span != 0 else 0
        wk = k + half
        tied_layer = False
        if rec is not None:
            x = abs(span) / ds_max
            # the scanline count (and so every level of the layer) is tied
            tied_layer = (tied_triangle or k in tied_layers or x <= rec.rel
                          or (N > 0 and abs(x - round(x)) <= rec.rel * max(1.0, x)))
        for m in range(N + 1):
            base = m == 0 and k > kfirst and not flat
            if tied_layer and base and tunnel != 26:
                s = s_start
                A, B = ends(s)
                p, q = [0, 0, 0], [0, 0, 0]
                p[a], p[b], p[w] = A[0], A[1], wk
                q[a], q[b], q[w] = B[0], B[1], wk
                cells = full(p, q, False)
                if cells is not None:
                    rec.cells.extend(cells)
            if base and tunnel == 6:
                if rec is not None:
                    s = s_start
                    A, B = ends(s)
                    p, q = [0, 0, 0], [0, 0, 0]
                    p[a], p[b], p[w] = A[0], A[1], wk
                    q[a], q[b], q[w] = B[0], B[1], wk
                    rec.near_points(p, q)
                continue
            s = s_start if m == 0 else (s_end if m == N else s_start + span * m / N)
            A, B = ends(s)
            p = [0, 0, 0]
            q = [0, 0, 0]
            p[a], p[b], p[w] = A[0], A[1], wk
            q[a], q[b], q[w] = B[0], B[1], wk
            if counts is not None:
                counts.scanlines += 1
            if base and tunnel == 18:
                c = clip_segment(p, q, box_lo, box_hi)
                if c is not None:
                    pa, pb = side_values(B[0] - A[0], B[1] - A[1], h)
                    mark(drop_corners(rlv_line(c[0], c[1], counts, False, dims), a, b, pa, pb))
                    if rec is not None:
                        rec.near_points(p, q)
            else:
                line(p, q, False)
                if tied_layer:
                    cells = full(p, q, False)
                    if cells is not None:
                        rec.cells.extend(cells)


# ----------------------------------------------------------------------------
# integer path: ILV

def _path(p: Cell, q: Cell, counts, edge=True, tie=None) -> list[Cell]:
    """ILV voxels from p to q (the reverse of q -> p, see :func:`tie_order`)."""
    return ilv_line(p, q, counts=counts, edge=edge, tie=tie)


def _ilv_triangle(P, dims, tunnel: int, mark: Callable, counts):
    lo = [min(P[0][i], P[1][i], P[2][i]) for i in range(3)]
    hi = [max(P[0][i], P[1][i], P[2][i]) for i in range(3)]
    if any(hi[i] < 0 or lo[i] >= dims[i] for i in range(3)):
        return
    for i, j in ((0, 1), (1, 2), (2, 0)):
        mark(_path(P[i], P[j], counts))
    n = _cross([P[1][i] - P[0][i] for i in range(3)], [P[2][i] - P[0][i] for i in range(3)])
    if n == (0, 0, 0):
        return
    w = dominant_axis(n)
    a, b = (w + 1) % 3, (w + 2) % 3
    Q0, Q1, Q2 = sorted(P, key=lambda p: (p[w], p))
    # The chains repeat the edges' voxels (already marked and counted above);
    # the GPU walks them again too, so they are counted as edge steps again.
    chain_a = _path(Q0, Q2, counts)
    first_b = _path(Q0, Q1, counts)
    chain_b = first_b + _path(Q1, Q2, counts)[1:]
    corner = len(first_b) - 1  # index of P1 in V_B: a scanline must end there
    nw = n[w]

    def height(c, K):
        """2 n_w (h - K), h the lattice plane's w (through the voxel centres
        P + 1/2) at the centre of c's column: exact, in integers."""
        return 2 * (Q0[w] - K) * nw + nw - 2 * (n[a] * (c[a] - Q0[a]) + n[b] * (c[b] - Q0[b]))

    def above(c, K):
        """The lattice plane at the centre of c's column lies at w >= K."""
        e = height(c, K)
        return e >= 0 if nw > 0 else e <= 0

    def base_tie(K):
        """Tie rule of a base edge on the plane w = K (see :func:`_ilv_slice`)."""
        def tie(c1, c2):
            return abs(height(c1, K)) - abs(height(c2, K))
        return tie

    ia = ib = 0
    first = Q0[w]
    for Z in range(first, Q2[w] + 1):
        ja = ia
        while ja + 1 < len(chain_a) and chain_a[ja + 1][w] == Z:
            ja += 1
        jb = ib
        while jb + 1 < len(chain_b) and chain_b[jb + 1][w] == Z:
            jb += 1
        if 0 <= Z < dims[w]:
            _ilv_slice(chain_a[ia:ja + 1], chain_b[ib:jb + 1], a, b, corner - ib, Z,
                       Z > first, Z < Q2[w], tunnel, above, base_tie, dims, mark, counts)
        ia, ib = ja + 1, jb + 1


def _scanline(A: Cell, B: Cell, a: int, b: int, dims, counts, tie=None) -> list[Cell] | None:
    """ILV scanline A -> B, or None when all its voxels lie outside the grid's (a, b) rectangle."""
    if counts is not None:
        counts.scanlines += 1
    if (max(A[a], B[a]) < 0 or min(A[a], B[a]) >= dims[a]
            or max(A[b], B[b]) < 0 or min(A[b], B[b]) >= dims[b]):
        return None
    return _path(A, B, counts, edge=False, tie=tie)


def _keep_copy(c: Cell, K: int, bottom: bool, tunnel: int, above: Callable, a: int, b: int) -> bool:
    """ILV ``tunnel`` 18 / 6: keep this copy of a base-edge voxel?

    The base edge between layers K - 1 and K is drawn in both (``bottom``: the
    copy in layer K).  A copy is kept where the lattice plane, at the centre
    of the voxel's column, lies in its layer (``above(c, K)``: at w >= K), so
    each column keeps exactly one copy (the naive, 6-separating
    digitization); for 18 also where it lies in that layer at the centre of a
    4-neighbouring column, so that 4-adjacent columns overlap.
    """
    if above(c, K) == bottom:
        return True
    if tunnel != 18:
        return False
    for d in (-1, 1):
        for ax in (a, b):
            q = list(c)
            q[ax] += d
            if above(q, K) == bottom:
                return True
    return False


def _ilv_slice(VA, VB, a, b, corner: int, Z: int, has_below: bool, has_above: bool, tunnel: int,
               above: Callable, base_tie: Callable, dims, mark, counts):
    """Scan one slice (layer Z) of a lattice triangle: Eq. 8-9, boundary treatment.

    ``VA``, ``VB``: the chains' entries in layer Z.  The base edges (the
    bottom scanline, on the plane w = Z, and the top one, on w = Z + 1, also
    where it continues an exhausted chain) join chain voxels' centres, which
    pass voxel edges all the time; there ``base_tie`` steps into the
    candidate voxel whose column centre has the lattice plane nearest that
    slicing plane, i.e. towards where the triangle really meets it (the
    paper leaves ties free, Sec. 4.1).
    """
    A_last, B_last = VA[-1], VB[-1]
    A, B = VA[0], VB[0]
    bottom_tie, top_tie = base_tie(Z), base_tie(Z + 1)
    # bottom base edge: the second copy of the previous slice's top base edge
    cells = _scanline(A, B, a, b, dims, counts, bottom_tie)
    if cells is not None:
        if has_below and tunnel != 26:
            cells = [c for c in cells if _keep_copy(c, Z, True, tunnel, above, a, b)]
        mark(cells)
    last = (A, B)
    ca, cb = VA, VB
    ia = ib = 0
    while True:
        a_done = ia == len(ca) - 1
        b_done = ib == len(cb) - 1
        if a_done or b_done:
            if a_done and b_done:
                break
            # Boundary treatment: the top base edge becomes the exhausted chain's
            # continuation; where both chains end in the same voxel there is none
            # and the exhausted side stays put while the other one goes on (a fan).
            if a_done and ca[-1] != cb[-1]:
                ca = ca + _path(A_last, B_last, counts, edge=False, tie=top_tie)[1:]
            elif b_done and cb[-1] != ca[-1]:
                cb = cb + _path(B_last, A_last, counts, edge=False, tie=top_tie)[1:]
        A, B = ca[ia], cb[ib]
        if A == B:
            na = min(ia + 1, len(ca) - 1)
            nb = min(ib + 1, len(cb) - 1)
        else:
            dX = A[a] - B[a]
            dY = A[b] - B[b]
            c0 = dY * A[a] - dX * A[b]
            tol = abs(dX) + abs(dY)
            # Eq. 8 with d < d^ (strict), the first entry always taken; see the module docstring
            na, tried = ia, 0
            while na + 1 < len(ca):
                c = ca[na + 1]
                tried += 1
                if na == ia or abs(dY * c[a] - dX * c[b] - c0) < tol:
                    na += 1
                else:
                    break
            nb = ib
            # V_B bends at P1 (index `corner`): the walk may end there, not pass it
            stop = corner if ib < corner < len(VB) else len(cb) - 1
            while nb + 1 <= stop:
                c = cb[nb + 1]
                tried += 1
                if nb == ib or abs(dY * c[a] - dX * c[b] - c0) < tol:
                    nb += 1
                else:
                    break
            if counts is not None:
                counts.candidates(tried)
        ia, ib = na, nb
        last = (ca[ia], cb[ib])
        top = last == (A_last, B_last)
        cells = _scanline(ca[ia], cb[ib], a, b, dims, counts, top_tie if top else None)
        if cells is not None:
            if top and has_above and tunnel != 26:  # the top base edge
                cells = [c for c in cells if _keep_copy(c, Z + 1, False, tunnel, above, a, b)]
            mark(cells)
    if last != (A_last, B_last):
        cells = _scanline(A_last, B_last, a, b, dims, counts, top_tie)
        if cells is not None:
            if has_above and tunnel != 26:
                cells = [c for c in cells if _keep_copy(c, Z + 1, False, tunnel, above, a, b)]
            mark(cells)


# ----------------------------------------------------------------------------
# public entry points

def lattice_points(tris: np.ndarray, dims: Sequence[int]) -> np.ndarray:
    """ILV's end voxels of the vertices (Alg. 1 ``GetVoxel``), (T, 3, 3) int64.

    ``floor`` of the voxel-space coordinates, except that a coordinate within
    :data:`ILV_BOUNDARY_SNAP` voxel outside the grid (on or just beyond its
    faces) is snapped to the boundary voxel: with the papers' fit the extreme
    vertices lie exactly on the grid's maximum faces, where ``floor`` gives
    voxel n, outside the grid, and the lattice surface there would be clipped
    away.  Coordinates beyond the int64 range are clipped (such triangles are
    far outside any grid and skipped).
    """
    x = np.clip(np.asarray(tris, dtype=np.float64), -2.0**62, 2.0**62)
    P = np.floor(x).astype(np.int64)
    n = np.asarray(dims, dtype=np.int64)
    nf = n.astype(np.float64)
    P = np.where((x >= nf) & (x <= nf + ILV_BOUNDARY_SNAP), n - 1, P)
    P = np.where((x < 0.0) & (x >= -ILV_BOUNDARY_SNAP), 0, P)
    return P


def check_ilv_limits(tris: np.ndarray, dims: Sequence[int]) -> None:
    """Raise LimitError if an ILV triangle that meets the grid has a voxel index beyond the limit."""
    P = lattice_points(tris, dims)
    lo, hi = P.min(axis=1), P.max(axis=1)
    meets = np.all((hi >= 0) & (lo < np.asarray(dims)), axis=1)
    bad = meets & (np.abs(P).reshape(len(P), -1).max(axis=1) > ILV_COORD_LIMIT)
    if bad.any():
        first = int(np.argmax(bad))
        raise LimitError(
            f"scanline-ilv needs every vertex of a triangle that meets the grid within "
            f"{ILV_COORD_LIMIT} voxel indices of voxel 0 (int32 arithmetic), got {int(bad.sum())} "
            f"triangles beyond it (first: triangle {first}, voxel indices {P[first].tolist()}); "
            "use scanline-rlv / scanline-slv, or a grid closer to the mesh's extent"
        )


def scanline_surface(tris: np.ndarray, dims: Sequence[int], mode: str = "ilv", tunnel: int = 26,
                     *, exact: bool = False, counts: OpCounts | None = None) -> np.ndarray:
    """Surface voxelization by projected optimal scanlines (Zhang et al. 2018).

    Parameters
    ----------
    tris : (T, 3, 3) float
        Triangle vertices in voxel space (voxel (i, j, k) is the unit cube at
        (i, j, k)).  For a voxel-for-voxel comparison with the GPU, pass the
        vertices as the GPU computes them (float32, see
        ``glvox.methods.scanline.voxelize.gpu_voxel_coords``): ILV then agrees exactly.
    dims : (3,) int
        Grid size (nx, ny, nz); voxels outside are clipped.
    mode : {'rlv', 'slv', 'ilv'}
        Line voxelization (Sec. 4.1): float RLV, float super cover SLV,
        integer ILV.
    tunnel : {26, 18, 6}
        26: the paper's cover; 18, 6: thinner variants (Sec. 5), see the
        module docstring.
    exact : bool
        RLV / SLV in exact rational arithmetic (``fractions.Fraction`` of the
        float inputs) instead of float64: slow, for constructed test cases
        whose singular points float rounding would blur.
    counts : OpCounts, optional
        Filled with the comparisons and additions of the run.

    Returns
    -------
    (nx, ny, nz) bool
    """
    tris = check_tris(tris)
    dims = check_dims(dims)
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    if tunnel not in TUNNELS:
        raise ValueError(f"tunnel must be one of {TUNNELS}, got {tunnel!r}")
    cells: list = []
    extend = cells.extend

    def mark(cs):
        extend(cs)

    if mode == "ilv":
        check_ilv_limits(tris, dims)
        for tri in lattice_points(tris, dims).tolist():
            _ilv_triangle([tuple(v) for v in tri], dims, tunnel, mark, counts)
    else:
        slv = mode == "slv"
        if exact:
            half, slack = Fraction(1, 2), Fraction(SCANLINE_SLACK)
            conv = Fraction
        else:
            half, slack = 0.5, SCANLINE_SLACK
            conv = float
        for tri in tris.tolist():
            P = [[conv(x) for x in v] for v in tri]
            _float_triangle(P, dims, slv, tunnel, mark, counts, half, slack)
    out = np.zeros(dims, dtype=bool)
    if cells:
        c = np.asarray(cells, dtype=np.int64).reshape(-1, 3)
        ok = np.all((c >= 0) & (c < np.asarray(dims)), axis=1)
        c = c[ok]
        out[c[:, 0], c[:, 1], c[:, 2]] = True
    return out


def float_variant_ties(tris: np.ndarray, dims: Sequence[int], mode: str, tunnel: int,
                       eps: float = TIE_EPS, rtol: float = DECISION_RTOL) -> np.ndarray:
    """Voxels where two float runs (float32 GPU, float64 CPU) of an RLV/SLV variant may differ.

    For ``tunnel=26`` the conservative tie set suffices: RLV and SLV lie between
    the conservative sets of half-sizes 0.5 - eps and 0.5 (see the module
    docstring), so rounding can only move voxels that are ties of that
    criterion.  The thinner variants drop voxels on purpose and are bracketed
    by nothing, so their ties are those of the algorithm itself, an explicit
    predicate evaluated on this float64 run:

    - line ties: every voxel incident to a point of a drawn line (or of a
      dropped base edge) that lies within ``eps`` of two face planes at once,
      and to an end point within ``eps`` of a face plane: there the order of
      the traversal's steps, or its end voxels, can flip;
    - decision ties: every voxel of a layer (its scanlines drawn in full) whose
      scanline count is tied (``|span| / bound`` within ``rtol`` of an
      integer, or of zero), and of the layers next to a lowest vertex within
      ``eps`` of a plane w = k (which layer keeps its base edge); every voxel
      of a triangle whose dominant axis or flatness is tied (within ``rtol``
      of the edge lengths' product).

    Parameters
    ----------
    tris : (T, 3, 3) float
        Voxel space, as given to :func:`scanline_surface`.
    dims : (3,) int
    mode : {'rlv', 'slv'}
    tunnel : {26, 18, 6}
    eps, rtol : float

    Returns
    -------
    (nx, ny, nz) bool
        To be united with :func:`glvox.reference.surface_ties` (conservative).
    """
    tris = check_tris(tris)
    dims = check_dims(dims)
    if mode not in ("rlv", "slv"):
        raise ValueError(f"mode must be 'rlv' or 'slv' (ILV is integer: no ties), got {mode!r}")
    if tunnel not in TUNNELS:
        raise ValueError(f"tunnel must be one of {TUNNELS}, got {tunnel!r}")
    rec = _TieRecorder(eps, rtol)

    def mark(cs):
        pass

    for tri in tris.tolist():
        _float_triangle([[float(x) for x in v] for v in tri], dims, mode == "slv", tunnel, mark, None,
                        0.5, SCANLINE_SLACK, rec)
    out = np.zeros(dims, dtype=bool)
    if rec.cells:
        c = np.asarray(rec.cells, dtype=np.int64).reshape(-1, 3)
        c = c[np.all((c >= 0) & (c < np.asarray(dims)), axis=1)]
        out[c[:, 0], c[:, 1], c[:, 2]] = True
    return out
