// Voxel columns along the render axis and the triangles crossing them
// (Eisemann & Decoret 2008, as described in Leung & Wang 2013 Sec. III-A and
// Schwarz & Seidel 2010 Sec. 2), shared by the vertex and fragment stages.
//
// Needs EIS_AXIS (0, 1, 2: the render axis a).  The pixel grid is the plane
// (u, v) = ((a + 1) % 3, (a + 2) % 3), the same plane and orientation as the
// CPU reference (glvox/reference/solid.py), so pixel (i, j) is the voxel column
// whose center is at (i + 0.5, j + 0.5) in voxel units: pixel centers are
// column centers.
//
// Precision.  Vertices arrive in voxel space as doubles (common/transform.comp with VOX_DOUBLE),
// computed from the float32 upload relative to the mesh's anchor: the mesh the
// GPU sees is the true one moved by at most 2^-24 * N/2 voxel (3e-5 voxel at
// N = 1024), below TIE_EPS (1e-4).  Their (u, v) coordinates are then rounded to
// multiples of 2^-F voxel (F = u_eis_fix_bits, glvox.methods.eisemann.passes.fixed_bits:
// 2^-18 at 1024 voxels), so that every coordinate, every column center and every
// difference is an integer below 2^30 in units of 2^-F.  Coverage is decided in
// those integers: each edge function and the orientation are a difference of two
// products, whose sign imulExtended's exact 64-bit products give whatever the
// compiler does with floating point.  Each vertex is rounded once, the same way for
// every triangle that has it, so the rounded mesh is closed where the true one is,
// and the top-left rule counts a center on a shared edge or vertex exactly once:
// the GPU computes the exact parity solid of a mesh moved by less than TIE_EPS, and
// a voxel it classifies differently from the float64 reference has its center
// within TIE_EPS of the surface, a tie (glvox.reference.solid_ties).  The edge
// functions in double were not enough: on a face parallel to the axis whose
// projection, a segment, runs through column centers, their rounding put centers
// inside all three edges of a sliver and outside its neighbours, flipping whole
// columns (tests/test_eisemann.py, the edge-on hull).
//
// The crossing is computed in double from the rounded vertices (the reference's
// formula).  On a triangle nearly parallel to the axis it is ill-conditioned: its
// rounding can move it by voxels.  There it is clamped to the triangle's section
// through the column (eis_section), every point of which lies within the
// section's width, far below TIE_EPS on such a triangle, of the column.

layout(std430, binding = 0) readonly buffer EisVox { double eis_vox[]; };  // voxel space, xyz per vertex
layout(std430, binding = 1) readonly buffer EisFaces { uint eis_faces[]; };

const int EIS_U = (EIS_AXIS + 1) % 3;
const int EIS_V = (EIS_AXIS + 2) % 3;

uniform int u_eis_fix_bits;  // F: (u, v) in multiples of 2^-F voxel (see above)

// A (u, v) point (a vertex or a column center) in units of 2^-F voxel, rounded to
// the nearest (ties to even): exact for a point that is already a multiple.
// (Scaled by products with exact powers of two: llvmpipe's ldexp on doubles loses bits.)
// exact: a product by a power of two, then one rounding
ivec2 eis_fixed(dvec2 p) {
    precise dvec2 x = p * double(1 << u_eis_fix_bits);
    return ivec2(roundEven(x));
}

// Vertex vi as (u, v, a), (u, v) rounded to multiples of 2^-F voxel.
dvec3 eis_vertex(uint vi) {
    uint b = 3u * vi;
    dvec2 uv = dvec2(eis_vox[b + uint(EIS_U)], eis_vox[b + uint(EIS_V)]);
    precise dvec2 snapped = dvec2(eis_fixed(uv)) * (1.0lf / double(1 << u_eis_fix_bits));
    return dvec3(snapped, eis_vox[b + uint(EIS_AXIS)]);
}

void eis_triangle(uint t, out dvec3 p0, out dvec3 p1, out dvec3 p2) {
    p0 = eis_vertex(eis_faces[3u * t]);
    p1 = eis_vertex(eis_faces[3u * t + 1u]);
    p2 = eis_vertex(eis_faces[3u * t + 2u]);
}

// The sign of a * b - c * d, exactly: the 64-bit products of imulExtended compared as
// signed 64-bit integers (high words signed, then low words unsigned).
// exact: integer arithmetic
int eis_det_sign(int a, int b, int c, int d) {
    int ab_hi, ab_lo, cd_hi, cd_lo;
    imulExtended(a, b, ab_hi, ab_lo);
    imulExtended(c, d, cd_hi, cd_lo);
    if (ab_hi != cd_hi) return ab_hi > cd_hi ? 1 : -1;
    uint l = uint(ab_lo), r = uint(cd_lo);
    return l == r ? 0 : (l > r ? 1 : -1);
}

// The sign of the edge function of p -> q at c, (q - p) x (c - p), in units of 2^-F.
// exact: integer arithmetic; opposite for the two triangles of an edge
int eis_edge_sign(ivec2 p, ivec2 q, ivec2 c) {
    ivec2 e = q - p;
    ivec2 r = c - p;
    return eis_det_sign(e.x, r.y, e.y, r.x);
}

// The projected triangle's orientation: +1 counter-clockwise (the normal's a
// component positive), -1 clockwise, 0 parallel to the axis (no crossing).
// exact: integer arithmetic
int eis_orientation(ivec2 f[3]) {
    return eis_det_sign(f[1].x - f[0].x, f[2].y - f[0].y, f[1].y - f[0].y, f[2].x - f[0].x);
}

int eis_orientation(dvec3 p0, dvec3 p1, dvec3 p2) {
    ivec2 f[3] = ivec2[3](eis_fixed(p0.xy), eis_fixed(p1.xy), eis_fixed(p2.xy));
    return eis_orientation(f);
}

// The triangle's normal (cross(p1 - p0, p2 - p0)) in (u, v, a) order.
// exact: as the reference's normal
dvec3 eis_normal(dvec3 p0, dvec3 p1, dvec3 p2) {
    precise dvec3 e0 = p1 - p0;
    precise dvec3 e1 = p2 - p0;
    precise dvec3 n = dvec3(e0.y * e1.z - e0.z * e1.y, e0.z * e1.x - e0.x * e1.z, e0.x * e1.y - e0.y * e1.x);
    return n;
}

// Edge i (f[i] -> f[i + 1]) of the projected triangle f at c, oriented by sgn so that
// the inside is positive: -1, 0 or +1.
// exact: eis_edge_sign times +-1
int eis_edge_at(ivec2 f[3], int i, int sgn, ivec2 c) {
    return eis_edge_sign(f[i], f[(i + 1) % 3], c) * sgn;
}

// Does edge i own the centers exactly on it?  Only a left edge (inward normal
// n_u > 0) or a top edge (n_u == 0, n_v < 0) does.
// exact: integer differences and signs
bool eis_top_left(ivec2 f[3], int i, int sgn) {
    ivec2 e = f[(i + 1) % 3] - f[i];
    int nu = -sign(e.y) * sgn;
    int nv = sign(e.x) * sgn;
    return nu > 0 || (nu == 0 && nv < 0);
}

// Is the column center c inside the projected triangle?  A center on an edge
// counts only for a top-left edge: each center on a shared edge counts exactly
// once.  (testing/tie_probe.glsl reads the same edge signs and flags.)
// exact: the reference's coverage test, in integers
bool eis_covers(dvec3 p0, dvec3 p1, dvec3 p2, dvec2 c) {
    ivec2 f[3] = ivec2[3](eis_fixed(p0.xy), eis_fixed(p1.xy), eis_fixed(p2.xy));
    int sgn = eis_orientation(f);
    if (sgn == 0) return false;
    ivec2 cf = eis_fixed(c);
    for (int i = 0; i < 3; ++i) {
        int s = eis_edge_at(f, i, sgn, cf);
        if (!(s > 0 || (s == 0 && eis_top_left(f, i, sgn)))) return false;
    }
    return true;
}

// The extent along a of the triangle's points whose projection lies in the slab
// |dot(d, x - c)| <= r, d the unit direction of its longest projected edge: with
// r = 0 its section through the column center c, the segment between the edges that
// reach the line through c across d.  The crossing of c lies in that section, and on
// a triangle nearly parallel to the axis (a sliver in projection) every point of it
// lies within the sliver's width of the column.  Without an edge in the slab (rounding,
// for a center on the triangle's outline), the whole extent.
dvec2 eis_section(dvec3 p[3], dvec2 c, double r) {
    dvec2 d = p[1].xy - p[0].xy;
    for (int i = 1; i < 3; ++i) {
        dvec2 e = p[(i + 1) % 3].xy - p[i].xy;
        if (dot(e, e) > dot(d, d)) d = e;
    }
    d = d / length(d);
    double lo = 1.0e300, hi = -1.0e300;
    for (int i = 0; i < 3; ++i) {
        dvec3 a = p[i], b = p[(i + 1) % 3];
        double sa = dot(d, a.xy - c), sb = dot(d, b.xy - c);
        double t0 = 0.0, t1 = 1.0;  // the part of the edge in the slab
        if (sa == sb) {
            if (abs(sa) > r) continue;
        } else {
            double ta = (-r - sa) / (sb - sa), tb = (r - sa) / (sb - sa);
            t0 = max(t0, min(ta, tb));
            t1 = min(t1, max(ta, tb));
            if (t0 > t1) continue;
        }
        double z0 = a.z + t0 * (b.z - a.z), z1 = a.z + t1 * (b.z - a.z);
        lo = min(lo, min(z0, z1));
        hi = max(hi, max(z0, z1));
    }
    if (lo > hi) {
        lo = min(min(p[0].z, p[1].z), p[2].z);
        hi = max(max(p[0].z, p[1].z), p[2].z);
    }
    return dvec2(lo, hi);
}

//: A triangle is steep when its normal's a component is below 2^-20 of the others: its
//: crossing's rounding may then exceed 1e-6 voxel, and eis_crossing clamps it.
#define EIS_STEEP 9.5367431640625e-07

// The range eis_crossing clamps to: the triangle's extent along a, as the reference
// clamps, and on a steep triangle its section through c (eis_section): the reference
// computes such a crossing exactly, the double formula can be voxels off.
dvec2 eis_crossing_range(dvec3 p0, dvec3 p1, dvec3 p2, dvec3 n, dvec2 c) {
    double lo = min(min(p0.z, p1.z), p2.z);
    double hi = max(max(p0.z, p1.z), p2.z);
    if (abs(n.z) <= EIS_STEEP * (abs(n.x) + abs(n.y))) {
        dvec3 p[3] = dvec3[3](p0, p1, p2);
        dvec2 s = eis_section(p, c, 0.0);
        lo = max(lo, s.x);
        hi = max(lo, min(hi, s.y));
    }
    return dvec2(lo, hi);
}

// Where the column through c crosses the triangle's plane, along a (voxel units),
// clamped to eis_crossing_range.  A triangle whose double normal has no a component
// (the exact one has, or c would not be covered) takes the range's low end.  The result
// differs from the exact crossing only where the voxel centers between them lie within
// TIE_EPS of the triangle.
// exact: the reference's crossing formula, in its order; in the section on a steep triangle
double eis_crossing(dvec3 p0, dvec3 p1, dvec3 p2, dvec3 n, dvec2 c) {
    dvec2 range = eis_crossing_range(p0, p1, p2, n, c);
    if (n.z == 0.0) return range.x;
    precise double q = p0.z + (n.x * (p0.x - c.x) + n.y * (p0.y - c.y)) / n.z;
    return clamp(q, range.x, range.y);
}

// A double voxel coordinate as an int, clamped first so that far-away geometry
// cannot overflow the conversion (callers only compare with grid indices).
int eis_to_int(double x) { return int(clamp(x, -2.0, 1073741824.0)); }

// First slice a crossing at q flips: voxel k flips iff its center k + 0.5 > q.
// exact: one rounding-free addition
int eis_first_flipped(double q) {
    precise double f = floor(q + 0.5);
    return eis_to_int(f);
}

// The slice holding the crossing point (the voxel whose [k, k+1] contains q;
// a crossing on the face k belongs to slice k).  On the grid's far face (q = n,
// n slices) it belongs to the last slice, the one voxel inside the grid that the
// face touches: geometry on the grid's boundary planes is voxelized like geometry
// inside, so a face there (the default fit puts the bounding box on them) keeps
// its wall.
int eis_slice_of(double q, int n) { return q == double(n) ? n - 1 : eis_to_int(floor(q)); }
