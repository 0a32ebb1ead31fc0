#version 450
// binvox-solid: the result, counted.  Carving survivors get 3 votes and a voxel is set
// when it has more than 2 (binvox's process_votes): default = carve | (votes >= 3),
// u_carve / u_vote select the parts (-c, -v); u_surface ORs in the voxels holding a
// crossing of the pixel-center rays.  The result replaces the carve buffer.
layout(local_size_x = 256) in;
#include "common/bits.glsl"
#include "common/dispatch.glsl"
#include "common/voxel_space.glsl"
uniform bool u_carve;
uniform bool u_vote;
uniform bool u_surface;
layout(std430, binding = 1) buffer Carve { uint carve[]; };
layout(std430, binding = 2) readonly buffer V0 { uint v0[]; };
layout(std430, binding = 3) readonly buffer V1 { uint v1[]; };
layout(std430, binding = 4) readonly buffer V2 { uint v2[]; };
layout(std430, binding = 6) readonly buffer Surface { uint surface[]; };
layout(std430, binding = 7) buffer Count { uint voxel_count[]; };

void main() {
    uint w = global_index_1d();
    uint wpr = words_per_row();
    if (w >= wpr * uint(u_dims.y) * uint(u_dims.z)) return;
    uint valid = w % wpr == wpr - 1u ? mask_upto((uint(u_dims.x) - 1u) & 31u) : 0xFFFFFFFFu;
    uint r = 0u;
    if (u_carve) r |= carve[w];
    if (u_vote) r |= v2[w] | (v1[w] & v0[w]);
    if (u_surface) r |= surface[w];
    r &= valid;
    carve[w] = r;
    uint n = uint(bitCount(r));
    if (n != 0u) atomicAdd(voxel_count[0], n);
}
