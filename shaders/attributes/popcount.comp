#version 450
// Set voxels per grid word, for the scan that ranks the set voxels (their slots).
layout(local_size_x = 256) in;
#include "common/dispatch.glsl"
layout(std430, binding = 3) readonly buffer Grid { uint grid[]; };
layout(std430, binding = 9) writeonly buffer Counts { uint counts[]; };
uniform uint u_words;
void main() {
    uint w = global_index_1d();
    if (w < u_words) counts[w] = uint(bitCount(grid[w]));
}
