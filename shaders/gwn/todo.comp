#version 450
// gwn-solid with bricks: the segments gwn/rows.comp left blocks in, listed
// for gwn/field.comp (id, mask).  One invocation per segment of the evaluated
// part, in gwn/field.comp's numbering (neighbouring rows of one x range next
// to each other): the list keeps that order within a group, so neighbouring
// invocations of the field pass walk the tree alike, and every SIMD lane or
// warp slot of it has a segment to work on.
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 2) readonly buffer Masks { uint masks[]; };
layout(std430, binding = 8) buffer Count { uint voxel_count; uint refine_count; uint todo_count; };
layout(std430, binding = 11) writeonly buffer Todo { uint todo[]; };
uniform uint u_items;

void main() {
    uint id = global_index_1d();
    if (id >= u_items) return;
    uint mask = masks[id];
    if (mask == 0u) return;
    uint slot = atomicAdd(todo_count, 1u);
    todo[2u * slot] = id;
    todo[2u * slot + 1u] = mask;
}
