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
// multiples of 2^-F voxel (F = u_eis_fix_bits, glvox.gpu.fixed_point.fixed_bits:
// 2^-18 at 1024 voxels), so that every coordinate and column center is an integer
// below 2^29 in units of 2^-F, and every difference below 2^30.  Coverage is decided in
// those integers (common/fixed.glsl, shared with ss/solid.glsl): each edge function and
// the orientation are a difference of two products, whose sign imulExtended's exact
// 64-bit products give whatever the compiler does with floating point.  Each vertex is rounded once, the same way for
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
// The crossing is the barycentric combination of the vertices' a with the edge
// functions as weights (eis_crossing), each rounded once from its exact value, not the
// plane's formula of the reference: on a triangle nearly parallel to the axis that
// divides by almost nothing and landed voxels away (tests/test_eisemann.py, the
// Fibonacci sliver), where the weights still give the exact crossing to double
// precision.

layout(std430, binding = 0) readonly buffer EisVox { double eis_vox[]; };  // voxel space, xyz per vertex
layout(std430, binding = 1) readonly buffer EisFaces { uint eis_faces[]; };

#include "common/fixed.glsl"

const int EIS_U = (EIS_AXIS + 1) % 3;
const int EIS_V = (EIS_AXIS + 2) % 3;

uniform int u_eis_fix_bits;  // F: (u, v) in multiples of 2^-F voxel (see above)

// 2^-F voxel, one unit of the fixed point, from its bits (GLSL lets a division be 2.5 ulp off).
double eis_unit() { return fixed_unit(u_eis_fix_bits); }

// A (u, v) point (a vertex or a column center, multiples of 2^-F voxel) in units of
// 2^-F voxel, exactly (rounded to the nearest, ties to even, were it not a multiple).
// (Scaled by products with exact powers of two: llvmpipe's ldexp on doubles loses bits.)
// exact: a product by a power of two, then one rounding
ivec2 eis_fixed(dvec2 p) {
    precise dvec2 x = p * double(1 << u_eis_fix_bits);
    return ivec2(roundEven(x));
}

// Vertex vi as (u, v, a), (u, v) already multiples of 2^-F voxel (common/transform.comp
// with VOX_FIX_AXIS rounds them once per run).
dvec3 eis_vertex(uint vi) {
    uint b = 3u * vi;
    return dvec3(eis_vox[b + uint(EIS_U)], eis_vox[b + uint(EIS_V)], eis_vox[b + uint(EIS_AXIS)]);
}

void eis_triangle(uint t, out dvec3 p0, out dvec3 p1, out dvec3 p2) {
    p0 = eis_vertex(eis_faces[3u * t]);
    p1 = eis_vertex(eis_faces[3u * t + 1u]);
    p2 = eis_vertex(eis_faces[3u * t + 2u]);
}

int eis_orientation(dvec3 p0, dvec3 p1, dvec3 p2) {
    ivec2 f[3] = ivec2[3](eis_fixed(p0.xy), eis_fixed(p1.xy), eis_fixed(p2.xy));
    return fixed_orientation(f);
}

// The triangle's normal (cross(p1 - p0, p2 - p0)) in (u, v, a) order.
// exact: as the reference's normal
dvec3 eis_normal(dvec3 p0, dvec3 p1, dvec3 p2) {
    precise dvec3 e0 = p1 - p0;
    precise dvec3 e1 = p2 - p0;
    precise dvec3 n = dvec3(e0.y * e1.z - e0.z * e1.y, e0.z * e1.x - e0.x * e1.z, e0.x * e1.y - e0.y * e1.x);
    return n;
}

// The edge functions at the column center c, oriented so that the inside is positive
// (edge i runs from vertex i to i + 1: its value weighs vertex i + 2), rounded once
// from their exact values, with their exact signs s; sgn: the orientation (0: parallel
// to the axis, and w and s are 0); f: the vertices' (u, v) in units of 2^-F.
// exact: integer edge functions, each rounded once
void eis_weights(dvec3 p0, dvec3 p1, dvec3 p2, dvec2 c, out dvec3 w, out ivec3 s, out int sgn,
                 out ivec2 f[3]) {
    f = ivec2[3](eis_fixed(p0.xy), eis_fixed(p1.xy), eis_fixed(p2.xy));
    sgn = fixed_orientation(f);
    w = dvec3(0.0);
    s = ivec3(0);
    if (sgn == 0) return;
    ivec2 cf = eis_fixed(c);
    for (int i = 0; i < 3; ++i) {
        int si;
        w[i] = fixed_edge(f[i], f[(i + 1) % 3], cf, si) * double(sgn);
        s[i] = si * sgn;
    }
}

// Is the column center c inside the projected triangle?  A center on an edge
// counts only for a top-left edge: each center on a shared edge counts exactly
// once.  w: eis_weights' edge functions, for eis_crossing.  (testing/tie_probe.glsl
// reads the same values and flags.)
// exact: the reference's coverage test, in integers
bool eis_covers_at(dvec3 p0, dvec3 p1, dvec3 p2, dvec2 c, out dvec3 w) {
    ivec3 s;
    int sgn;
    ivec2 f[3];
    eis_weights(p0, p1, p2, c, w, s, sgn, f);
    if (sgn == 0) return false;
    for (int i = 0; i < 3; ++i) {
        if (!(s[i] > 0 || (s[i] == 0 && fixed_top_left(f, i, sgn)))) return false;
    }
    return true;
}

// eis_section's step: widens range by the extent along a of the part of the edge a -> b
// in the slab (sa, sb: the ends' positions across it, relative to c).
void eis_section_edge(dvec3 a, dvec3 b, double sa, double sb, double r, inout dvec2 range) {
    double t0 = 0.0, t1 = 1.0;
    if (sa == sb) {
        if (abs(sa) > r) return;
    } else {
        double ta = (-r - sa) / (sb - sa), tb = (r - sa) / (sb - sa);
        t0 = max(t0, min(ta, tb));
        t1 = min(t1, max(ta, tb));
        if (t0 > t1) return;
    }
    double z0 = a.z + t0 * (b.z - a.z), z1 = a.z + t1 * (b.z - a.z);
    range = dvec2(min(range.x, min(z0, z1)), max(range.y, max(z0, z1)));
}

// The extent along a of the triangle's points whose projection lies in the slab
// |dot(d, x - c)| <= r, d the unit direction of its longest projected edge: with
// r = 0 its section through the column center c, the segment between the edges that
// reach the line through c across d.  The crossing of c lies in that section, and on
// a triangle nearly parallel to the axis (a sliver in projection) every point of it
// lies within the sliver's width of the column.  Without an edge in the slab (rounding,
// for a center on the triangle's outline), the whole extent.  (ldi/depths.frag bounds
// its widened samples with it.)
dvec2 eis_section(dvec3 p0, dvec3 p1, dvec3 p2, dvec2 c, double r) {
    dvec2 d0 = p1.xy - p0.xy, d1 = p2.xy - p1.xy, d2 = p0.xy - p2.xy;
    double l0 = dot(d0, d0), l1 = dot(d1, d1), l2 = dot(d2, d2);
    dvec2 d = l0 >= l1 && l0 >= l2 ? d0 : (l1 >= l2 ? d1 : d2);
    d = d / length(d);
    double s0 = dot(d, p0.xy - c), s1 = dot(d, p1.xy - c), s2 = dot(d, p2.xy - c);
    dvec2 range = dvec2(1.0e300, -1.0e300);
    eis_section_edge(p0, p1, s0, s1, r, range);
    eis_section_edge(p1, p2, s1, s2, r, range);
    eis_section_edge(p2, p0, s2, s0, r, range);
    if (range.x > range.y) {
        range = dvec2(min(min(p0.z, p1.z), p2.z), max(max(p0.z, p1.z), p2.z));
    }
    return range;
}

// Where the column through a center the triangle covers crosses it, along a (voxel
// units): the barycentric combination of its vertices with the edge functions w of
// eis_weights, clamped to the triangle's extent along a (outside the triangle, with
// raster coverage, the plane's value there).  The weights are exact up
// to one rounding each, so even on a triangle nearly parallel to the axis, where the
// plane's formula (the reference's) divides by almost nothing and lands voxels away,
// the crossing is the exact one to double precision; a face parallel to the grid gets
// its own a exactly (every z difference is 0).
// exact: one formula on exact weights
double eis_crossing(dvec3 p0, dvec3 p1, dvec3 p2, dvec3 w) {
    precise double q = p0.z + (w.x * (p2.z - p0.z) + w.z * (p1.z - p0.z)) / (w.x + w.y + w.z);
    return clamp(q, min(min(p0.z, p1.z), p2.z), max(max(p0.z, p1.z), p2.z));
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
