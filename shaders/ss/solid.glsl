// Schwarz & Seidel 2010, Sec. 4.1: a triangle's crossings of the voxel columns
// along x.  Shared by ss-solid, ss-solid-tiled and ss-octree so that all three
// decide every crossing with the same arithmetic (the octree is tested to
// decode to exactly ss-solid's grid).
//
// Voxel space; the ray of column (j, k) runs along x through its center
// c = (j + 1/2, k + 1/2) in the (y, z) plane.  A triangle covering c flips the
// voxels from floor(q + 1/2) to the end of the column, q being the x of the
// crossing: voxel i flips iff its center i + 1/2 > q.
//
// Watertightness.  A closed mesh must count each crossing through a shared
// edge or vertex exactly once.  Two things make that hold here exactly, not
// just up to rounding:
//   * the edge function of an edge is evaluated from its lexicographically
//     smaller endpoint and negated for the triangle that runs it the other
//     way, so the two triangles of a shared edge see bit-identical values of
//     opposite sign (as glvox/reference/solid.py does), and the top-left rule
//     gives a zero value to exactly one of them;
//   * orientation and edge functions are computed in double from the float32
//     voxel-space vertices: coordinate differences and their products are
//     then exact or within one rounding of the exact value, so the sign of
//     the orientation is exact and an edge function is zero only for centers
//     exactly on the edge.  In float32 a center within rounding of a vertex
//     shared by a fan could be claimed by two triangles of the fan, or none,
//     and flip a whole column wrongly.
// The paper adds the smallest float (f term) for top-left edges; the same rule
// is written out as "> 0, or == 0 on a top-left edge" (see common/edge.glsl).

struct SolidTri {
    dvec3 v0;        // a vertex, for the plane equation
    dvec3 n;         // plane normal (unnormalized), n.x != 0
    vec2 lo, hi;     // (y, z) bounding box
    float xlo, xhi;  // x extent, to clamp q against rounding on edge-on triangles
    dvec2 a[3];      // edge i: lexicographically smaller endpoint in (y, z)
    dvec2 d[3];      // edge i: larger minus smaller endpoint
    double s[3];     // +-1: orientation sign, negated when the edge was swapped
    bool tl[3];      // edge i owns centers exactly on it (top-left rule)
};

// Set up t from the voxel-space vertices; false when the triangle is parallel
// to x (zero projected area, including zero-area triangles): it flips nothing.
// exact: the normal and the edges, bit for bit glvox/reference/solid.py
bool solid_setup(vec3 p0, vec3 p1, vec3 p2, out SolidTri t) {
    dvec3 q0 = dvec3(p0), q1 = dvec3(p1), q2 = dvec3(p2);
    // cross(q1 - q0, q2 - q1) written out (a built-in is not covered by precise)
    precise dvec3 ea = q1 - q0, eb = q2 - q1;
    precise dvec3 n = dvec3(ea.y * eb.z - ea.z * eb.y, ea.z * eb.x - ea.x * eb.z, ea.x * eb.y - ea.y * eb.x);
    t.n = n;
    t.v0 = q0;
    t.lo = min(min(p0.yz, p1.yz), p2.yz);
    t.hi = max(max(p0.yz, p1.yz), p2.yz);
    t.xlo = min(min(p0.x, p1.x), p2.x);
    t.xhi = max(max(p0.x, p1.x), p2.x);
    if (t.n.x == 0.0lf) return false;
    double sgn = t.n.x > 0.0lf ? 1.0lf : -1.0lf;
    dvec2 v[3] = dvec2[3](q0.yz, q1.yz, q2.yz);
    for (int i = 0; i < 3; ++i) {
        dvec2 p = v[i], q = v[(i + 1) % 3];
        precise dvec2 e = q - p;
        // inward edge normal (-e_z, e_y) * sgn; only its signs matter
        precise double nu = -e.y * sgn, nv = e.x * sgn;
        t.tl[i] = nu > 0.0lf || (nu == 0.0lf && nv < 0.0lf);
        bool swap = p.x > q.x || (p.x == q.x && p.y > q.y);
        t.a[i] = swap ? q : p;
        precise dvec2 pq = p - q, qp = q - p;
        t.d[i] = swap ? pq : qp;
        t.s[i] = swap ? -sgn : sgn;
    }
    return true;
}

// Columns (j0, k0, j1, k1), inclusive, whose centers lie in t's (y, z)
// bounding box, clipped to the grid; empty when j0 > j1 or k0 > k1.
ivec4 solid_columns(SolidTri t, ivec3 dims) {
    ivec2 c0 = max(ivec2(ceil(t.lo - 0.5)), ivec2(0));
    ivec2 c1 = min(ivec2(floor(t.hi - 0.5)), dims.yz - 1);
    return ivec4(c0, c1);
}

// The edge function of the edge from a (its lexicographically smaller end
// point) along d, at c.  gwn-solid's strips (shaders/gwn/strip.glsl) call it
// too, so that they change sign on exactly the rows where a triangle's
// crossing starts or stops.
// exact: bit for bit glvox/reference/solid.py; opposite for the two triangles of an edge
double solid_edge_raw(dvec2 a, dvec2 d, dvec2 c) {
    precise dvec2 r = c - a;
    precise double f = d.x * r.y - d.y * r.x;
    return f;
}

// Edge function i at c, oriented so that the inside is positive.
// exact: a product by +-1
double solid_edge(SolidTri t, int i, dvec2 c) {
    precise double f = solid_edge_raw(t.a[i], t.d[i], c) * t.s[i];
    return f;
}

// Does the column center c = (y, z) lie in t's projection (top-left rule)?
bool solid_covers(SolidTri t, vec2 c) {
    dvec2 p = dvec2(c);
    for (int i = 0; i < 3; ++i) {
        double f = solid_edge(t, i, p);
        if (!(f > 0.0lf || (f == 0.0lf && t.tl[i]))) return false;
    }
    return true;
}

// Could any center of the box [c0, c1] of column centers lie in t's
// projection?  Each edge is evaluated at its critical center, the box corner
// farthest inside it (Sec. 4.2's tile test).  Conservative: a margin far
// above the rounding of solid_edge keeps every box that contains a covered
// center; a few extra boxes only cost a little work.
bool solid_may_cover(SolidTri t, vec2 c0, vec2 c1) {
    for (int i = 0; i < 3; ++i) {
        dvec2 n = dvec2(-t.d[i].y, t.d[i].x) * t.s[i];
        dvec2 p = dvec2(n.x > 0.0lf ? c1.x : c0.x, n.y > 0.0lf ? c1.y : c0.y);
        if (solid_edge(t, i, p) < -1e-6lf * (abs(n.x) + abs(n.y))) return false;
    }
    return true;
}

// The first voxel along x that the crossing at the covered center c flips:
// floor(q + 1/2); below 0 flips the whole column, at or past dims.x nothing.
// exact: the crossing, as the reference computes it
int solid_first_flip(SolidTri t, vec2 c) {
    dvec2 p = dvec2(c);
    precise double q = t.v0.x + (t.n.y * (t.v0.y - p.x) + t.n.z * (t.v0.z - p.y)) / t.n.x;
    // the exact crossing lies within the triangle's x extent; clamping only
    // removes rounding on nearly edge-on triangles (as the reference does)
    q = clamp(q, double(t.xlo), double(t.xhi));
    // far-away triangles (explicit bounds) must not overflow the int
    precise double first = floor(q + 0.5lf);
    return int(clamp(first, -1.0lf, 1073741824.0lf));
}
