#version 450
// First level of the multi-level exclusive scan: the sum of each block of
// BLOCK = WG_SIZE * ITEMS consecutive uints of `src` (the last block may be
// partial) is written to sums[block].
// defaults: the sizes glvox.gpu_sort passes as defines
#ifndef WG_SIZE
#define WG_SIZE 64
#endif
#ifndef ITEMS
#define ITEMS 64
#endif
#include "common.glsl"
layout(local_size_x = WG_SIZE) in;

layout(std430, binding = 0) readonly buffer Src { uint src[]; };
layout(std430, binding = 2) writeonly buffer Sums { uint sums[]; };

uniform uint u_n;       // number of uints in src
uniform uint u_groups;  // number of blocks, ceil(u_n / BLOCK)

void main() {
    uint g = group_index();
    if (g >= u_groups) return;  // uniform over the work group
    uint first = (g * uint(WG_SIZE) + gl_LocalInvocationIndex) * uint(ITEMS);
    uint s = 0u;
    for (uint i = 0u; i < uint(ITEMS); ++i) {
        uint k = first + i;
        s += k < u_n ? src[k] : 0u;
    }
    uint total;
    wg_exclusive_scan(s, total);
    if (gl_LocalInvocationIndex == 0u) sums[g] = total;
}
