// Triangle setup of Schwarz & Seidel Sec. 3.1 in voxel space (box extent 1).
// Needs common/voxel_space.glsl and common/edge.glsl.  SS_CRITERION selects
// the offsets: 0 conservative (Eq. 1-3), 1 6-separating (Sec. 3.4).

layout(std430, binding = 1) readonly buffer VoxVerts { float vox[]; };
layout(std430, binding = 2) readonly buffer Faces { uint faces[]; };

// The vertices are kept relative to an integer base point near the triangle
// (floor of v0): the tests then subtract small numbers, so float32 keeps
// about 1e-7 voxel of precision whatever the grid size, instead of the
// ~1e-4 voxel that absolute coordinates near 1024 would leave.
struct Tri {
    vec3 v0, v1, v2;  // relative to base
    ivec3 base;
    vec3 n;        // the cross product of its two shorter edges (setup_triangle), not normalized
    ivec3 lo, hi;  // touched voxels (closed boxes, Fig. 5a), clipped; lo > hi: outside the grid
    ivec3 ext;     // unclipped touched extent per axis, in voxels
    bool no_plane; // a sliver: its plane is rounding, only the projections decide
};

vec3 vox_vertex(uint i) { return vec3(vox[3u * i], vox[3u * i + 1u], vox[3u * i + 2u]); }

// exact: the triangle's normal and sliver bound (Eq. 1), see common/edge.glsl
Tri setup_triangle(uint t) {
    Tri T;
    vec3 a0 = vox_vertex(faces[3u * t]);
    vec3 a1 = vox_vertex(faces[3u * t + 1u]);
    vec3 a2 = vox_vertex(faces[3u * t + 2u]);
    // clamp before the int conversions so far-away triangles cannot overflow them
    precise vec3 lim = vec3(u_dims) + 2.0;
    T.base = ivec3(floor(clamp(a0, vec3(-2.0), lim)));
    vec3 b = vec3(T.base);  // subtracting an integer is exact here
    precise vec3 v0 = a0 - b, v1 = a1 - b, v2 = a2 - b;
    T.v0 = v0;
    T.v1 = v1;
    T.v2 = v2;
    // The normal from the two shorter edges: cross(v1 - v0, v2 - v1) = cross(v2 - v1, v0 - v2)
    // = cross(v0 - v2, v1 - v0).  Its rounding is about ulp * |e| |e'| of the pair, so two
    // long, nearly parallel edges of a needle (length 50, width 2e-3) would tilt its plane
    // by 0.03 voxel at the far end; the shorter pair keeps it to rounding.  Written out: a
    // built-in's inner operations are not an l-value's r-values (GLSL 4.50 Sec. 4.9)
    // (the lengths precise too, so that every conforming compiler picks the same pair)
    precise vec3 d0 = v1 - v0, d1 = v2 - v1, d2 = v0 - v2;
    precise float l0 = d0.x * d0.x + d0.y * d0.y + d0.z * d0.z;
    precise float l1 = d1.x * d1.x + d1.y * d1.y + d1.z * d1.z;
    precise float l2 = d2.x * d2.x + d2.y * d2.y + d2.z * d2.z;
    vec3 p = l0 >= l1 && l0 >= l2 ? d1 : (l1 >= l2 ? d2 : d0);
    vec3 q = l0 >= l1 && l0 >= l2 ? d2 : (l1 >= l2 ? d0 : d1);
    precise vec3 n = vec3(p.y * q.z - p.z * q.y, p.z * q.x - p.x * q.z, p.x * q.y - p.y * q.x);
    T.n = n;
    // A sliver: in each of the three projections the signed area n_c is within what
    // moving the vertices by SS_SLIVER_EPS voxel can change (the bound of
    // glvox.reference.ties.orientation_ambiguous, with half the tie epsilon, so that
    // every sliver here is a "free" sliver there, whose tie set holds every voxel its
    // projections allow).  Its normal is then mostly the float32 rounding of the
    // vertices, so S&S's plane test (Eq. 1) and the dominant axis of the columns are
    // rounding too; such a triangle gets the projection tests alone over its bounding
    // box, as a zero-area one does.  A triangle in a coordinate plane is no sliver
    // (its normal is exact), as in the reference.
    precise vec3 bound = 2.0 * SS_SLIVER_EPS * (abs(d0.yzx) + abs(d0.zxy) + abs(d2.yzx) + abs(d2.zxy))
               + 8.0 * SS_SLIVER_EPS * SS_SLIVER_EPS;
    bvec3 in_plane = bvec3(ivec3(equal(T.v0, T.v1)) * ivec3(equal(T.v1, T.v2)));
    T.no_plane = all(lessThanEqual(abs(T.n), bound)) && !any(in_plane);
    vec3 mn = clamp(min(min(a0, a1), a2), vec3(-2.0), lim);
    vec3 mx = clamp(max(max(a0, a1), a2), vec3(-2.0), lim);
    // voxel i touches [mn, mx] iff i <= mx and i + 1 >= mn
    precise ivec3 first = ivec3(ceil(mn)) - 1;
    ivec3 last = ivec3(floor(mx));
    precise ivec3 ext = last - first + 1;
    T.ext = ext;
    T.lo = max(first, ivec3(0));
    T.hi = min(last, u_dims - 1);
#ifdef VOX_SLAB
    // only this slab's voxels are visited; T.ext (the bounding-box type, the case
    // axis) stays the whole box's, so every voxel is decided as without slabs
    T.lo.z = max(T.lo.z, u_slab.x);
    T.hi.z = min(T.hi.z, u_slab.x + u_slab.y - 1);
#endif
    return T;
}

bool outside_grid(Tri T) { return any(greaterThan(T.lo, T.hi)); }

// 0: 1D bounding box (one voxel thick along >= 2 axes), 1: 2D, 2: 3D (Sec. 3.2).
int bbox_type(Tri T) {
    precise int thin = int(T.ext.x == 1) + int(T.ext.y == 1) + int(T.ext.z == 1);
    return thin >= 2 ? 0 : (thin == 1 ? 1 : 2);
}

int dominant_axis(vec3 n) {
    vec3 a = abs(n);
    return (a.x >= a.y && a.x >= a.z) ? 0 : (a.y >= a.z ? 1 : 2);
}

// The projection onto the coordinate plane (A, B) perpendicular to C, where
// (A, B, C) is a cyclic permutation of (x, y, z): the edge normals point into
// the projected triangle when oriented by the sign of n_C (Eq. 2).
struct Proj { vec2 n0, n1, n2; vec2 p0, p1, p2; float o0, o1, o2; ivec2 base; };

float edge_term(vec2 n) {
#if SS_CRITERION == 1
    return edge_box_term_6sep(n, vec2(1.0));
#else
    return edge_box_term_conservative(n, vec2(1.0));
#endif
}

Proj make_proj(Tri T, int A, int B, int C) {
    Proj P;
    float s = T.n[C] >= 0.0 ? 1.0 : -1.0;
    P.base = ivec2(T.base[A], T.base[B]);
    P.p0 = vec2(T.v0[A], T.v0[B]);
    P.p1 = vec2(T.v1[A], T.v1[B]);
    P.p2 = vec2(T.v2[A], T.v2[B]);
    P.n0 = edge_normal(P.p0, P.p1, s);
    P.n1 = edge_normal(P.p1, P.p2, s);
    P.n2 = edge_normal(P.p2, P.p0, s);
    P.o0 = edge_term(P.n0);
    P.o1 = edge_term(P.n1);
    P.o2 = edge_term(P.n2);
    return P;
}

// exact: one edge function of Eq. 3 at r, dot(n, r - p) + o, in this order
float proj_edge(vec2 n, vec2 r, vec2 p, float o) {
    precise vec2 d = r - p;
    precise float f = (n.x * d.x + n.y * d.y) + o;
    return f;
}

// Eq. 3 for the box whose projection has minimum corner q (absolute voxel indices).
// exact: see proj_edge
bool proj_test(Proj P, ivec2 q) {
    precise ivec2 rq = q - P.base;
    vec2 r = vec2(rq);
    return proj_edge(P.n0, r, P.p0, P.o0) >= 0.0
        && proj_edge(P.n1, r, P.p1, P.o1) >= 0.0
        && proj_edge(P.n2, r, P.p2, P.o2) >= 0.0;
}

// Plane overlap (Eq. 1, or Sec. 3.4's 6-separating offsets) for the box with
// minimum corner p (absolute voxel indices).
// exact: dot(n, p - v0) and the offsets written out, in this order
bool plane_test(Tri T, ivec3 voxel) {
    if (T.no_plane) return true;
    precise ivec3 pv = voxel - T.base;
    vec3 p = vec3(pv);
#if SS_CRITERION == 1
    precise vec3 d = p + 0.5 - T.v0;
    precise float s = T.n.x * d.x + T.n.y * d.y + T.n.z * d.z;
    vec3 a = abs(T.n);
    precise float lim = 0.5 * max(a.x, max(a.y, a.z));
    return abs(s) <= lim;
#else
    precise vec3 d = p - T.v0;
    precise float s = T.n.x * d.x + T.n.y * d.y + T.n.z * d.z;
    vec3 pos = max(T.n, vec3(0.0));
    vec3 neg = min(T.n, vec3(0.0));
    precise float hi = s + (pos.x + pos.y + pos.z);
    precise float lo = s + (neg.x + neg.y + neg.z);
    return hi >= 0.0 && lo <= 0.0;
#endif
}
