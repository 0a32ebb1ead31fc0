#version 450
// Indirect dispatch arguments for one invocation per chunk (see
// ss_octree/work_expand.glsl): groups of LOCAL invocations over
// chunk_total[0] chunks, split along y past u_max_groups groups in x
// (common/dispatch.glsl numbers them back).
layout(local_size_x = 1) in;
#include "common/dispatch.glsl"
layout(std430, binding = 7) readonly buffer ChunkTotal { uint chunk_total[]; };
layout(std430, binding = 8) writeonly buffer Args { uint args[]; };
uniform uint u_local_size;
uniform uint u_max_groups;
void main() {
    uvec3 a = dispatch_args_1d(chunk_total[0], u_local_size, u_max_groups);
    args[0] = a.x;
    args[1] = a.y;
    args[2] = a.z;
}
