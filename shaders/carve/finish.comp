#version 450
// carve-solid, last pass: the solid is every voxel the flood fill did not
// reach, in place of the exterior (bits past nx stay zero), counted on the way.
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
#include "carve/grid_words.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 1) buffer Exterior { uint ext[]; };
layout(std430, binding = 2) buffer Count { uint voxel_count; };
uniform uint u_first_word;  // words before u_first_word and from u_first_word + u_words on are not visited
uniform uint u_words;

void main() {
    uint i = global_index_1d();
    if (i >= u_words) return;
    uint idx = u_first_word + i;
    uint s = ~ext[idx] & valid_bits(idx % words_per_row());
    ext[idx] = s;
    uint c = uint(bitCount(s));
    if (c != 0u) atomicAdd(voxel_count, c);
}
