// Triangle setup of Schwarz & Seidel Sec. 3.1 in voxel space (box extent 1).
// Needs common/voxel_space.glsl and common/edge.glsl.  SS_CRITERION selects
// the offsets: 0 conservative (Eq. 1-3), 1 6-separating (Sec. 3.4).

layout(std430, binding = 1) readonly buffer VoxVerts { float vox[]; };
layout(std430, binding = 2) readonly buffer Faces { uint faces[]; };

struct Tri {
    vec3 v0, v1, v2;
    vec3 n;        // cross(v1 - v0, v2 - v0), not normalized
    ivec3 lo, hi;  // touched voxels (closed boxes, Fig. 5a), clipped; lo > hi: outside the grid
    ivec3 ext;     // unclipped touched extent per axis, in voxels
};

vec3 vox_vertex(uint i) { return vec3(vox[3u * i], vox[3u * i + 1u], vox[3u * i + 2u]); }

Tri setup_triangle(uint t) {
    Tri T;
    T.v0 = vox_vertex(faces[3u * t]);
    T.v1 = vox_vertex(faces[3u * t + 1u]);
    T.v2 = vox_vertex(faces[3u * t + 2u]);
    T.n = cross(T.v1 - T.v0, T.v2 - T.v0);
    // clamp before the int conversion so far-away triangles cannot overflow it
    vec3 lim = vec3(u_dims) + 2.0;
    vec3 mn = clamp(min(min(T.v0, T.v1), T.v2), vec3(-2.0), lim);
    vec3 mx = clamp(max(max(T.v0, T.v1), T.v2), vec3(-2.0), lim);
    // voxel i touches [mn, mx] iff i <= mx and i + 1 >= mn
    ivec3 a = ivec3(ceil(mn)) - 1;
    ivec3 b = ivec3(floor(mx));
    T.ext = b - a + 1;
    T.lo = max(a, ivec3(0));
    T.hi = min(b, u_dims - 1);
    return T;
}

bool outside_grid(Tri T) { return any(greaterThan(T.lo, T.hi)); }

// 0: 1D bounding box (one voxel thick along >= 2 axes), 1: 2D, 2: 3D (Sec. 3.2).
int bbox_type(Tri T) {
    int thin = int(T.ext.x == 1) + int(T.ext.y == 1) + int(T.ext.z == 1);
    return thin >= 2 ? 0 : (thin == 1 ? 1 : 2);
}

int dominant_axis(vec3 n) {
    vec3 a = abs(n);
    return (a.x >= a.y && a.x >= a.z) ? 0 : (a.y >= a.z ? 1 : 2);
}

// The projection onto the coordinate plane (A, B) perpendicular to C, where
// (A, B, C) is a cyclic permutation of (x, y, z): the edge normals point into
// the projected triangle when oriented by the sign of n_C (Eq. 2).
struct Proj { vec2 n0, n1, n2; vec2 p0, p1, p2; float o0, o1, o2; };

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

// Eq. 3 for the box whose projection has minimum corner q.
bool proj_test(Proj P, vec2 q) {
    return dot(P.n0, q - P.p0) + P.o0 >= 0.0
        && dot(P.n1, q - P.p1) + P.o1 >= 0.0
        && dot(P.n2, q - P.p2) + P.o2 >= 0.0;
}

// Plane overlap (Eq. 1, or Sec. 3.4's 6-separating offsets) for the box with minimum corner p.
bool plane_test(Tri T, vec3 p) {
#if SS_CRITERION == 1
    float s = dot(T.n, p + 0.5 - T.v0);
    vec3 a = abs(T.n);
    return abs(s) <= 0.5 * max(a.x, max(a.y, a.z));
#else
    float s = dot(T.n, p - T.v0);
    vec3 pos = max(T.n, vec3(0.0));
    vec3 neg = min(T.n, vec3(0.0));
    return s + (pos.x + pos.y + pos.z) >= 0.0 && s + (neg.x + neg.y + neg.z) <= 0.0;
#endif
}
