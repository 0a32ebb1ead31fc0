#version 450
// binvox -down: halve the grid along every axis; an output voxel is set when at least
// u_dmin of the 2 x 2 x 2 voxels it covers are set (binvox's -dmin, default 4).
// u_dims is the output grid; Fine holds the grid of twice its dims.
layout(local_size_x = 64) in;
#include "common/bits.glsl"
#include "common/dispatch.glsl"
#include "common/voxel_space.glsl"
uniform int u_dmin;
layout(std430, binding = 0) readonly buffer Fine { uint fine[]; };
layout(std430, binding = 1) writeonly buffer Coarse { uint coarse[]; };
layout(std430, binding = 2) buffer Count { uint voxel_count[]; };

void main() {
    uint w = global_index_1d();
    uint wpr = words_per_row();
    uint nx = uint(u_dims.x), ny = uint(u_dims.y), nz = uint(u_dims.z);
    if (w >= wpr * ny * nz) return;
    uint wi = w % wpr, row = w / wpr, j = row % ny, k = row / ny;
    uint fwpr = (2u * nx + 31u) / 32u, fny = 2u * ny;
    uint r = 0u;
    for (uint b = 0u; b < 32u; ++b) {
        uint i = wi * 32u + b;
        if (i >= nx) break;
        uint n = 0u;
        for (uint dz = 0u; dz < 2u; ++dz) {
            for (uint dy = 0u; dy < 2u; ++dy) {
                uint base = ((2u * k + dz) * fny + 2u * j + dy) * fwpr;
                uint x = 2u * i;
                // x and x + 1 share a word: x is even
                n += uint(bitCount((fine[base + x / 32u] >> (x & 31u)) & 3u));
            }
        }
        if (n >= uint(u_dmin)) r |= bit_of(b);
    }
    coarse[w] = r;
    uint c = uint(bitCount(r));
    if (c != 0u) atomicAdd(voxel_count[0], c);
}
