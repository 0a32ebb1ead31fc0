#version 450
// One pass of the LSD radix sort, step 1: per-tile digit histograms.
//
// Tile g covers keys [g * TILE, (g + 1) * TILE), TILE = WG_SIZE * ITEMS, the
// last one partial.  The count of digit d = (key >> u_shift) & (RADIX - 1) in
// tile g goes to counts[d * u_groups + g] (digit-major), so that one exclusive
// scan of `counts` gives every (digit, tile) its first output position.
// Shared atomics only count here: the counts do not depend on their order.
// defaults: the sizes glvox.gpu_sort passes as defines
#ifndef WG_SIZE
#define WG_SIZE 32
#endif
#ifndef ITEMS
#define ITEMS 256
#endif
#ifndef DIGIT_BITS
#define DIGIT_BITS 8
#endif
#define RADIX (1u << DIGIT_BITS)
#include "common.glsl"
layout(local_size_x = WG_SIZE) in;

layout(std430, binding = 0) readonly buffer KeysIn { uint keys_in[]; };
layout(std430, binding = 4) writeonly buffer Counts { uint counts[]; };

uniform uint u_n;
uniform uint u_shift;
uniform uint u_groups;

shared uint s_hist[RADIX];

void main() {
    uint g = group_index();
    if (g >= u_groups) return;
    uint t = gl_LocalInvocationIndex;
    for (uint d = t; d < RADIX; d += uint(WG_SIZE)) s_hist[d] = 0u;
    memoryBarrierShared();
    barrier();
    uint first = (g * uint(WG_SIZE) + t) * uint(ITEMS);
    uint end = min(first + uint(ITEMS), u_n);
    for (uint k = first; k < end; ++k) {
        atomicAdd(s_hist[(keys_in[k] >> u_shift) & (RADIX - 1u)], 1u);
    }
    memoryBarrierShared();
    barrier();
    for (uint d = t; d < RADIX; d += uint(WG_SIZE)) counts[d * u_groups + g] = s_hist[d];
}
