#version 450
// Active level-1 nodes, pass 2: one invocation per chunk of an item's work
// marks the level-1 nodes its triangle meets (modified conservative test,
// ss_octree/activate.glsl) in a bit array indexed by Morton code: bit m % 32
// of word m / 32 is node m, so a word is a 4 x 4 x 2 block of nodes in Morton
// order (Sec. 5.1) and extraction needs no sort.
#include "common/edge.glsl"
#include "common/voxel_space.glsl"
#include "ss/solid.glsl"
#define SOLID_UNIT 1
#include "ss/solid_input.glsl"
#include "ss_octree/common.glsl"
#include "ss_octree/activate.glsl"
#include "ss_octree/work_expand.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 8) buffer L1Bits { uint l1bits[]; };

// One pending word in a register: neighbouring nodes mostly share a word.
uint pend_word = OCT_NONE, pend_bits = 0u;

void mark(ivec3 node) {
    uint m = oct_morton(uvec3(node));
    uint w = m >> 5, b = 1u << (m & 31u);
    if (w == pend_word) { pend_bits |= b; return; }
    if (pend_bits != 0u) atomicOr(l1bits[pend_word], pend_bits);
    pend_word = w;
    pend_bits = b;
}

void mark_every(ATri T, uint q0, uint q1) {
    uvec3 s = uvec3(T.hi - T.lo + 1);
    int i = T.lo.x + int(q0 % s.x), j = T.lo.y + int((q0 / s.x) % s.y), k = T.lo.z + int(q0 / (s.x * s.y));
    for (uint q = q0; q < q1; ++q) {
        mark(ivec3(i, j, k));
        if (++i > T.hi.x) { i = T.lo.x; if (++j > T.hi.y) { j = T.lo.y; ++k; } }
    }
}

// Columns along the dominant axis w (Sec. 3.2): the (u, v) projection test,
// the plane's w range over the column gives the candidate nodes, then the
// two remaining projection tests.
void mark_columns(ATri T, uint q0, uint q1) {
    int w = dominant_axis(T.n);
    int u = (w + 1) % 3, v = (w + 2) % 3;
    Proj Pw = make_proj(T, u, v, w), Pu = make_proj(T, v, w, u), Pv = make_proj(T, w, u, v);
    float du = -T.n[u] / T.n[w], dv = -T.n[v] / T.n[w];  // dw per unit step in u and v
    float bw = float(T.base[w]);
    uint su = uint(T.hi[u] - T.lo[u] + 1);
    int iu = T.lo[u] + int(q0 % su), iv = T.lo[v] + int(q0 / su);
    for (uint q = q0; q < q1; ++q) {
        vec2 bu = node_box(T, u, iu), bv = node_box(T, v, iv);
        if (proj_box(Pw, vec2(bu.x, bv.x), vec2(bu.y, bv.y))) {
            float wb = T.v0[w] + du * (bu.x - T.v0[u]) + dv * (bv.x - T.v0[v]);
            float wlo = wb + min(0.0, du * bu.y) + min(0.0, dv * bv.y) - OCT_W_EPS;
            float whi = wb + max(0.0, du * bu.y) + max(0.0, dv * bv.y) + OCT_W_EPS;
            ivec2 r = node_range(w, wlo + bw, whi + bw);
            r = ivec2(max(r.x, T.lo[w]), min(r.y, T.hi[w]));
            for (int k = r.x; k <= r.y; ++k) {
                vec2 bk = node_box(T, w, k);
                if (proj_box(Pu, vec2(bv.x, bk.x), vec2(bv.y, bk.y))
                    && proj_box(Pv, vec2(bk.x, bu.x), vec2(bk.y, bu.y)))
                    mark(compose(u, v, w, iu, iv, k));
            }
        }
        if (++iu > T.hi[u]) { iu = T.lo[u]; ++iv; }
    }
}

void main() {
    uint g = global_index_1d();
    if (g >= chunk_total[0]) return;
    uint item = chunk_item(g, u_triangles + 2u * u_walls);
    uint chunk = g - chunk_offsets[item];
    ATri T = activation_setup(item);
    uint units = activation_units(T);
    uint q0 = chunk * uint(OCT_CHUNK), q1 = min(units, q0 + uint(OCT_CHUNK));
    if (T.every) mark_every(T, q0, q1); else mark_columns(T, q0, q1);
    if (pend_bits != 0u) atomicOr(l1bits[pend_word], pend_bits);
}
