#version 450
// vote-solid: the majority of the parities along x, y and z, all three in
// glvox's packed layout (ss/solid_fill.comp, ss/solid_fill_axis.comp):
// maj(X, Y, Z) = (X & Y) | (Z & (X | Y)), into X, counted.  One invocation
// per VEC words; bits past nx are zero in all three.
#include "common/voxel_space.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
#if VEC == 4
#define WORDS uvec4
#elif VEC == 2
#define WORDS uvec2
#else
#define WORDS uint
#endif
layout(std430, binding = 0) buffer X { WORDS grid_x[]; };
layout(std430, binding = 1) readonly buffer Y { WORDS grid_y[]; };
layout(std430, binding = 2) readonly buffer Z { WORDS grid_z[]; };
layout(std430, binding = 3) buffer Count { uint voxel_count; };
uniform uint u_first;  // the VEC-word groups u_first .. u_first + u_count - 1 (the mesh's slices)
uniform uint u_count;

void main() {
    uint i = global_index_1d();
    if (i >= u_count) return;
    uint idx = u_first + i;
    WORDS x = grid_x[idx], y = grid_y[idx];
    WORDS v = (x & y) | (grid_z[idx] & (x | y));
    if (v != x) grid_x[idx] = v;
    uint c = 0u;
#if VEC == 1
    c = uint(bitCount(v));
#else
    for (int k = 0; k < VEC; ++k) c += uint(bitCount(v[k]));
#endif
    if (c != 0u) atomicAdd(voxel_count, c);
}
