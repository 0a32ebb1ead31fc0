#version 450
// gwn-solid with bricks: the segments gwn/rows.comp left blocks in, listed
// for gwn/field.comp (id, mask).  One invocation per run of GWN_TODO_RUN
// consecutive segments of the evaluated part, in gwn/field.comp's numbering
// (neighbouring rows of one x range next to each other): it counts the run's
// segments with blocks left, takes that many slots with one atomic, and lists
// them in order, so neighbouring invocations of the field pass walk the tree
// alike, as they do without the list.  (One atomic per segment orders them as
// the lanes happen to run: 10% slower walks on llvmpipe where every segment
// is listed.  A work group's prefix sum in shared memory keeps the order too,
// but its barriers made this listing half of the field stage on llvmpipe:
// docs/methods/gwn.md.)
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 2) readonly buffer Masks { uint masks[]; };
layout(std430, binding = 8) buffer Count { uint voxel_count; uint refine_count; uint todo_count; };
layout(std430, binding = 11) writeonly buffer Todo { uint todo[]; };
uniform uint u_items;

void main() {
    uint first = global_index_1d() * uint(GWN_TODO_RUN);
    if (first >= u_items) return;
    uint end = min(first + uint(GWN_TODO_RUN), u_items);
    uint n = 0u;
    for (uint id = first; id < end; ++id)
        if (masks[id] != 0u) ++n;
    if (n == 0u) return;
    uint slot = atomicAdd(todo_count, n);
    for (uint id = first; id < end; ++id) {
        uint mask = masks[id];
        if (mask == 0u) continue;
        todo[2u * slot] = id;
        todo[2u * slot + 1u] = mask;
        ++slot;
    }
}
