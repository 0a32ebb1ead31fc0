#version 450
// Jump flood (Rong & Tan 2006) over the set voxels of a solid: every voxel
// ends with the coordinates of a near surface voxel (one whose source triangle
// exists), for --fill-attributes nearest.  One invocation per grid word, its
// (at most 32) set voxels each looking at 27 voxels u_step apart; seeds are
// read from u_in and written to u_out (ping-pong), so no pass sees its own
// writes.  Only set voxels hold seeds: the flood runs through the solid.
//   u_mode 0: init (a voxel with a source triangle is its own seed)
//   u_mode 1: one jump-flood step
//   u_mode 2: the seed's slot, for the gather of its attributes
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 3) readonly buffer Grid { uint grid[]; };
layout(std430, binding = 9) readonly buffer Offsets { uint word_offset[]; };
layout(std430, binding = 11) readonly buffer BestTri { uint best_tri[]; };
layout(std430, binding = 12) readonly buffer SeedIn { uvec2 seed_in[]; };  // (x | y << 16, z); x NONE: no seed yet
layout(std430, binding = 13) writeonly buffer SeedOut { uvec2 seed_out[]; };
layout(std430, binding = 14) writeonly buffer SeedSlot { uint seed_slot[]; };
uniform uint u_words;
uniform int u_step;
uniform int u_mode;

const uint NONE = 0xFFFFFFFFu;

ivec3 unpack_seed(uvec2 s) { return ivec3(int(s.x & 0xFFFFu), int(s.x >> 16), int(s.y)); }
uvec2 pack_seed(ivec3 v) { return uvec2(uint(v.x) | (uint(v.y) << 16), uint(v.z)); }

// The slot of voxel v, or NONE when it is outside the grid or not set.
uint slot_of(ivec3 v) {
    if (!in_grid(v)) return NONE;
    uint w = word_index(v);
    uint word = grid[w];
    uint b = bit_of(uint(v.x));
    return (word & b) == 0u ? NONE : word_offset[w] + uint(bitCount(word & (b - 1u)));
}

int dist2(ivec3 a, ivec3 b) { ivec3 d = a - b; return d.x * d.x + d.y * d.y + d.z * d.z; }

void main() {
    uint w = global_index_1d();
    if (w >= u_words) return;
    uint word = grid[w];
    uint row = w / words_per_row();
    int i0 = int((w % words_per_row()) * 32u);
    ivec2 jk = ivec2(int(row % uint(u_dims.y)), int(row / uint(u_dims.y)));
    uint slot = word_offset[w];
    for (; word != 0u; word &= word - 1u, ++slot) {
        ivec3 v = ivec3(i0 + findLSB(word), jk);
        if (u_mode == 0) {
            seed_out[slot] = best_tri[slot] != NONE ? pack_seed(v) : uvec2(NONE, NONE);
            continue;
        }
        uvec2 best = seed_in[slot];
        if (u_mode == 2) {
            seed_slot[slot] = best.x == NONE ? NONE : slot_of(unpack_seed(best));
            continue;
        }
        int bd = best.x == NONE ? 0x7FFFFFFF : dist2(v, unpack_seed(best));
        for (int n = 0; n < 27; ++n) {
            ivec3 o = ivec3(n % 3 - 1, (n / 3) % 3 - 1, n / 9 - 1) * u_step;
            if (o == ivec3(0)) continue;
            uint s = slot_of(v + o);
            if (s == NONE) continue;
            uvec2 c = seed_in[s];
            if (c.x == NONE) continue;
            int d = dist2(v, unpack_seed(c));
            // ties: the smaller packed seed, so the result does not depend on the order of the reads
            if (d < bd || (d == bd && (c.y < best.y || (c.y == best.y && c.x < best.x)))) { bd = d; best = c; }
        }
        seed_out[slot] = best;
    }
}
