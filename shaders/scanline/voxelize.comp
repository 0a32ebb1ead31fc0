#version 450
// Projected optimal scanline surface voxelization (Zhang et al. 2018, Sec. 4
// and Alg. 1): one invocation per triangle, atomicOr into the packed grid.
// The same algorithm, step for step, as glvox/reference/scanline.py; its
// docstring explains the conventions (the paper's lattice vs voxel space),
// the float and integer paths and the tunnel variants.
//
// Defines (set by glvox/methods/scanline.py):
//   LINE_MODE   0 RLV, 1 SLV (float path), 2 ILV (integer path)
//   TUNNEL      26, 18 or 6
//   PASS        0 all triangles, 1 measure, 2 draw parts (budget.glsl); in PASS 0
//               out_words[1] counts ILV triangles refused for ILV_COORD_LIMIT;
//               3 (ILV) builds the small-triangle table (below)
//   SMALL_TABLE 1 (ILV, PASS 0): a triangle whose lattice points lie in a 4 x 4 x 4
//               block takes its voxels from the table; the others are listed
//               in Scan for the scan, which a second dispatch of PASS 0 with
//               FROM_LIST 1 runs over them (scanline/scan_args.comp sizes it)
//   LOCAL_SIZE  work group size
//   SCANLINE_SLACK, ILV_COORD_LIMIT, ILV_BOUNDARY_SNAP, RLV_BOUNDARY_SNAP
//               (constants of the CPU module)
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
#include "common/snap.glsl"

layout(local_size_x = LOCAL_SIZE) in;
#include "common/dispatch.glsl"

layout(std430, binding = 0) readonly buffer Vertices { float verts[]; };
layout(std430, binding = 1) readonly buffer Faces { uint faces[]; };
layout(std430, binding = 2) buffer Grid { uint grid[]; };
layout(std430, binding = 3) buffer Out { uint out_words[]; };
layout(std430, binding = 4) readonly buffer Items { uvec4 items[]; };  // PASS 1, 2: (triangle, lo, hi, -)
#if PASS == 3 || SMALL_TABLE
// Bit x + 4 y + 16 z (of .x below 32, else of .y) of the entry of the ILV triangle
// P0 P1 P2 (small_index): voxel lo + (x, y, z), lo its lattice box's low corner, as the
// scan below draws it.
layout(std430, binding = 5) buffer Table { uvec2 small_table[]; };
#endif
#if SMALL_TABLE || FROM_LIST
// The triangles the table pass leaves to the scan, so that the scan's long loops
// run in batches (warps) of such triangles only; scan_args: the scan's indirect
// dispatch.
layout(std430, binding = 6) buffer Scan { uint scan_n; uint scan_args[3]; uint scan_list[]; };
#endif

uniform uint u_count;   // triangles (PASS 0) or items (PASS 1, 2)
uniform uint u_budget;  // loop iterations this invocation may charge (budget.glsl)

#include "scanline/budget.glsl"
#include "scanline/lines.glsl"

// Vertex i in voxel space: the one transform of every method (double, plane
// snap, then float32: common/snap.glsl), which the CPU repeats exactly
// (glvox.methods.scanline.voxelize.gpu_voxel_coords).
uniform dvec3 u_origin_d;
uniform double u_inv_h_d;
vec3 vertex(uint i) {
    vec3 p = vec3(verts[3u * i], verts[3u * i + 1u], verts[3u * i + 2u]);
    return vec3(vertex_to_voxel(p, u_origin_d, u_inv_h_d));
}

// Largest |n| component; ties prefer z, then y, then x.
int dominant(vec3 n) {
    vec3 m = abs(n);
    if (m.z >= m.x && m.z >= m.y) return 2;
    return m.y >= m.x ? 1 : 0;
}

int dominant(dvec3 n) {
    dvec3 m = abs(n);
    if (m.z >= m.x && m.z >= m.y) return 2;
    return m.y >= m.x ? 1 : 0;
}

int dominant(ivec3 n) {
    ivec3 m = abs(n);
    if (m.z >= m.x && m.z >= m.y) return 2;
    return m.y >= m.x ? 1 : 0;
}

// ---------------------------------------------------------------------------
// Float path (RLV, SLV)

// A line of the float path, clipped to the grid grown by one voxel.  `ends`:
// SLV marks the voxels incident to its end points (draw_float).
void float_line(vec3 p, vec3 q, bool ends, bool reduce, int a, int b, float pa, float pb) {
    vec3 cp, cq;
    if (!clip_segment(p, q, vec3(-1.0), vec3(u_dims) + 1.0, cp, cq)) return;
    draw_float(cp, cq, LINE_MODE == 1 && !reduce, ends, reduce, a, b, pa, pb);
}

// Edges go from their lexicographically smaller end: the ends chosen by a
// select and one call, since llvmpipe runs both sides of a branch under
// masks, and a call on each side cost two lines (docs/methods/scanline.md).
// Their end points' voxels are not marked here: SLV's float_triangle marks
// each vertex's incident voxels once for its two edges.  An end point the
// clip moved lies on the grown grid's face, whose incident voxels are all
// outside the grid, so nothing is lost.
void float_edge(vec3 p, vec3 q) {
    bool swap = lex_less(q, p);
    float_line(swap ? q : p, swap ? p : q, false, false, 0, 1, 0.0, 0.0);
}

bool key_less(float sa, int ia, float sb, int ib) { return sa < sb || (sa == sb && ia < ib); }

// exact: the tunnel variants are nested only if every variant rounds alike
void float_triangle(vec3 P0, vec3 P1, vec3 P2) {
    vec3 lo = min(P0, min(P1, P2));
    vec3 hi = max(P0, max(P1, P2));
    if (any(lessThan(hi, vec3(0.0))) || any(greaterThan(lo, vec3(u_dims)))) return;
#if LINE_MODE == 1
    // SLV: the voxels incident to the vertices, once for the two edges at each
    // (float_edge leaves them out), charged for their boxes' corner loops
    if (!tick(3u * MARK_BOX_COST)) return;
#if PASS != 1
    mark_incident(P0);
    mark_incident(P1);
    mark_incident(P2);
#endif
#endif
    float_edge(P0, P1);
    float_edge(P1, P2);
    float_edge(P2, P0);
    // The normal in double: in float32 its error is ulp * |e|^2, which for a thin
    // triangle tilts the iso-w lines enough to draw scanlines in the wrong layer;
    // in double from the float32 vertices it is the CPU's float64 normal.
    precise dvec3 e1 = dvec3(P1) - dvec3(P0);
    precise dvec3 e2 = dvec3(P2) - dvec3(P0);
    precise dvec3 nd = dvec3(e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z, e1.x * e2.y - e1.y * e2.x);
    if (all(equal(nd, dvec3(0.0lf)))) return;
    int w = dominant(nd);
    int a = (w + 1) % 3, b = (w + 2) % 3;
    float ga = float(nd[a]), gb = float(nd[b]), nw = float(nd[w]);
    bool level_plane = nd[a] == 0.0lf && nd[b] == 0.0lf;  // parallel to the slicing plane: scan along a
    if (level_plane) ga = 1.0;
    // sweep coordinate s = g . (p - P0) of the projection; sort the vertices on (s, index)
    vec3 P[3] = vec3[3](P0, P1, P2);
    precise float S1 = ga * (P1[a] - P0[a]) + gb * (P1[b] - P0[b]);
    precise float S2 = ga * (P2[a] - P0[a]) + gb * (P2[b] - P0[b]);
    float S[3] = float[3](0.0, S1, S2);
    int o0 = 0, o1 = 1, o2 = 2, t;
    if (key_less(S[o1], o1, S[o0], o0)) { t = o0; o0 = o1; o1 = t; }
    if (key_less(S[o2], o2, S[o1], o1)) { t = o1; o1 = o2; o2 = t; }
    if (key_less(S[o1], o1, S[o0], o0)) { t = o0; o0 = o1; o1 = t; }
    vec3 q0 = P[o0], q1 = P[o1], q2 = P[o2];
    float s0 = S[o0], s1 = S[o1], s2 = S[o2];
    if (s2 <= s0) return;  // projection degenerate in float: the edges are all there is
    // layers: RLV floor(w_min) .. floor(w_max); SLV also the one a vertex on a plane w = k touches
    float kmax = float(u_dims[w]) + 1.0;
    float wlo = clamp(lo[w], -2.0, kmax), whi = clamp(hi[w], -2.0, kmax);
    int kfirst = LINE_MODE == 1 ? int(ceil(wlo)) - 1 : cell1(wlo, u_dims[w]);
    int klast = LINE_MODE == 1 ? int(floor(whi)) : cell1(whi, u_dims[w]);
    int k0 = max(kfirst, 0), k1 = min(klast, u_dims[w] - 1);
    precise float ds_max = (abs(ga) + abs(gb)) * SCANLINE_SLACK;  // Theorem 4.1 in s units
    float w0 = P0[w];
    vec2 h = level_plane ? vec2(1.0, 0.0) : (nw > 0.0 ? vec2(-ga, -gb) : vec2(ga, gb));  // towards w + 1
    // s-range of the grid rectangle grown by one voxel: other levels draw nothing
    float ra0 = -1.0 - P0[a], ra1 = float(u_dims[a]) + 1.0 - P0[a];
    float rb0 = -1.0 - P0[b], rb1 = float(u_dims[b]) + 1.0 - P0[b];
    precise float r_lo = min(ga * ra0, ga * ra1) + min(gb * rb0, gb * rb1);
    precise float r_hi = max(ga * ra0, ga * ra1) + max(gb * rb0, gb * rb1);
    precise float s_prev = level_plane ? s0 : clamp(-nw * (float(k0) - w0), s0, s2);
    // Every layer's scanlines in one loop, not a loop per layer: a SIMD batch
    // (a warp) then runs the most scanlines any of its triangles has, not the
    // sum over the layers of the most any has in the layer.
    int k = k0 - 1, i = 0, count = -1;
    float s_start = 0.0, s_end = 0.0, span = 0.0, N = 0.0, m_lo = 0.0, wk = 0.0;
    bool below = false;
    for (;;) {
        if (i > count) {  // layer k done: set up the next one
            k += 1;
            if (k > k1) break;
            s_start = level_plane ? s0 : s_prev;
            precise float s_k = level_plane ? s2 : clamp(-nw * (float(k + 1) - w0), s0, s2);
            s_end = s_k;
            s_prev = s_end;
            span = s_end - s_start;
            N = span == 0.0 ? 0.0 : ceil(abs(span) / ds_max);
            m_lo = 0.0;
            float m_hi = N;
            if (N > 0.0) {
                precise float u0 = (r_lo - s_start) / span * N, u1 = (r_hi - s_start) / span * N;
                m_lo = clamp(floor(min(u0, u1)) - 1.0, 0.0, N);
                m_hi = clamp(ceil(max(u0, u1)) + 1.0, 0.0, N);
            }
            wk = float(k) + 0.5;
            below = k > kfirst && !level_plane;
            count = int(m_hi - m_lo);
            i = 0;
        }
        if (!tick(2u)) break;  // 1 + the draw loop inside
        float m = m_lo + float(i);
        i += 1;
        bool base = m == 0.0 && below;  // the bottom copy of the base edge shared with layer k - 1
        if (base && TUNNEL == 6) continue;
        precise float s = m == 0.0 ? s_start : (m == N ? s_end : s_start + span * m / N);
        float ta = clamp((s - s0) / (s2 - s0), 0.0, 1.0);
        precise vec2 A = vec2(q0[a] + ta * (q2[a] - q0[a]), q0[b] + ta * (q2[b] - q0[b]));
        precise vec2 B;
        if (s < s1) {
            float tb = clamp((s - s0) / (s1 - s0), 0.0, 1.0);
            B = vec2(q0[a] + tb * (q1[a] - q0[a]), q0[b] + tb * (q1[b] - q0[b]));
        } else {
            float tb = s2 == s1 ? 0.0 : clamp((s - s1) / (s2 - s1), 0.0, 1.0);
            B = vec2(q1[a] + tb * (q2[a] - q1[a]), q1[b] + tb * (q2[b] - q1[b]));
        }
        vec3 p, q;
        p[a] = A.x; p[b] = A.y; p[w] = wk;
        q[a] = B.x; q[b] = B.y; q[w] = wk;
        bool reduce = base && TUNNEL == 18;
        vec2 side = vec2(0.0);
        if (reduce) {
            side = vec2(-(B.y - A.y), B.x - A.x);
            precise float sh = side.x * h.x + side.y * h.y;
            if (sh < 0.0) side = -side;
        }
        float_line(p, q, true, reduce, a, b, side.x, side.y);
    }
}

// ---------------------------------------------------------------------------
// Integer path (ILV)

// Alg. 1 GetVoxel for one coordinate: floor, with a coordinate just outside
// the grid snapped to its boundary voxel (lattice_points in the CPU module).
int lattice1(float x, int n) {
    if (x >= float(n) && x <= float(n) + ILV_BOUNDARY_SNAP) return n - 1;
    if (x < 0.0 && x >= -ILV_BOUNDARY_SNAP) return 0;
    return int(floor(clamp(x, -1.0e9, 1.0e9)));
}

ivec3 lattice(vec3 x) {
    return ivec3(lattice1(x.x, u_dims.x), lattice1(x.y, u_dims.y), lattice1(x.z, u_dims.z));
}

// exact: integers (precise for the convention's sake: no fma in ints)
ivec3 icross(ivec3 u, ivec3 v) {
    precise ivec3 r = ivec3(u.y * v.z - u.z * v.y, u.z * v.x - u.x * v.z, u.x * v.y - u.y * v.x);
    return r;
}

// A side-edge voxel chain: the ILV path p -> m, then m -> q, one path at a time
// (the second begins where the first ends, so it is set up on reaching m and
// each step takes one axis choice).  seg 0: on p -> m with steps left; 1: at m,
// on m -> q and not moved on it yet; 2: past m.
struct Chain {
    Ilv cur;
    ivec3 q;
    int seg;
};

// After a step: past m, or on reaching m the second path set up.
void chain_stepped(inout Chain c) {
    if (c.seg == 1) c.seg = 2;
    if (c.seg == 0 && c.cur.left == ivec3(0)) {
        c.cur = ilv_path(c.cur.p, c.q);
        c.seg = 1;
    }
}

Chain chain_begin(ivec3 p, ivec3 m, ivec3 q) {
    Chain c;
    c.cur = ilv_path(p, m);
    c.q = q;
    c.seg = 0;
    if (p == m) {
        c.cur = ilv_path(m, q);
        c.seg = 1;
    }
    return c;
}

ivec3 chain_pos(Chain c) { return c.cur.p; }

bool chain_next(inout Chain c) {
    int ax = ilv_axis_plain(c.cur);
    if (ax < 0) return false;
    ilv_step(c.cur, ax);
    chain_stepped(c);
    return true;
}

// One side of a slice's scan: its chain within layer Z, `left` more entries
// of it in the layer (counted by the look-ahead), or, once the chain ran out
// first (ext), the slice's top base edge towards the other chain's end, in c.cur.
struct Side {
    Chain c;
    bool ext;
    int left;
};

ivec3 side_pos(Side s) { return s.c.cur.p; }

// One step within layer Z (a base edge never leaves it); false, and s as it
// was, where there is none.
bool side_advance(inout Side s, int w, int Z) {
    Ilv t = s.c.cur;
    int ax = ilv_axis(t);  // the base edge's tie where it is one (a chain's path never is)
    if (ax < 0) return false;
    ilv_step(t, ax);
    if (t.p[w] != Z) return false;
    s.c.cur = t;
    if (!s.ext) {
        chain_stepped(s.c);
        s.left -= 1;
    }
    return true;
}

// side_advance would fail: the chain's last entry in the layer, the base edge's end.
bool side_done(Side s) { return s.ext ? s.c.cur.left == ivec3(0) : s.left == 0; }

// Eq. 8-9: the farthest next entry strictly within d^ of the scanline through
// A and B, the first entry always taken; a chain may stop at its bend P1
// (the end of its first edge) but not pass it (see the CPU module docstring).
void side_select(inout Side s, int w, int Z, int a, int b, int dX, int dY, int c0, int tol) {
    bool before_bend = !s.ext && s.c.seg == 0;
    bool first = true;
    for (;;) {
        if (!tick(1u)) break;
        Side t = s;
        if (!side_advance(t, w, Z)) break;
        if (before_bend && t.c.seg == 2) break;
        ivec3 c = side_pos(t);
        if (!first && abs(dY * c[a] - dX * c[b] - c0) >= tol) break;
        s = t;
        first = false;
    }
}

// The lattice triangle's plane (through the voxel centres): a vertex and the normal.
ivec3 g_Q0, g_n;
int g_w, g_a, g_b;

// 2 n_w (h - K), h the lattice plane's w at the centre of c's column: twice the
// plane equation, exact in double (the products reach ~1e14).
double plane_height(ivec3 c, int K) {
    double nw = double(g_n[g_w]);
    return 2.0lf * double(g_Q0[g_w] - K) * nw + nw
         - 2.0lf * (double(g_n[g_a]) * double(c[g_a] - g_Q0[g_a]) + double(g_n[g_b]) * double(c[g_b] - g_Q0[g_b]));
}

// The lattice plane lies at w >= K at the centre of c's column.
bool plane_above(ivec3 c, int K) {
    double e = plane_height(c, K);
    return g_n[g_w] > 0 ? e >= 0.0lf : e <= 0.0lf;
}

// A base edge on the plane w = K passing a voxel edge: step into the candidate
// whose column centre has the lattice plane nearer w = K (> 0: c2, < 0: c1,
// 0: the default order; base_tie in the CPU module's _ilv_triangle).
int base_tie(ivec3 c1, ivec3 c2, int K) {
    double d = abs(plane_height(c1, K)) - abs(plane_height(c2, K));
    return d > 0.0lf ? 1 : (d < 0.0lf ? -1 : 0);
}

// ILV tunnel 18 / 6: keep this copy of a base-edge voxel (bottom: the copy in
// layer K of the edge between layers K - 1 and K)?  Where the plane lies in
// its layer at the centre of its column; for 18 also at a 4-neighbouring one
// (_keep_copy in the CPU module).
bool keep_copy(ivec3 c, int K, bool bottom) {
    if (plane_above(c, K) == bottom) return true;
    if (TUNNEL != 18) return false;
    ivec3 ea = ivec3(0), eb = ivec3(0);
    ea[g_a] = 1;
    eb[g_b] = 1;
    return plane_above(c - ea, K) == bottom || plane_above(c + ea, K) == bottom
        || plane_above(c - eb, K) == bottom || plane_above(c + eb, K) == bottom;
}

// One ILV scanline in layer Z, skipped when it lies outside the grid's (a, b)
// rectangle; `base`: a base edge on the plane w = K.
void scan_draw(ivec3 L0, ivec3 L1, int keep, int K, bool base, int a, int b) {
    if (max(L0[a], L1[a]) < 0 || min(L0[a], L1[a]) >= u_dims[a]
            || max(L0[b], L1[b]) < 0 || min(L0[b], L1[b]) >= u_dims[b]) return;
    draw_ilv(L0, L1, keep, K, base);
}

// Scan one slice (layer Z): bottom base edge, Eq. 8-9 scanlines, top base edge.
// One loop with a single draw call (each draw call is a loop to charge).
void ilv_slice(Chain ca, Chain cb, int na, int nb, ivec3 A_last, ivec3 B_last, bool below, bool above,
               int w, int Z, int a, int b) {
    Side sa, sb;
    sa.c = ca; sa.ext = false; sa.left = na;
    sb.c = cb; sb.ext = false; sb.left = nb;
    ivec3 lastA = chain_pos(ca), lastB = chain_pos(cb);  // the last scanline drawn
    int phase = 0;  // 0 bottom base, 1 scanning, 2 top base drawn: done
    for (;;) {
        if (!tick(4u)) break;  // 1 + the two selection loops and the draw loop inside
        ivec3 L0 = lastA, L1 = lastB;
        bool draw = true;
        int keep = 0, K = Z;  // keep: 1 bottom base edge copy, 2 top one (tunnel 18 / 6)
        bool base = true;     // a base edge, on the plane w = K (its ties: base_tie)
        if (phase == 0) {
            keep = below && TUNNEL != 26 ? 1 : 0;
            phase = 1;
        } else {
            bool a_done = side_done(sa);
            bool b_done = side_done(sb);
            bool stop = false;
            if (a_done || b_done) {
                ivec3 ea = sa.ext ? B_last : A_last;
                ivec3 eb = sb.ext ? A_last : B_last;
                // boundary treatment: the top base edge becomes the exhausted side;
                // where both sides end in the same voxel, the exhausted side stays (a fan)
                if (a_done && b_done) {
                    stop = true;
                } else if (a_done && ea != eb) {  // the side stands at A_last
                    sa.ext = true;
                    sa.c.cur = ilv_base(A_last, B_last, Z + 1);
                } else if (b_done && ea != eb) {
                    sb.ext = true;
                    sb.c.cur = ilv_base(B_last, A_last, Z + 1);
                }
            }
            if (stop) {
                L0 = A_last;
                L1 = B_last;
                draw = !(lastA == A_last && lastB == B_last);
                phase = 2;
                keep = above && TUNNEL != 26 ? 2 : 0;
                K = Z + 1;
            } else {
                ivec3 A = side_pos(sa), B = side_pos(sb);
                // where A == B (Eq. 6 is 0/0) dX = dY = tol = 0: each side takes its
                // next entry alone, the second failing |0| < 0
                int dX = A[a] - B[a], dY = A[b] - B[b];
                int c0 = dY * A[a] - dX * A[b];
                int tol = abs(dX) + abs(dY);
                side_select(sa, w, Z, a, b, dX, dY, c0, tol);
                side_select(sb, w, Z, a, b, dX, dY, c0, tol);
                L0 = side_pos(sa);
                L1 = side_pos(sb);
                lastA = L0;
                lastB = L1;
                base = L0 == A_last && L1 == B_last;  // the top base edge
                if (base) {
                    K = Z + 1;
                    if (above && TUNNEL != 26) keep = 2;
                }
            }
        }
        if (draw) scan_draw(L0, L1, keep, K, base, a, b);
        if (phase == 2 || g_abort) break;
    }
}

// ---------------------------------------------------------------------------
// Small triangles by table
//
// ILV is integer from the lattice points on, and nothing it decides depends on
// where the triangle lies or on the order of its vertices: moved by whole
// voxels, it draws the same voxels moved alike (the grid only clips them), and
// its edges, normal axis and sorted slices are the same in any vertex order.  So
// the voxels of every set of three corners of a 4 x 4 x 4 block whose lowest x,
// y and z are 0 (8,614 sets; a lookup is relative to the low corner of the
// triangle's lattice box) are drawn once, by the scan itself, into a table of
// C(66, 3) = 45,760 slots, one per sorted triple (PASS 3, once per context and
// tunnel).  A triangle whose lattice points fit in such a block (nearly all of
// a fine mesh's up to 256^3) reads its block from it: no scan, only a loop over
// the rows that hold voxels, one atomicOr per word of each (mark_small).

uint small_corner(ivec3 d) { return uint(d.x + 4 * d.y + 16 * d.z); }

// The entry of corners c0, c1, c2 in any order: sorted, their rank among the
// sorted triples (the combinatorial number system with repeats).
uint small_index(uint c0, uint c1, uint c2) {
    uint lo = min(c0, min(c1, c2)), hi = max(c0, max(c1, c2));
    uint mid = c0 + c1 + c2 - lo - hi;
    return hi * (hi + 1u) * (hi + 2u) / 6u + mid * (mid + 1u) / 2u + lo;
}

#if SMALL_TABLE
// Voxels v + (i, 0, 0) for the set bits i < 4 of `bits`, clipped to the grid.
// A row of 4 voxels spans at most two words; v.x >= -3 (the block meets the grid).
void mark_row4(ivec3 v, uint bits) {
    if (bits == 0u || v.y < 0 || v.y >= u_dims.y || v.z < 0 || v.z >= u_dims.z) return;
    if (v.x < 0) bits &= mask_from(uint(-v.x));                   // voxels from x = 0 on
    int over = v.x + 4 - u_dims.x;
    if (over > 0) bits &= ~mask_from(uint(max(4 - over, 0)));     // voxels before x = nx
    if (bits == 0u) return;
    // voxel x lies in word x >> 5 at bit x & 31 (for x < 0 too, in two's complement);
    // the bits of voxels below 0 are cleared above, so word -1 never gets any
    uint s = uint(v.x) & 31u;
    uint row = word_index(ivec3(0, v.y, v.z));
    int w = v.x >> 5;
    uint first = bits << s, second = s == 0u ? 0u : bits >> (32u - s);
    if (first != 0u) atomicOr(grid[row + uint(w)], first);
    if (second != 0u) atomicOr(grid[row + uint(w + 1)], second);
}

// Bit r of the result: nibble r (bits 4 r .. 4 r + 3) of w is not 0.
uint nonzero_nibbles(uint w) {
    uint t = w | (w >> 1);
    t = (t | (t >> 2)) & 0x11111111u;   // bit 4 r
    t = (t | (t >> 3)) & 0x03030303u;   // gathered: bits 0-1 of each byte
    t = (t | (t >> 6)) & 0x000F000Fu;   // bits 0-3 of each half
    return (t | (t >> 12)) & 0xFFu;
}

// The entry's voxels: row r = y + 4 z of the block holds bits 4 r .. 4 r + 3,
// of .x for r < 8.  A loop over the rows that hold any (a small triangle's
// few), not the sixteen rows written out: llvmpipe runs every mark site
// under masks, and an atomicOr site steps through the batch's lanes.  Loop
// iterations: 1 + up to 16 (SMALL_COST).
const uint SMALL_COST = 17u;

void mark_small(ivec3 lo, uvec2 m) {
    uint rows = nonzero_nibbles(m.x) | (nonzero_nibbles(m.y) << 8u);
    while (rows != 0u) {
        uint r = uint(findLSB(rows));
        rows &= rows - 1u;
        mark_row4(lo + ivec3(0, int(r & 3u), int(r >> 2u)), ((r < 8u ? m.x : m.y) >> (4u * (r & 7u))) & 15u);
    }
}
#endif

// ---------------------------------------------------------------------------

void ilv_scan(ivec3 P0, ivec3 P1, ivec3 P2);

// The ILV voxels of the triangle X0 X1 X2, or nothing where it is refused or
// outside the grid.  With SMALL_TABLE a small one is drawn from the table and
// the others are not drawn: true, they are left to the scan.
bool ilv_triangle(vec3 X0, vec3 X1, vec3 X2) {
    ivec3 P0 = lattice(X0), P1 = lattice(X1), P2 = lattice(X2);
    ivec3 lo = min(P0, min(P1, P2)), hi = max(P0, max(P1, P2));
    if (any(lessThan(hi, ivec3(0))) || any(greaterThanEqual(lo, u_dims))) return false;
    ivec3 big = max(abs(lo), abs(hi));
    if (max(big.x, max(big.y, big.z)) > ILV_COORD_LIMIT) {  // int32 would overflow: refused
#if PASS == 0
        atomicAdd(out_words[1], 1u);
#endif
        return false;
    }
#if SMALL_TABLE
    if (all(lessThanEqual(hi - lo, ivec3(3)))) {
        if (tick(SMALL_COST))
            mark_small(lo, small_table[small_index(small_corner(P0 - lo), small_corner(P1 - lo), small_corner(P2 - lo))]);
        return false;
    }
    return true;
#else
    ilv_scan(P0, P1, P2);
    return false;
#endif
}

// The ILV voxels of the lattice triangle P0 P1 P2 (edges, then the slices' scans).
void ilv_scan(ivec3 P0, ivec3 P1, ivec3 P2) {
    draw_ilv(P0, P1, 0, 0, false);
    draw_ilv(P1, P2, 0, 0, false);
    draw_ilv(P2, P0, 0, 0, false);
    ivec3 n = icross(P1 - P0, P2 - P0);
    if (n == ivec3(0)) return;
    int w = dominant(n);
    int a = (w + 1) % 3, b = (w + 2) % 3;
    // sort on (w, lexicographic)
    ivec3 Q0 = P0, Q1 = P1, Q2 = P2, t;
    if (Q1[w] < Q0[w] || (Q1[w] == Q0[w] && lex_less(Q1, Q0))) { t = Q0; Q0 = Q1; Q1 = t; }
    if (Q2[w] < Q1[w] || (Q2[w] == Q1[w] && lex_less(Q2, Q1))) { t = Q1; Q1 = Q2; Q2 = t; }
    if (Q1[w] < Q0[w] || (Q1[w] == Q0[w] && lex_less(Q1, Q0))) { t = Q0; Q0 = Q1; Q1 = t; }
    g_Q0 = Q0;
    g_n = n;
    g_w = w;
    g_a = a;
    g_b = b;
    Chain ca = chain_begin(Q0, Q2, Q2);  // V_A: the long edge
    Chain cb = chain_begin(Q0, Q1, Q2);  // V_B: the two short edges joined
    int first = Q0[w];
    for (int Z = first; Z <= Q2[w]; ++Z) {
        if (!tick(7u)) break;  // 1 + the two look-ahead loops, the scan loop and its three
        Chain la = ca, lb = cb;  // -> the chains' last entries in layer Z, na and nb steps on
        int na = 0, nb = 0;
        for (;;) {
            if (!tick(1u)) break;
            Chain c = la;
            if (!chain_next(c) || chain_pos(c)[w] != Z) break;
            la = c;
            ++na;
        }
        for (;;) {
            if (!tick(1u)) break;
            Chain c = lb;
            if (!chain_next(c) || chain_pos(c)[w] != Z) break;
            lb = c;
            ++nb;
        }
        if (g_abort) break;
        if (Z >= 0 && Z < u_dims[w])
            ilv_slice(ca, cb, na, nb, chain_pos(la), chain_pos(lb), Z > first, Z < Q2[w], w, Z, a, b);
        ca = la;
        cb = lb;
        chain_next(ca);  // the step along w into layer Z + 1
        chain_next(cb);
    }
}

// ---------------------------------------------------------------------------

#if PASS == 3
// Item gid holds three corners (x + 4 y + 16 z) of the block at SMALL_BASE (u_dims
// holds the block with room around it); their entry is written, or counted bad.
ivec3 small_offset(uint c) { return ivec3(int(c & 3u), int(c >> 2 & 3u), int(c >> 4)); }

void main() {
    uint gid = global_index_1d();
    if (gid >= u_count) return;
    tick(16u);
    uvec4 c = items[gid];
    ilv_scan(SMALL_BASE + small_offset(c.x), SMALL_BASE + small_offset(c.y), SMALL_BASE + small_offset(c.z));
    small_table[small_index(c.x, c.y, c.z)] = g_small;
    if (g_abort || g_small_bad) atomicAdd(out_words[0], 1u);
}
#else
void main() {
    uint gid = global_index_1d();
#if FROM_LIST
    if (gid >= scan_n) return;
    uint tri = scan_list[gid];
#elif PASS == 0
    if (gid >= u_count) return;
    uint tri = gid;
#else
    if (gid >= u_count) return;
    uvec4 item = items[gid];
    uint tri = item.x;
    g_lo = item.y;
    g_hi = item.z;
#endif
    tick(16u);  // the entries of the loops outside any other loop
    vec3 X0 = vertex(faces[3u * tri]);
    vec3 X1 = vertex(faces[3u * tri + 1u]);
    vec3 X2 = vertex(faces[3u * tri + 2u]);
#if LINE_MODE == 2
    bool listed = ilv_triangle(X0, X1, X2);
#if SMALL_TABLE
    if (listed) scan_list[atomicAdd(scan_n, 1u)] = tri;
#endif
#else
    float_triangle(X0, X1, X2);
#endif
#if PASS == 0
    if (g_abort) out_words[2u + atomicAdd(out_words[0], 1u)] = tri;
#elif PASS == 1
    out_words[3u * gid] = g_abort ? 0xFFFFFFFFu : g_ticks;
    out_words[3u * gid + 1u] = g_cost;
    out_words[3u * gid + 2u] = g_maxjob;
#else
    if (g_abort) atomicAdd(out_words[0], 1u);
#endif
}
#endif
