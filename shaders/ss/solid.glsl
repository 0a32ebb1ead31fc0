// Schwarz & Seidel 2010, Sec. 4.1: a triangle's crossings of the voxel columns
// along x.  Shared by ss-solid, ss-solid-tiled, ss-octree, vote-solid and
// gwn-solid's crossings and strips, so that all of them decide every crossing
// with the same arithmetic (the octree is tested to decode to exactly
// ss-solid's grid).
//
// Voxel space; the ray of column (j, k) runs along x through its center
// c = (j + 1/2, k + 1/2) in the (y, z) plane.  A triangle covering c flips the
// voxels from floor(q + 1/2) to the end of the column, q being the x of the
// crossing: voxel i flips iff its center i + 1/2 > q.
//
// Watertightness.  A closed mesh must count each crossing through a shared
// edge or vertex exactly once.  Coverage is decided in integers
// (common/fixed.glsl): each vertex's (y, z), float32 from common/transform.comp,
// is rounded once to a multiple of 2^-F voxel (F = u_solid_fix_bits,
// glvox.gpu.fixed_point.fixed_bits: 18 at 1024 voxels), the same way for every
// triangle that has it, so the rounded mesh is closed where the true one is;
// the edge functions and the orientation are then exact, an edge function is 0
// only for centers exactly on the edge, and the two triangles of a shared edge
// see exactly opposite values: the top-left rule gives a center on it to
// exactly one of them.  No floating point takes part in a coverage decision,
// so no compiler can change one.  The mesh the decisions see is the true one
// moved by at most 2^-(F+1) voxel across the rays, below TIE_EPS: a voxel
// classified otherwise than by the float64 reference has its center within
// TIE_EPS of the surface, a tie (glvox.reference.solid_ties).
//
// The crossing is the barycentric combination of the vertices' x with the
// exact edge functions (each rounded once) as weights: a point of the rounded
// triangle, so within the same motion of the true surface even on a triangle
// nearly parallel to the rays, where the plane's formula divides by almost
// nothing.  The paper adds the smallest float (f term) for top-left edges; the
// same rule is written out as "> 0, or == 0 on a top-left edge".
#include "common/fixed.glsl"

uniform int u_solid_fix_bits;  // F (see above), 1..28

struct SolidTri {
    vec3 x;          // the vertices' x, for the crossing
    ivec2 f[3];      // the vertices' (y, z) in units of 2^-F voxel
    ivec2 e[3];      // edge i, f[i + 1] - f[i], times sgn: its edge function is inside-positive
    int sgn;         // the projection's orientation: +1 (normal's x > 0), -1; 0: parallel to x
    double inv_area2;  // 1 / twice its projected area (units^2, rounded once: the edge functions' sum)
    int tl;          // bit i: edge i (vertex i -> i + 1) owns the centers exactly on it
    ivec4 box;       // (y, z) bounding box of f: (lo, hi), units
    float xlo, xhi;  // x extent, to clamp q against rounding on edge-on triangles
};

// A (y, z) point in units of 2^-F voxel (common/fixed.glsl's fixed_point).
// exact: fixed_point
ivec2 solid_fixed(vec2 p) { return fixed_point(p, u_solid_fix_bits); }

// One voxel^2 in the edge functions' units^2 is 2^2F: their value times this is in voxel^2.
double solid_unit2() {
    double u = fixed_unit(u_solid_fix_bits);
    return u * u;
}

// Set up t from the voxel-space vertices; false when the triangle is parallel
// to x (zero projected area after the rounding, including zero-area triangles):
// it flips nothing.
// exact: integer orientation and flags
bool solid_setup(vec3 p0, vec3 p1, vec3 p2, out SolidTri t) {
    t.x = vec3(p0.x, p1.x, p2.x);
    t.f = ivec2[3](solid_fixed(p0.yz), solid_fixed(p1.yz), solid_fixed(p2.yz));
    t.box = ivec4(min(min(t.f[0], t.f[1]), t.f[2]), max(max(t.f[0], t.f[1]), t.f[2]));
    t.xlo = min(min(p0.x, p1.x), p2.x);
    t.xhi = max(max(p0.x, p1.x), p2.x);
    double area2 = abs(fixed_det(t.f[1].x - t.f[0].x, t.f[2].y - t.f[0].y, t.f[1].y - t.f[0].y,
                                 t.f[2].x - t.f[0].x, t.sgn));
    t.inv_area2 = 1.0lf / area2;  // once per triangle, not a division per column
    t.tl = 0;
    for (int i = 0; i < 3; ++i) {
        ivec2 d = t.f[(i + 1) % 3] - t.f[i];
        t.e[i] = t.sgn < 0 ? -d : d;
        if (t.sgn != 0 && fixed_top_left(t.f, i, t.sgn)) t.tl |= 1 << i;
    }
    return t.sgn != 0;
}

// Columns (j0, k0, j1, k1), inclusive, whose centers lie in t's (y, z)
// bounding box, clipped to the grid; empty when j0 > j1 or k0 > k1.  Center j
// is (2 j + 1) 2^(F-1) units: j0 = ceil((lo - 2^(F-1)) / 2^F), j1 = floor(...).
ivec4 solid_columns(SolidTri t, ivec3 dims) {
    int half_unit = 1 << (u_solid_fix_bits - 1);
    ivec2 c0 = max(-((half_unit - t.box.xy) >> u_solid_fix_bits), ivec2(0));
    ivec2 c1 = min((t.box.zw - half_unit) >> u_solid_fix_bits, dims.yz - 1);
    return ivec4(c0, c1);
}

// Edge i's function at the center cf (units), oriented so that the inside is
// positive, as a 64-bit integer (hi, lo).
// exact: integer arithmetic
void solid_edge(SolidTri t, int i, ivec2 cf, out int hi, out uint lo) {
    ivec2 r = cf - t.f[i];
    fixed_det_words(t.e[i].x, r.y, t.e[i].y, r.x, hi, lo);
}

// The center of column (j, k) in units: (2 j + 1, 2 k + 1) 2^(F-1).
ivec2 solid_center(ivec2 jk) { return fixed_center(jk, u_solid_fix_bits); }

// Does the column center cf (units) lie in t's projection (top-left rule)?
// w: the oriented edge functions there (edge i weighs vertex i + 2), each rounded
// once, for solid_first_flip (set where covered).
// exact: integer edge functions and flags
bool solid_covers(SolidTri t, ivec2 cf, out dvec3 w) {
    ivec3 hi;
    uvec3 lo;
    for (int i = 0; i < 3; ++i) {
        solid_edge(t, i, cf, hi[i], lo[i]);
        int s = fixed_sign(hi[i], lo[i]);
        if (!(s > 0 || (s == 0 && ((t.tl >> i) & 1) != 0))) return false;
    }
    // (solid_first_flip does not read w.y)
    w = dvec3(fixed_value(hi.x, lo.x), 0.0lf, fixed_value(hi.z, lo.z));
    return true;
}

// The same at the column center c = (y, z), voxels.
// exact: integer edge functions and flags
bool solid_covers(SolidTri t, vec2 c, out dvec3 w) {
    return solid_covers(t, solid_fixed(c), w);
}

// Could any center of the box [c0, c1] of column centers lie in t's
// projection?  Each edge is evaluated at its critical center, the box corner
// farthest inside it (Sec. 4.2's tile test): exactly, so no box with a covered
// center is dropped, and a box is kept only if every edge reaches it.
// exact: integer edge functions
bool solid_may_cover(SolidTri t, vec2 c0, vec2 c1) {
    ivec2 a = solid_fixed(c0), b = solid_fixed(c1);
    for (int i = 0; i < 3; ++i) {
        ivec2 n = ivec2(-t.e[i].y, t.e[i].x);  // inward normal
        ivec2 p = ivec2(n.x > 0 ? b.x : a.x, n.y > 0 ? b.y : a.y);
        int hi;
        uint lo;
        solid_edge(t, i, p, hi, lo);
        if (hi < 0) return false;
    }
    return true;
}

// The first voxel along x that the crossing at a covered center flips, from
// solid_covers' weights w: floor(q + 1/2); below 0 flips the whole column, at
// or past dims.x nothing.  The weights' sum is twice the triangle's area, exact up
// to its one rounding: its reciprocal is taken once per triangle (a division per
// column cost about a tenth of the voxelize pass on llvmpipe); w.y is not needed.
// exact: one formula on exact weights
int solid_first_flip(SolidTri t, dvec3 w) {
    dvec3 x = dvec3(t.x);
    precise double q = x.x + (w.x * (x.z - x.x) + w.z * (x.y - x.x)) * t.inv_area2;
    // within the triangle's x extent but for rounding on nearly edge-on triangles
    q = clamp(q, double(t.xlo), double(t.xhi));
    // far-away triangles (explicit bounds) must not overflow the int
    precise double first = floor(q + 0.5lf);
    return int(clamp(first, -1.0lf, 1073741824.0lf));
}
