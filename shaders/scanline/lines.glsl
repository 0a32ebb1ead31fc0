// Line voxelizations of Zhang et al. 2018, Sec. 4.1, step for step as in
// glvox/reference/scanline.py (rlv_line, slv_line, ilv_line, drop_corners).
// Voxel space: voxel v is the unit cube at v; a point lies in voxel floor(p).
// Needs mark(), job() and tick() (budget.glsl).  No loop here other than the
// one stepping loop of each draw function and the corner loop of
// mark_box_but: every loop must be charged (see budget.glsl), and a per-axis
// loop the compiler did not unroll would not be, so per-axis work is written
// out.

const float T_NONE = 3.0e38;

// Lexicographic order of integer points (the canonical direction of an edge).
bool lex_less(ivec3 p, ivec3 q) {
    return p.x < q.x || (p.x == q.x && (p.y < q.y || (p.y == q.y && p.z < q.z)));
}

bool lex_less(vec3 p, vec3 q) {
    return p.x < q.x || (p.x == q.x && (p.y < q.y || (p.y == q.y && p.z < q.z)));
}

// ---------------------------------------------------------------------------
// Float lines (RLV, SLV)

// One axis of clip_segment: narrow [t0, t1] to where p + t d lies in [lo, hi].
// exact: the same rounding in every variant (they are nested, tests/test_scanline.py)
void clip_axis(float p, float d, float lo, float hi, inout float t0, inout float t1, inout bool ok) {
    if (d == 0.0) {
        if (p < lo || p > hi) ok = false;
    } else {
        precise float ta = (lo - p) / d;
        precise float tb = (hi - p) / d;
        t0 = max(t0, min(ta, tb));
        t1 = min(t1, max(ta, tb));
    }
}

// The part of segment p-q inside the closed box [lo, hi]; false if none.
// exact: p + t d must not fuse differently in the variants
bool clip_segment(vec3 p, vec3 q, vec3 lo, vec3 hi, out vec3 cp, out vec3 cq) {
    float t0 = 0.0, t1 = 1.0;
    bool ok = true;
    precise vec3 d = q - p;
    clip_axis(p.x, d.x, lo.x, hi.x, t0, t1, ok);
    clip_axis(p.y, d.y, lo.y, hi.y, t0, t1, ok);
    clip_axis(p.z, d.z, lo.z, hi.z, t0, t1, ok);
    precise vec3 c0 = p + t0 * d, c1 = p + t1 * d;
    cp = t0 == 0.0 ? p : c0;
    cq = t1 == 1.0 ? q : c1;
    return ok && t0 <= t1;
}

// Voxels on both sides of a coordinate lying on a face plane, else the one containing it.
ivec2 incident(float c) {
    float f = floor(c);
    int i = int(f);
    return c == f ? ivec2(i - 1, i) : ivec2(i, i);
}

// The corner index of voxel v of a box whose low corner is lo (bit i: v lies
// at the box's high end on axis i).
uint box_corner(ivec3 v, ivec3 lo) {
    return (v.x != lo.x ? 1u : 0u) | (v.y != lo.y ? 2u : 0u) | (v.z != lo.z ? 4u : 0u);
}

// Every voxel of the box [lo, hi] (at most 2 x 2 x 2) whose corner index
// (box_corner) is not set in `skip`, the caller having marked those.  Most
// boxes are one voxel, and most SLV events two that the caller marks: a loop
// over the corners left runs no iteration for them, where eight mark sites
// written out each cost a SIMD batch (llvmpipe runs every site under masks,
// and an atomicOr site steps through the batch's lanes).  Loop iterations: 1
// + up to 7, charged by the caller (MARK_BOX_COST).
const uint MARK_BOX_COST = 8u;

void mark_box_but(ivec3 lo, ivec3 hi, uint skip) {
    uint corners = (lo.x == hi.x ? 0x55u : 0xFFu) & (lo.y == hi.y ? 0x33u : 0xFFu)
                   & (lo.z == hi.z ? 0x0Fu : 0xFFu) & ~skip;
    while (corners != 0u) {
        uint c = uint(findLSB(corners));
        corners &= corners - 1u;
        mark(mix(lo, hi, bvec3((c & 1u) != 0u, (c & 2u) != 0u, (c & 4u) != 0u)));
    }
}

// The voxels incident to p (charge MARK_BOX_COST): the one holding it, and
// more where p lies on face planes.
void mark_incident(vec3 p) {
    ivec2 x = incident(p.x), y = incident(p.y), z = incident(p.z);
    ivec3 lo = ivec3(x.x, y.x, z.x);
    mark(lo);
    mark_box_but(lo, ivec3(x.y, y.y, z.y), 1u);
}

// Stepping state of a float line.  RLV: from floor(p), `left` steps per axis
// to floor(q).  SLV: `plane` is the next face plane crossed per axis, `left`
// the planes strictly between p and q, `cur` the voxel of the open stretch.
struct FLine {
    vec3 p;
    vec3 v;
    ivec3 cur;
    ivec3 stp;
    ivec3 left;
    ivec3 plane;
};

// One axis of the SLV set-up: the voxel of the first open stretch, the first
// face plane crossed, the planes strictly between p and q, the step.
void slv_axis(float p, float q, out int cur, out int plane, out int left, out int stp) {
    if (q > p) {
        cur = int(floor(p));
        plane = cur + 1;
        left = max(0, int(ceil(q)) - 1 - plane + 1);
        stp = 1;
    } else if (q < p) {
        cur = int(ceil(p)) - 1;
        plane = cur;
        left = max(0, plane - (int(floor(q)) + 1) + 1);
        stp = -1;
    } else {
        cur = int(floor(p));
        plane = 0;
        left = 0;
        stp = 0;
    }
}

// RLV's voxel index of coordinate x on an axis of n voxels: floor, except that
// x within RLV_BOUNDARY_SNAP outside the grid belongs to the boundary voxel (cell()).
int cell1(float x, int n) {
    if (x >= float(n) && x <= float(n) + RLV_BOUNDARY_SNAP) return n - 1;
    if (x < 0.0 && x >= -RLV_BOUNDARY_SNAP) return 0;
    return int(floor(x));
}

ivec3 cell(vec3 x) { return ivec3(cell1(x.x, u_dims.x), cell1(x.y, u_dims.y), cell1(x.z, u_dims.z)); }

FLine fline_begin(vec3 p, vec3 q, bool super_cover) {
    FLine l;
    l.p = p;
    l.v = q - p;
    if (!super_cover) {
        l.cur = cell(p);
        ivec3 e = cell(q) - l.cur;
        l.left = abs(e);
        l.stp = ivec3(sign(e));
        l.plane = l.cur + max(l.stp, ivec3(0));  // face ahead: cur + 1 going up, cur going down
        return l;
    }
    slv_axis(p.x, q.x, l.cur.x, l.plane.x, l.left.x, l.stp.x);
    slv_axis(p.y, q.y, l.cur.y, l.plane.y, l.left.y, l.stp.y);
    slv_axis(p.z, q.z, l.cur.z, l.plane.z, l.left.z, l.stp.z);
    return l;
}

// Parameters at which the line reaches its next face plane, T_NONE where it has none left.
// exact: the order of the crossings decides the voxels of every variant alike
vec3 fline_t(FLine l) {
    precise vec3 t = vec3(T_NONE);
    if (l.left.x > 0) t.x = (float(l.plane.x) - l.p.x) / l.v.x;
    if (l.left.y > 0) t.y = (float(l.plane.y) - l.p.y) / l.v.y;
    if (l.left.z > 0) t.z = (float(l.plane.z) - l.p.z) / l.v.z;
    return t;
}

// Voxel range of one axis at an SLV event: both sides of the plane on an axis
// the line lies in or crosses now, else the voxel of the current stretch.
ivec2 slv_range(float p, int cur, int stp, bool crossing) {
    if (stp == 0) return incident(p);
    if (crossing) return ivec2(min(cur, cur + stp), max(cur, cur + stp));
    return ivec2(cur, cur);
}

// Voxelize segment p-q.  super_cover: SLV (with `ends`, the voxels incident to
// p and q too; without, the caller marks them); else RLV, and with `reduce` the
// tunnel=18 base edge: a voxel is dropped when the path arrives by a step of
// negative value and leaves by one of positive value, a step along axis a
// (b) with sign s being worth pa * s (pb * s); the end voxels stay.
void draw_float(vec3 p, vec3 q, bool super_cover, bool ends, bool reduce, int a, int b, float pa, float pb) {
    FLine l = fline_begin(p, q, super_cover);
    int n = l.left.x + l.left.y + l.left.z;
    // the steps and the last test; SLV's steps with their boxes' corner loops, and
    // its end points' boxes
    uint cost = uint(n) + 1u;
    if (super_cover) cost += MARK_BOX_COST * uint(n) + (ends ? 2u * MARK_BOX_COST : 0u);
    if (!job(cost)) return;
    if (super_cover) {
        if (ends) {
            mark_incident(p);
            mark_incident(q);
        }
    } else {
        mark(l.cur);
    }
    float arr = 0.0;  // value of the step that reached l.cur (RLV with reduce)
    for (int s = 0; s < n; ++s) {
        vec3 t = fline_t(l);
        float tmin = min(t.x, min(t.y, t.z));
        if (tmin == T_NONE) break;
        if (super_cover) {
            bvec3 x = bvec3(t.x == tmin, t.y == tmin, t.z == tmin);
            ivec2 rx = slv_range(l.p.x, l.cur.x, l.stp.x, x.x);
            ivec2 ry = slv_range(l.p.y, l.cur.y, l.stp.y, x.y);
            ivec2 rz = slv_range(l.p.z, l.cur.z, l.stp.z, x.z);
            ivec3 lo = ivec3(rx.x, ry.x, rz.x), hi = ivec3(rx.y, ry.y, rz.y);
            // the box holds l.cur (both sides of a crossed plane, cur itself on the
            // other axes, incident(p) with cur = floor(p) where the line lies in a
            // plane), and l.cur is marked: by mark_incident(p) first (here or by
            // the caller), then as the new voxel of the event before.  The new
            // voxel (in the box, and not l.cur: some axis crosses) is marked
            // here, the rest of the box, at a singular point only, by the corner
            // loop.  Marks are idempotent ORs, so leaving l.cur out changes
            // nothing but the count of atomics.
            ivec3 xs = ivec3(x);
            ivec3 next = l.cur + xs * l.stp;
            mark(next);
            mark_box_but(lo, hi, (1u << box_corner(l.cur, lo)) | (1u << box_corner(next, lo)));
            l.cur += xs * l.stp;
            l.plane += xs * l.stp;
            l.left -= xs;
        } else {
            int ax = t.x == tmin ? 0 : (t.y == tmin ? 1 : 2);
            ivec3 prev = l.cur;
            l.cur[ax] += l.stp[ax];
            l.plane[ax] += l.stp[ax];
            l.left[ax] -= 1;
            if (reduce) {
                float dep = (ax == a ? pa : (ax == b ? pb : 0.0)) * float(l.stp[ax]);
                // prev was reached by a step worth `arr` (none for the first voxel)
                if (s > 0 && !(arr < 0.0 && dep > 0.0)) mark(prev);
                arr = dep;
                if (l.left.x + l.left.y + l.left.z == 0) mark(l.cur);
            } else {
                mark(l.cur);
            }
        }
    }
}

// ---------------------------------------------------------------------------
// Integer line (ILV, Eq. 3-4 and Alg. 1 MarkLineILV)

// M over the non-zero deltas only; L is the scaled distance to the next face
// per axis.  Ties: at a tie of axes i < j, i steps first iff it moves up
// (tie_order in the CPU reference: the crossings of the segment after an
// infinitesimal shift of the lattice by (e1, e2, e3), e1 >> e2 >> e3 > 0), so
// q -> p is the exact reverse of p -> q and all lines pass a voxel corner on
// the same side.  A base edge (`base`, on the slicing plane w = K) decides a
// tie of its two axes by base_tie() instead (defined by the includer).
struct Ilv {
    ivec3 p;
    ivec3 stp;
    ivec3 m2;
    ivec3 L;
    ivec3 left;
    bool base;
    int K;
};

int base_tie(ivec3 c1, ivec3 c2, int K);

Ilv ilv_begin(ivec3 p, ivec3 q) {
    Ilv it;
    ivec3 d = q - p;
    it.p = p;
    it.left = abs(d);
    it.stp = ivec3(sign(d));
    ivec3 f = max(it.left, ivec3(1));
    ivec3 m = ivec3(f.y * f.z, f.x * f.z, f.x * f.y) * ivec3(greaterThan(it.left, ivec3(0)));
    it.L = m;
    it.m2 = 2 * m;
    it.base = false;
    it.K = 0;
    return it;
}

// A base edge on the plane w = K (_ilv_slice's base_tie in the CPU reference).
Ilv ilv_base(ivec3 p, ivec3 q, int K) {
    Ilv it = ilv_begin(p, q);
    it.base = true;
    it.K = K;
    return it;
}

// The axis of the next step, -1 at the end.  Scanning x, y, z, a later axis
// wins a tie iff the current best moves down (a total order: see above).
// Without the base edges' tie: for the paths that are never base edges.
int ilv_axis_plain(Ilv it) {
    int best = -1;
    int bl = 0, bs = 0;  // best's L and step
    if (it.left.x > 0) { best = 0; bl = it.L.x; bs = it.stp.x; }
    if (it.left.y > 0 && (best < 0 || it.L.y < bl || (it.L.y == bl && bs < 0))) { best = 1; bl = it.L.y; bs = it.stp.y; }
    if (it.left.z > 0 && (best < 0 || it.L.z < bl || (it.L.z == bl && bs < 0))) { best = 2; bl = it.L.z; bs = it.stp.z; }
    return best;
}

// The same, and a base edge's tie of two axes decided by base_tie().
int ilv_axis(Ilv it) {
    int best = ilv_axis_plain(it);
    if (it.base && best >= 0) {
        int bl = it.L[best];
        int o = -1;  // the other axis tied with best (a base edge moves along two axes at most)
        if (best != 0 && it.left.x > 0 && it.L.x == bl) o = 0;
        if (best != 1 && it.left.y > 0 && it.L.y == bl) o = 1;
        if (best != 2 && it.left.z > 0 && it.L.z == bl) o = 2;
        if (o >= 0) {
            ivec3 c1 = it.p, c2 = it.p;
            c1[best] += it.stp[best];
            c2[o] += it.stp[o];
            if (base_tie(c1, c2, it.K) > 0) best = o;
        }
    }
    return best;
}

void ilv_step(inout Ilv it, int ax) {
    ivec3 e = ivec3(equal(ivec3(ax), ivec3(0, 1, 2)));  // one-hot: no vector indexed by a variable
    int lm = it.L.x * e.x + it.L.y * e.y + it.L.z * e.z;
    it.L = mix(it.L - ivec3(greaterThan(it.m2, ivec3(0))) * lm, it.m2, bvec3(e));
    it.p += it.stp * e;
    it.left -= e;
}

// The ILV voxels from p to q, the exact reverse of q -> p (_path).
Ilv ilv_path(ivec3 p, ivec3 q) { return ilv_begin(p, q); }

// Draw the path p -> q, every voxel, or (keep != 0) only the voxels
// keep_copy() keeps of a base-edge copy: keep = 1 the copy in layer K,
// keep = 2 the copy in layer K - 1 (keep_copy is defined by the includer).
// `base`: p -> q is a base edge on the plane w = K (ilv_base).
bool keep_copy(ivec3 c, int K, bool bottom);

void draw_ilv(ivec3 p, ivec3 q, int keep, int K, bool base) {
    Ilv it = base ? ilv_base(p, q, K) : ilv_path(p, q);
    int n = it.left.x + it.left.y + it.left.z;
    if (!job(uint(n) + 1u)) return;
    if (keep == 0 || keep_copy(p, K, keep == 1)) mark(p);
    for (int s = 0; s < n; ++s) {
        int ax = ilv_axis(it);
        if (ax < 0) break;
        ilv_step(it, ax);
        if (keep == 0 || keep_copy(it.p, K, keep == 1)) mark(it.p);
    }
}
