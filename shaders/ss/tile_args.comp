#version 450
// ss-solid-tiled: indirect dispatch arguments of the tile passes.  Pass p
// handles triangles p * TILE_TRIANGLES ... of every active tile; it gets one
// work group per active tile while the fullest tile has triangles left, and
// none afterwards (the CPU issues an upper bound of passes from the pair
// count and the empty ones cost nothing).  Work groups beyond
// GL_MAX_COMPUTE_WORK_GROUP_COUNT along x continue along y.
layout(local_size_x = 1) in;
layout(std430, binding = 4) readonly buffer Stats { uint stats[]; };
layout(std430, binding = 5) writeonly buffer Args { uint args[]; };
uniform uint u_passes;
uniform uint u_max_groups;
void main() {
    uint n = stats[0], most = stats[1];
    uint x = min(n, u_max_groups), y = x == 0u ? 0u : (n + x - 1u) / x;
    for (uint p = 0u; p < u_passes; ++p) {
        bool work = most > p * uint(TILE_TRIANGLES);
        args[3u * p] = work ? x : 0u;
        args[3u * p + 1u] = work ? y : 0u;
        args[3u * p + 2u] = work ? 1u : 0u;
    }
}
