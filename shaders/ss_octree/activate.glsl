// Active level-1 nodes (Schwarz & Seidel 2010, Sec. 5.1): a conservative
// voxelization (Sec. 3.1-3.2) of the mesh into the grid of level-1 nodes
// (8^3 voxels each), modified so that it marks every node the later passes
// need:
//   * the triangle is shifted by +1/2 voxel (a level-0 sub-grid voxel) in x:
//     a crossing at x = q flips voxels from floor(q + 1/2), which lies in
//     node floor((q + 1/2) / 8);
//   * node a's box is enlarged by one voxel in +x, [8a, 8a + 9] instead of
//     [8a, 8a + 8] (the paper's bounding box grown by one voxel in -x with
//     the critical points on the max x face moved by one voxel), so the
//     node before a crossing's node is active too and the boundary of the
//     solid consists of level-0 nodes only;
//   * glvox adds OCT_MARGIN below 8a: the crossings come from ss/solid.glsl's
//     double arithmetic, this test is float32, and a crossing that lands
//     exactly on a node's -x face must still find its node.
// Items: the mesh's triangles, then two triangles per wall.  A wall is the
// +x extrusion (to beyond the grid) of an open boundary edge of the mesh:
// across it the parity of crossings changes without any triangle there, so
// its nodes must be refined too (see glvox/methods/ss_octree.py).
// Needs common/edge.glsl, ss/solid_input.glsl (vox_vertex, faces), ss_octree/common.glsl.

const float OCT_MARGIN = 1.0 / 16.0;
// Widening of the plane's depth range in a column: float32 rounding there
// must not drop a node (extra nodes are harmless).
const float OCT_W_EPS = 1.0 / 64.0;

layout(std430, binding = 3) readonly buffer Walls { uint walls[]; };  // vertex index pairs
uniform uint u_triangles;
uniform uint u_walls;
uniform ivec3 u_n1;  // level-1 nodes covering the grid, ceil(dims / 8)

struct ATri {
    vec3 v0, v1, v2;  // shifted, relative to base
    ivec3 base;
    vec3 n;           // cross(v1 - v0, v2 - v0)
    ivec3 lo, hi;     // candidate nodes (lo > hi: none)
    bool every;       // mark every candidate node without tests
};

void item_vertices(uint item, out vec3 a0, out vec3 a1, out vec3 a2) {
    if (item < u_triangles) {
        a0 = vox_vertex(faces[3u * item]);
        a1 = vox_vertex(faces[3u * item + 1u]);
        a2 = vox_vertex(faces[3u * item + 2u]);
        return;
    }
    uint h = item - u_triangles, e = h >> 1;
    vec3 a = vox_vertex(walls[2u * e]), b = vox_vertex(walls[2u * e + 1u]);
    float far = float(8 * u_n1.x + 16);
    vec3 af = vec3(max(far, a.x + 1.0), a.yz), bf = vec3(max(far, b.x + 1.0), b.yz);
    if ((h & 1u) == 0u) { a0 = a; a1 = b; a2 = bf; } else { a0 = a; a1 = bf; a2 = af; }
}

// Node range along an axis touched by the interval [lo, hi] (absolute,
// shifted voxel space).  x boxes are [8a - OCT_MARGIN, 8a + 9], y and z
// boxes [8b, 8b + 8].
ivec2 node_range(int axis, float lo, float hi) {
    ivec2 r = axis == 0 ? ivec2(ceil((lo - 9.0) * 0.125), floor((hi + OCT_MARGIN) * 0.125))
                        : ivec2(ceil((lo - 8.0) * 0.125), floor(hi * 0.125));
    return ivec2(max(r.x, 0), min(r.y, u_n1[axis] - 1));
}

// Lower corner (relative to T.base) and extent of node i's box along axis.
vec2 node_box(ATri T, int axis, int i) {
    float lo = float(8 * i - T.base[axis]);
    return axis == 0 ? vec2(lo - OCT_MARGIN, 9.0 + OCT_MARGIN) : vec2(lo, 8.0);
}

ATri activation_setup(uint item) {
    vec3 a0, a1, a2;
    item_vertices(item, a0, a1, a2);
    vec3 shift = vec3(0.5, 0.0, 0.0);
    a0 += shift;
    a1 += shift;
    a2 += shift;
    // clamped before the int conversions, so far-away vertices cannot overflow them
    vec3 lim = vec3(8 * u_n1) + 32.0;
    ATri T;
    T.base = ivec3(floor(clamp(a0, -lim, lim)));
    vec3 b = vec3(T.base);
    T.v0 = a0 - b;
    T.v1 = a1 - b;
    T.v2 = a2 - b;
    T.n = cross(T.v1 - T.v0, T.v2 - T.v0);
    vec3 mn = clamp(min(min(a0, a1), a2), -lim, lim);
    vec3 mx = clamp(max(max(a0, a1), a2), -lim, lim);
    ivec2 rx = node_range(0, mn.x, mx.x), ry = node_range(1, mn.y, mx.y), rz = node_range(2, mn.z, mx.z);
    // A crossing left of the grid (q < -1/2, only with explicit bounds) flips
    // whole columns from voxel 0: node 0 then needs every column of the
    // triangle's (y, z) range, which the bounding box gives.
    bool left = mn.x < 0.0;
    if (left && rx.y < 0 && u_n1.x > 0) rx.y = 0;
    T.lo = ivec3(rx.x, ry.x, rz.x);
    T.hi = ivec3(rx.y, ry.y, rz.y);
    T.every = left || all(equal(T.n, vec3(0.0)));
    return T;
}

int dominant_axis(vec3 n) {
    vec3 a = abs(n);
    return (a.x >= a.y && a.x >= a.z) ? 0 : (a.y >= a.z ? 1 : 2);
}

// Work units of an item: candidate nodes (every) or candidate columns along
// the dominant axis; 0 when none.
uint activation_units(ATri T) {
    if (any(greaterThan(T.lo, T.hi))) return 0u;
    uvec3 s = uvec3(T.hi - T.lo + 1);
    if (T.every) return s.x * s.y * s.z;
    int w = dominant_axis(T.n);
    return s[(w + 1) % 3] * s[(w + 2) % 3];
}

// The projection onto the plane (A, B) perpendicular to C (Eq. 2), edge
// normals oriented inwards by the sign of n_C.
struct Proj { vec2 n0, n1, n2; vec2 p0, p1, p2; };

Proj make_proj(ATri T, int A, int B, int C) {
    Proj P;
    float s = T.n[C] >= 0.0 ? 1.0 : -1.0;
    P.p0 = vec2(T.v0[A], T.v0[B]);
    P.p1 = vec2(T.v1[A], T.v1[B]);
    P.p2 = vec2(T.v2[A], T.v2[B]);
    P.n0 = edge_normal(P.p0, P.p1, s);
    P.n1 = edge_normal(P.p1, P.p2, s);
    P.n2 = edge_normal(P.p2, P.p0, s);
    return P;
}

// Eq. 3 for the 2D box [lo, lo + d] (relative coordinates).
bool proj_box(Proj P, vec2 lo, vec2 d) {
    return dot(P.n0, lo - P.p0) + edge_box_term_conservative(P.n0, d) >= 0.0
        && dot(P.n1, lo - P.p1) + edge_box_term_conservative(P.n1, d) >= 0.0
        && dot(P.n2, lo - P.p2) + edge_box_term_conservative(P.n2, d) >= 0.0;
}

ivec3 compose(int u, int v, int w, int iu, int iv, int iw) {
    ivec3 p;
    p[u] = iu;
    p[v] = iv;
    p[w] = iw;
    return p;
}
