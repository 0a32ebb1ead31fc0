#version 450
// gwn-solid with bricks: the segments gwn/rows.comp left blocks in, listed
// for gwn/field.comp (id, mask).  One invocation per segment of the evaluated
// part, in gwn/field.comp's numbering (neighbouring rows of one x range next
// to each other).  A work group lists its segments in that order, after one
// another (a prefix sum in shared memory and one atomic per group), so
// neighbouring invocations of the field pass walk the tree alike, as they do
// without the list, and every SIMD lane or warp slot has a segment to work on.
// (One atomic per segment orders them as the lanes happen to run: 10% slower
// walks on llvmpipe where every segment is listed.)
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 2) readonly buffer Masks { uint masks[]; };
layout(std430, binding = 8) buffer Count { uint voxel_count; uint refine_count; uint todo_count; };
layout(std430, binding = 11) writeonly buffer Todo { uint todo[]; };
uniform uint u_items;

shared uint s_scan[64];
shared uint s_base;

void main() {
    uint id = global_index_1d();
    uint li = gl_LocalInvocationIndex;
    uint mask = id < u_items ? masks[id] : 0u;
    s_scan[li] = mask != 0u ? 1u : 0u;
    barrier();
    for (uint off = 1u; off < 64u; off <<= 1u) {
        uint v = li >= off ? s_scan[li - off] : 0u;
        barrier();
        s_scan[li] += v;
        barrier();
    }
    if (li == 63u) s_base = s_scan[63] == 0u ? 0u : atomicAdd(todo_count, s_scan[63]);
    barrier();
    if (mask != 0u) {
        uint slot = s_base + s_scan[li] - 1u;
        todo[2u * slot] = id;
        todo[2u * slot + 1u] = mask;
    }
}
