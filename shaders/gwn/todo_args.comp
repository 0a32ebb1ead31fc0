#version 450
// gwn-solid with bricks: the indirect dispatch of gwn/field.comp over the
// segments gwn/todo.comp listed (groups of u_local_size; more than
// u_max_groups groups are split along y, as glvox.gpu.dispatch.dispatch_1d does).
// One invocation.
layout(local_size_x = 1) in;
#include "common/dispatch.glsl"
layout(std430, binding = 8) buffer Count { uint voxel_count; uint refine_count; uint todo_count; uint todo_total; };
layout(std430, binding = 4) writeonly buffer Args { uint args[]; };
uniform uint u_local_size;
uniform uint u_max_groups;

void main() {
    uvec3 a = dispatch_args_1d(todo_count, u_local_size, u_max_groups);
    args[0] = a.x;
    args[1] = a.y;
    args[2] = a.z;
    todo_total += todo_count;  // over the slabs: run.stats["field_segments"]
}
