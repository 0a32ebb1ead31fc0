#version 450
// ss-solid-tiled (Schwarz & Seidel 2010, Sec. 4.2), tile processing: one
// work group per active tile, one invocation per voxel column of the tile.
// Each invocation walks the tile's triangles (TILE_TRIANGLES of them in this
// pass) keeping an active 32-bit segment of its row and a flip bitmask of
// the segments after it; a crossing outside the active segment first flushes
// it.  At the end the active segment is flushed and the flagged segments are
// flipped whole.  A row belongs to exactly one invocation, so every write is
// a plain read-modify-write: no atomics.  The voxel count follows the writes:
// each one changes its word's set bits by a known amount, and an invocation
// adds its net change (mod 2^32) to voxel_count once, so after the last pass
// voxel_count holds the grid's set bits (the grid starts empty).
//
// Departure: the paper sets up up to 14 triangles per warp in shared memory
// and runs two triangles per warp (twin threads); here each invocation sets up
// the triangle itself, which costs no barriers (expensive on llvmpipe).
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
#include "ss/solid.glsl"
#define SOLID_UNIT TILE
#include "ss/solid_input.glsl"
layout(local_size_x = TILE, local_size_y = TILE) in;
layout(std430, binding = 3) buffer Grid { uint grid[]; };
layout(std430, binding = 4) readonly buffer Stats { uint stats[]; };
layout(std430, binding = 5) buffer Count { uint voxel_count; };
layout(std430, binding = 6) readonly buffer Active { uint tiles[]; };
layout(std430, binding = 8) readonly buffer Values { uint values[]; };
uniform uint u_pairs;
uniform uint u_pass;

// Bits of the segments after `seg` in a 128-bit mask.
uvec4 segments_after(uint seg) {
    uvec4 m;
    for (int w = 0; w < 4; ++w) {
        int lo = int(seg) + 1 - 32 * w;
        m[w] = lo <= 0 ? 0xFFFFFFFFu : mask_from(uint(lo));
    }
    return m;
}

uint g_delta = 0u;  // this invocation's net change of set bits, mod 2^32

// grid[w] ^= bits, tracking the change of its set bits.
void flip_word(uint w, uint bits) {
    uint old = grid[w];
    uint now = old ^ bits;
    grid[w] = now;
    g_delta += uint(bitCount(now)) - uint(bitCount(old));
}

void main() {
    uint s = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    uint n_active = stats[0];
    if (s >= n_active) return;
    uint key = tiles[2u * s], start = tiles[2u * s + 1u];
    uint end = s + 1u < n_active ? tiles[2u * s + 3u] : u_pairs;
    uint first = start + u_pass * uint(TILE_TRIANGLES);
    if (first >= end) return;
    uint last = min(end, first + uint(TILE_TRIANGLES));
    uint tiles_y = (uint(u_dims.y) + uint(TILE) - 1u) / uint(TILE);
    int j = int(key % tiles_y) * TILE + int(gl_LocalInvocationID.x);
    int k = int(key / tiles_y) * TILE + int(gl_LocalInvocationID.y);
    if (j >= u_dims.y || k >= u_dims.z) return;
    ivec2 center = solid_center(ivec2(j, k));
    uint wpr = words_per_row();
    uint row = (uint(k) * uint(u_dims.y) + uint(j)) * wpr;

    // the last word keeps its bits past nx zero
    uint tail = mask_upto(uint(u_dims.x) - 32u * (wpr - 1u) - 1u);
    int seg = -1;      // active segment
    uint value = 0u;   // its pending flips
    uvec4 flips = uvec4(0u);
    for (uint p = first; p < last; ++p) {
        SolidTri T;
        dvec3 w;
        if (!load_solid_triangle(values[p], T) || !solid_covers(T, center, w)) continue;
        int f = solid_first_flip(T, w);
        if (f >= u_dims.x) continue;
        uint b = uint(max(f, 0));
        if (int(b >> 5) != seg) {
            if (seg >= 0) flip_word(row + uint(seg), value & (uint(seg) == wpr - 1u ? tail : 0xFFFFFFFFu));
            seg = int(b >> 5);
            value = 0u;
        }
        value ^= mask_from(b & 31u);
        flips ^= segments_after(b >> 5);
    }
    if (seg >= 0) flip_word(row + uint(seg), value & (uint(seg) == wpr - 1u ? tail : 0xFFFFFFFFu));
    for (int w = 0; w < 4; ++w) {
        uint bits = flips[w];
        while (bits != 0u) {
            uint g = uint(32 * w + findLSB(bits));
            bits &= bits - 1u;
            if (g < wpr) flip_word(row + g, g == wpr - 1u ? tail : 0xFFFFFFFFu);
        }
    }
    if (g_delta != 0u) atomicAdd(voxel_count, g_delta);
}
