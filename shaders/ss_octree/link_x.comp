#version 450
// Octree construction: x-neighbour pointers across parents (Sec. 5.2), from
// the top down.  Node n of level L on the +x side of its parent P (c odd)
// gets as +x neighbour the -x-side child with the same y and z of P's +x
// neighbour P', if P' has children; that child gets n as -x neighbour.
// P's pointers are final because level L + 1 was linked before.
layout(local_size_x = 256) in;
#include "common/dispatch.glsl"
#include "ss_octree/common.glsl"
layout(std430, binding = 13) readonly buffer Parent { uint parent[]; };
layout(std430, binding = 14) buffer XNext { uint x_next[]; };
layout(std430, binding = 15) buffer XPrev { uint x_prev[]; };
layout(std430, binding = 16) readonly buffer Child { uint child[]; };
uniform uint u_level;
uniform uint u_count;
void main() {
    uint n = global_index_1d();
    if (n >= u_count || (n & 1u) == 0u) return;
    uint L = u_level;
    uint p = parent[u_nbase[L] + n];
    uint pn = x_next[u_nbase[L + 1u] + p];
    if (pn == OCT_NONE) return;
    uint ch = child[u_ubase[L + 1u] + pn];
    if (ch == OCT_NONE) return;
    uint m = ch + ((n & 7u) & 6u);
    x_next[u_nbase[L] + n] = m;
    x_prev[u_nbase[L] + m] = n;
}
