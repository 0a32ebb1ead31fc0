#version 450
// Indirect dispatch arguments for one invocation per chunk (see
// ss_octree/work_expand.glsl): groups of LOCAL invocations over
// chunk_total[0] chunks, split along y past u_max_groups groups in x
// (common/dispatch.glsl numbers them back).
layout(local_size_x = 1) in;
layout(std430, binding = 7) readonly buffer ChunkTotal { uint chunk_total[]; };
layout(std430, binding = 8) writeonly buffer Args { uint args[]; };
uniform uint u_local_size;
uniform uint u_max_groups;
void main() {
    uint groups = (chunk_total[0] + u_local_size - 1u) / u_local_size;
    uint x = min(groups, u_max_groups);
    args[0] = x;
    args[1] = x == 0u ? 0u : (groups + x - 1u) / x;
    args[2] = 1u;
}
