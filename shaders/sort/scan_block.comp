#version 450
// Exclusive scan of each block of BLOCK = WG_SIZE * ITEMS consecutive uints
// of `src` into `dst` (which may be the same buffer: each invocation reads
// its ITEMS items before anyone writes, and blocks are disjoint).  With
// HAS_OFFSETS, offsets[block] (the exclusive scan of the block sums) is added;
// with u_write_total != 0 (single-block dispatches only), the block total plus
// its offset is written to total[0].
// defaults: the sizes glvox.gpu_sort passes as defines
#ifndef WG_SIZE
#define WG_SIZE 64
#endif
#ifndef ITEMS
#define ITEMS 64
#endif
#ifndef HAS_OFFSETS
#define HAS_OFFSETS 0
#endif
#include "common.glsl"
layout(local_size_x = WG_SIZE) in;

layout(std430, binding = 0) readonly buffer Src { uint src[]; };
layout(std430, binding = 1) writeonly buffer Dst { uint dst[]; };
#if HAS_OFFSETS
layout(std430, binding = 2) readonly buffer Offsets { uint offsets[]; };
#endif
layout(std430, binding = 3) writeonly buffer Total { uint total_out[]; };

uniform uint u_n;
uniform uint u_groups;
uniform uint u_write_total;

void main() {
    uint g = group_index();
    if (g >= u_groups) return;
    uint first = (g * uint(WG_SIZE) + gl_LocalInvocationIndex) * uint(ITEMS);
    uint v[ITEMS];
    uint s = 0u;
    for (uint i = 0u; i < uint(ITEMS); ++i) {
        uint k = first + i;
        v[i] = k < u_n ? src[k] : 0u;
        s += v[i];
    }
    uint total;
    uint run = wg_exclusive_scan(s, total);
#if HAS_OFFSETS
    uint base = offsets[g];
#else
    uint base = 0u;
#endif
    run += base;
    for (uint i = 0u; i < uint(ITEMS); ++i) {
        uint k = first + i;
        if (k < u_n) dst[k] = run;
        run += v[i];
    }
    if (u_write_total != 0u && gl_LocalInvocationIndex == 0u) total_out[0] = base + total;
}
