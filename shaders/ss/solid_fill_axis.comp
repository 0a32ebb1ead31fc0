#version 450
// vote-solid's parity along y (AXIS 1) or z (AXIS 2), in the grid's own
// x-packed layout: ss/solid.comp (FLIP_AXIS = AXIS) left one bit per crossing
// at the first voxel it flips; each voxel becomes the XOR of the crossing bits
// at or before it along AXIS: a running XOR down every column of words, 32 x
// positions per word, VEC words per load.
//
// One invocation per column of VEC words and segment of SEGMENT cells (the
// loop bound; llvmpipe ends an invocation's loops after 65535 iterations).
// Segments run one after the other (u_segment): segment s starts from the
// last cell of segment s - 1, already final.
#include "common/bits.glsl"
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
layout(std430, binding = 3) buffer Grid { WORDS grid[]; };
uniform int u_segment;

void main() {
    uint nv = words_per_row() / uint(VEC);
    uint lines = nv * uint(AXIS == 1 ? u_dims.z : u_dims.y);
    uint line = global_index_1d();
    if (line >= lines) return;
    uint v = line % nv, other = line / nv;
    uint stride = AXIS == 1 ? nv : nv * uint(u_dims.y);
    uint first = AXIS == 1 ? other * uint(u_dims.y) * nv + v : other * nv + v;
    int c0 = u_segment * SEGMENT, c1 = min(u_dims[AXIS], c0 + SEGMENT);
    WORDS acc = c0 > 0 ? grid[first + uint(c0 - 1) * stride] : WORDS(0u);
    for (int c = c0; c < c1; ++c) {
        uint idx = first + uint(c) * stride;
        WORDS x = grid[idx];
        acc ^= x;
        if (acc != x) grid[idx] = acc;
    }
}
