#version 450
// passalis-stencil (Sec. 3.2): where some direction is complete, its verdict (acc0);
// elsewhere every direction's double-layer verdict (acc1), and the voxel is marked
// unclassifiable (acc2 becomes that mask).  The set bits of both are counted on the
// way: voxel_count[0] the result's, [1] the unclassifiable mask's.
layout(local_size_x = 256) in;
#include "common/bits.glsl"
#include "common/dispatch.glsl"
#include "common/voxel_space.glsl"
layout(std430, binding = 1) buffer Acc0 { uint acc0[]; };
layout(std430, binding = 2) readonly buffer Acc1 { uint acc1[]; };
layout(std430, binding = 3) buffer Acc2 { uint acc2[]; };
layout(std430, binding = 5) buffer Count { uint voxel_count[]; };

void main() {
    uint w = global_index_1d();
    uint wpr = words_per_row();
    if (w >= wpr * uint(u_dims.y) * uint(u_dims.z)) return;
    uint valid = w % wpr == wpr - 1u ? mask_upto((uint(u_dims.x) - 1u) & 31u) : 0xFFFFFFFFu;
    uint complete = acc2[w];
    uint result = ((complete & acc0[w]) | (~complete & acc1[w])) & valid;
    uint unclassifiable = ~complete & valid;
    acc0[w] = result;
    acc2[w] = unclassifiable;
    uint n = uint(bitCount(result)), u = uint(bitCount(unclassifiable));
    if (n != 0u) atomicAdd(voxel_count[0], n);
    if (u != 0u) atomicAdd(voxel_count[1], u);
}
