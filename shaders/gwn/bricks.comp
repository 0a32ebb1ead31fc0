#version 450
// gwn-solid, pass 2 (before the row sums): F, its error and a bound of its
// gradient per brick (gwn/bricks.glsl), so that gwn/rows.comp decides most
// voxels from C and the brick's F, and gwn/field.comp walks the tree only for
// the blocks left.
//
// Why it holds.  F sums the strips that the boundary edges sweep along +x.
// Off those strips F is smooth, and its gradient is the Biot-Savart integral
// over the boundary chain (a strip's boundary is its edge, two rays along +x
// and an edge at infinity; at every vertex of the chain as many edges start
// as end, so the rays cancel): |grad F(p)| <= 1 / (4 pi) sum over edges of
// the integral of |dl| / |x - p|^2.  Where no strip reaches the brick's box
// of voxel centers (convex), the segment from p0 to any voxel center p of it
// crosses none, so |F(p) - F(p0)| <= G |p - p0| with G that sum's bound over
// the box: a node of length L whose ball (c, r) is at distance d from the box
// adds L / (4 pi (d - r)^2), a near edge of length l at distance g at least
// min(l / g^2, 4 / g) / (4 pi) (|x - p| >= max(g, |s|) along the edge's line,
// s from the foot of the perpendicular: the integral of 1 / max(g, |s|)^2 over
// all s is 4 / g).
// C(p) is exact (the row sums), so w(p) = C(p) + F(p) lies within
// err + G |p - p0| of C(p) + F(p0).
//
// Behind the boundary along +x, strips cross the brick ("shadows").  There
// the mirrored split holds instead: F- = F + T sums the strips swept along
// -x, where T is the row's total signed crossings, -(the winding number of
// the boundary chain's (y, z) projection around the row); F- is smooth off
// its own strips, with the same gradient (T is constant between them), and
// w = (C - T) + F-.  A brick that only +x strips reach gets F-(p0) =
// F(p0) - wn(p0), where wn(p0) sums the chain's edges' crossings (a far
// node's edges: the winding number of its polygons around p0, 0 when its
// disk misses p0, minus its chord's part).  gwn/rows.comp applies T at the
// row's end.
//
// One invocation per brick of the evaluated part (u_brick0 .. + u_bricks),
// walking the tree's roots u_roots (a chunk; glvox.methods.gwn.field.plan_chunks):
// a node whose ball no +x strip carries into the box and that lies at distance
// >= u_beta r from the box adds its expansion at p0 (and its error bound),
// minus its chord's strip, and L / (d - r)^2 to G; a near leaf's edges add
// their exact strips at p0, or mark the brick when a strip can reach it; a near
// inner node is replaced by its children.  The record (gwn/bricks.glsl) takes
// the +x split where no +x strip reaches the box, else the -x split where no
// -x strip does, else marks the brick.  With several chunks the sums so far
// live in the second vec4 of each brick's pair (F, err, G, wn) and the first
// holds the flags until the last chunk writes the record.
//
// CAPS 1: first the caps' bound (gwn/caps.glsl).  A brick where it stays
// under the limit gets the record (0, 0, 0, 3) and its bit in CapBits:
// gwn/rows.comp decides its voxels from the crossing counts of the mesh and
// its caps, and the tree is not walked for it.
//
// GWN_SUPER > 0 (with CAPS): the pass before, one invocation per super brick
// of GWN_SUPER^3 bricks of the evaluated part.  The caps' bound holds over any
// ball, so where it holds over the ball around a super brick's voxel centers
// each of its bricks gets its bit in CapBits at once; the brick pass then
// takes a brick whose bit is set as decided, without a test of its own.  Far
// from the caps one test stands for GWN_SUPER^3 (each of which loops over
// every fan triangle whose ball it is in).  GWN_SUPER_AFTER 1: a pass over
// super bricks of half the edge of the pass before, aligned alike, so each
// lies in one of those: it skips the super bricks that pass decided (their
// first brick's bit is set) and tests the others, nearer the caps, over
// balls of half the radius.
#include "common/voxel_space.glsl"
#include "gwn/layout.glsl"
#include "gwn/strip.glsl"
#include "gwn/bricks.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 1) readonly buffer VoxVerts { float vox[]; };
layout(std430, binding = 4) buffer Bricks { vec4 bricks[]; };
layout(std430, binding = 5) readonly buffer Edges { uvec2 edges[]; };
layout(std430, binding = 6) readonly buffer Nodes { vec4 nodes[]; };
layout(std430, binding = 9) readonly buffer Links { ivec4 links[]; };
layout(std430, binding = 10) readonly buffer Roots { int roots[]; };
uniform float u_beta;
uniform ivec2 u_roots;
uniform bool u_first, u_last;
uniform ivec3 u_brick0;   // first brick of the evaluated part (x, y, z in the slab)
uniform ivec3 u_bricks;   // bricks of it per axis

const int GWN_STACK = 64;

vec3 vertex(uint i) { return vec3(vox[3u * i], vox[3u * i + 1u], vox[3u * i + 2u]); }

#include "gwn/winding2d.glsl"
#if CAPS
#include "gwn/caps.glsl"
layout(std430, binding = 8) buffer Count {
    uint count_words[7];
    uint cap_bricks;    // bricks the caps decide (run.stats)
    uint super_bricks;  // of them, those their super brick decided
};
// a bit per brick (bit brick_index(b), cleared before): the caps decide it
layout(std430, binding = 3) buffer CapBits { uint cap_bits[]; };
#endif

// Distance from p to the box [lo, hi].
float box_distance(vec3 p, vec3 lo, vec3 hi) { return length(max(max(lo - p, p - hi), vec3(0.0))); }

// Whether the strip swept along +x from a point of the ball (c, r) can meet
// the box: the ball's (y, z) disk meets the box's (y, z) rectangle and part
// of the ball lies at x <= the box's last x.
bool ball_reaches(vec3 c, float r, vec3 lo, vec3 hi) {
    vec2 d = max(max(lo.yz - c.yz, c.yz - hi.yz), vec2(0.0));
    return dot(d, d) <= r * r && c.x - r <= hi.x;
}

// The same for the strips swept along -x: part of the ball at x >= the box's first x.
bool ball_reaches_minus(vec3 c, float r, vec3 lo, vec3 hi) {
    vec2 d = max(max(lo.yz - c.yz, c.yz - hi.yz), vec2(0.0));
    return dot(d, d) <= r * r && c.x + r >= lo.x;
}

// The same for the strip of the edge u -> v, by its bounding box (along +x,
// and along -x).
bool edge_reaches(vec3 u, vec3 v, vec3 lo, vec3 hi) {
    vec3 a = min(u, v), b = max(u, v);
    return a.x <= hi.x && all(lessThanEqual(a.yz, hi.yz)) && all(greaterThanEqual(b.yz, lo.yz));
}

bool edge_reaches_minus(vec3 u, vec3 v, vec3 lo, vec3 hi) {
    vec3 a = min(u, v), b = max(u, v);
    return b.x >= lo.x && all(lessThanEqual(a.yz, hi.yz)) && all(greaterThanEqual(b.yz, lo.yz));
}

// A lower bound of the distance from the edge u -> v (of length len) to the
// box: the larger of its bounding ball's and its bounding box's distances.
float edge_gap(vec3 u, vec3 v, float len, vec3 lo, vec3 hi) {
    vec3 sep = max(max(lo - max(u, v), min(u, v) - hi), vec3(0.0));
    return max(box_distance(0.5 * (u + v), lo, hi) - 0.5 * len, length(sep));
}

#if GWN_GRAD
uniform int u_edges;  // boundary edges (all of them: Edges)

// The integral of dl x (p - x) / |p - x|^3 along the edge from p + a to p + b
// (Biot-Savart; e = b - a): (a x b)(|a| + |b|) / (|a| |b| (|a| |b| + a . b)),
// the last factor written without cancellation where a . b < 0 (p beside the
// edge): |a| |b| + a . b = |a x b|^2 / (|a| |b| - a . b).  a x b as a x e, e
// the correctly rounded difference of the vertices (not of a and b), so that a
// short edge far away keeps its direction.
vec3 biot_savart(vec3 a, vec3 b, vec3 e) {
    vec3 c = cross(a, e);
    float la = length(a), lb = length(b), ab = la * lb, d = dot(a, b);
    float c2 = dot(c, c);
    if (c2 == 0.0) return vec3(0.0);  // p on the edge's line: no field off the edge
    float den = d >= 0.0 ? ab + d : c2 / (ab - d);
    return c * ((la + lb) / (ab * den));
}

// The first-order record of a brick whose record has a smooth split (w 0 or
// 2): the gradient of F at p0, the Biot-Savart integral over every boundary
// edge, exact up to float32 rounding (turns per voxel), and H, a bound of
// F's second derivative over the box (turns per voxel^2): the derivative of
// r / |r|^3 (r = p - x) is (I - 3 r r^T / |r|^2) / |r|^3, of norm 2 / |r|^3, so
// an edge of length l at distance g from the box adds at most
// min(2 l / g^3, 4 / g^2) / (4 pi) (the integral of 2 / (g^2 + s^2)^(3/2) over
// all s is 4 / g^2).  gwn/rows.comp then bounds |F(p) - F(p0) - grad . (p - p0)|
// by H |p - p0|^2 / 2 (Taylor's theorem along the segment p0 -> p, which no
// strip of the split crosses).  GWN_NO_H where an edge meets the box.
vec4 gradient_record(vec3 p0, vec3 lo, vec3 hi) {
    vec3 g = vec3(0.0);
    float h = 0.0;
    for (int e = 0; e < u_edges; ++e) {
        uvec2 ed = edges[e];
        vec3 u = vertex(ed.x), v = vertex(ed.y);
        vec3 uv = v - u;
        float len = length(uv);
        float gap = edge_gap(u, v, len, lo, hi);
        if (!(gap > 0.0)) return vec4(0.0, 0.0, 0.0, GWN_NO_H);
        h += min(2.0 * len / (gap * gap * gap), 4.0 / (gap * gap));
        g += biot_savart(u - p0, v - p0, uv);
    }
    // H rounded up (float32 sums of a bound, distances cubed)
    return vec4(g * (0.25 / GWN_PI), h * (1.001 * 0.25 / GWN_PI));
}
#endif

#if GWN_SUPER
// (GWN_SUPER: bricks.comp's header)
void main() {
    uint id = global_index_1d();
    ivec3 ns = (u_bricks + GWN_SUPER - 1) / GWN_SUPER;
    uint nxy = uint(ns.x * ns.y);
    if (id >= nxy * uint(ns.z)) return;
    ivec3 b0 = u_brick0 + GWN_SUPER * ivec3(int(id % uint(ns.x)), int((id % nxy) / uint(ns.x)), int(id / nxy));
    ivec3 b1 = min(b0 + GWN_SUPER, u_brick0 + u_bricks) - 1;
    vec3 lo = brick_low(b0), hi = brick_low(b1) + float(GWN_BRICK - 1);
#if GWN_SUPER_AFTER
    // inside a super brick the pass before decided: every bit is set already
    uint first = brick_index(b0);
    if (((cap_bits[first / 32u] >> (first & 31u)) & 1u) != 0u) return;
#endif
    if (!caps_decide(0.5 * (lo + hi), 0.5 * length(hi - lo))) return;
    ivec3 n = b1 - b0 + 1;
    atomicAdd(super_bricks, uint(n.x * n.y * n.z));
    for (int z = b0.z; z <= b1.z; ++z)
        for (int y = b0.y; y <= b1.y; ++y)
            for (int x = b0.x; x <= b1.x; ++x) {
                uint bi = brick_index(ivec3(x, y, z));
                atomicOr(cap_bits[bi / 32u], 1u << (bi & 31u));
            }
}
#else
void main() {
    uint id = global_index_1d();
    uint nxy = uint(u_bricks.x * u_bricks.y);
    if (id >= nxy * uint(u_bricks.z)) return;
    ivec3 b = u_brick0 + ivec3(int(id % uint(u_bricks.x)), int((id % nxy) / uint(u_bricks.x)), int(id / nxy));
    vec3 lo = brick_low(b), hi = lo + float(GWN_BRICK - 1), p0 = brick_center(b);
    uint bi = brick_index(b), at = 2u * bi;
    float f = 0.0, err = 0.0, grad = 0.0;
    int wn = 0;  // the boundary chain's (y, z) winding number around p0
#if CAPS
    // the caps' bound, on the first chunk; later chunks read its flag (w: 1)
    bool pre = u_first && ((cap_bits[bi / 32u] >> (bi & 31u)) & 1u) != 0u;
    bool capped = u_first ? pre || caps_decide(p0, 0.5 * sqrt(3.0) * float(GWN_BRICK - 1)) : bricks[at].w != 0.0;
    if (capped) {
        if (u_first) {
            atomicAdd(cap_bricks, 1u);
            if (!pre) atomicOr(cap_bits[bi / 32u], 1u << (bi & 31u));
        }
        bricks[at] = vec4(0.0, 0.0, 0.0, u_last ? 3.0 : 1.0);
        return;
    }
#endif
    // +x strips reach the box, -x strips do, p0 lies on a projected edge
    bool plus = false, minus = false, tie = false;
    if (!u_first) {
        vec4 flags = bricks[at];
        plus = flags.x != 0.0;
        minus = flags.y != 0.0;
        tie = flags.z != 0.0;
    }
    int stack[GWN_STACK];
    for (int r = u_roots.x; r < u_roots.y && !(plus && (minus || tie)); ++r) {
        int sp = 0;
        stack[sp++] = roots[r];
        while (sp > 0) {
            int n = stack[--sp];
            vec4 cr = nodes[GWN_NODE_VEC4 * n];
            float d = box_distance(cr.xyz, lo, hi);
            ivec4 lk = links[2 * n];
            ivec4 chord = links[2 * n + 1];
            bool rp = ball_reaches(cr.xyz, cr.w, lo, hi), rm = ball_reaches_minus(cr.xyz, cr.w, lo, hi);
            // far: out of reach of the +x strips (a ball that +x strips carry into
            // the box is walked down to its edges, whose boxes may well miss it)
            if (d >= u_beta * cr.w && !rp) {
                vec4 rec[7];
                for (int q = 0; q < 7; ++q) rec[q] = nodes[GWN_NODE_VEC4 * n + q];
                vec2 fb = far_at(rec, p0);
                f += fb.x;
                err += fb.y;
                minus = minus || rm;
                vec2 cd = cr.yz - p0.yz;
                // the node's polygons around p0 (0 when p0 lies outside their
                // disk), for wn while the -x split is still possible
                int wq = !minus && dot(cd, cd) <= cr.w * cr.w ? node_winding(lk, chord, p0.yz, tie) : 0;
                int wc = 0;
                if (chord.x >= 0) {
                    vec3 cu = vertex(uint(chord.x)), cv = vertex(uint(chord.y));
                    f -= strip_at(cu, cv, p0);
                    wc = edge_winding(cu.yz, cv.yz, p0.yz, tie);
                }
                wn += wq - wc;
                float gap = d - cr.w;
                grad += nodes[GWN_NODE_VEC4 * n + 7].x / (gap * gap);
                continue;
            }
            if (lk.z < 0) {
                for (int e = lk.x; e < lk.x + lk.y; ++e) {
                    uvec2 ed = edges[e];
                    vec3 u = vertex(ed.x), v = vertex(ed.y);
                    float len = length(v - u);
                    float gap = edge_gap(u, v, len, lo, hi);
                    plus = plus || edge_reaches(u, v, lo, hi);
                    minus = minus || edge_reaches_minus(u, v, lo, hi);
                    if (!(gap > 0.0)) plus = minus = true;
                    if (plus && minus) break;
                    f += strip_at(u, v, p0);
                    wn += edge_winding(u.yz, v.yz, p0.yz, tie);
                    grad += min(len / (gap * gap), 4.0 / gap);
                }
                if (plus && (minus || tie)) break;
            } else {
                stack[sp++] = lk.w;
                stack[sp++] = lk.z;
            }
        }
    }
    if (!u_first) {
        vec4 sums = bricks[at + 1u];
        f += sums.x;
        err += sums.y;
        grad += sums.z;
        wn += int(sums.w);
    }
    if (!u_last) {
        bricks[at] = vec4(plus, minus, tie, 0.0);
        bricks[at + 1u] = vec4(f, err, grad, float(wn));
        return;
    }
    // G in turns per voxel, rounded up a little (float32 sums of a bound)
    grad *= 1.0001 * 0.25 / GWN_PI;
    // the +x split needs no winding number; the -x split does, off a tie
    vec4 rec = vec4(0.0, 0.0, 0.0, 1.0);  // strips reach the box either way
    if (!plus) rec = vec4(f, err, grad, 0.0);
    else if (!minus && !tie) rec = vec4(f - 2.0 * GWN_PI * float(wn), err, grad, 2.0);
    bricks[at] = rec;
    // the first-order record (gwn/bricks.glsl)
    vec4 first_order = vec4(0.0, 0.0, 0.0, GWN_NO_H);
#if GWN_GRAD
    if (rec.w != 1.0) first_order = gradient_record(p0, lo, hi);
#endif
    bricks[at + 1u] = first_order;
}
#endif
