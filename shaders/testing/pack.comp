#version 450
// Harness self-test: set voxels by index into the packed grid with atomicOr,
// the way every surface method writes (layout of common/voxel_space.glsl).
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Voxels { ivec4 voxels[]; };
layout(std430, binding = 1) buffer Grid { uint grid[]; };
uniform uint u_count;
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    ivec3 v = voxels[i].xyz;
    if (!in_grid(v)) return;
    atomicOr(grid[word_index(v)], bit_of(uint(v.x)));
}
