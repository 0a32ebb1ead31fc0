#version 450
// ss-solid, pass 3: turns the crossing bits of ss/solid.comp into voxels, in
// place.  Voxel x of a row is set when an odd number of crossings lie at or
// before x: the prefix XOR along the row, each word a 32-bit prefix XOR (five
// shifts) flipped by the carry of the words before it.
//
// The grid was cleared before the voxelize pass, so the pass visits only the
// rows of u_rows (the mesh's projected bounding box on the (y, z) plane: no
// other row has a crossing) and writes only the words that change: words with
// crossings or an odd carry.  Every invocation does ROWS rows; the set voxels
// are counted on the way (voxel_count), so no one counts the grid again on
// the CPU.
//
// VEC words (1, 2 or 4, dividing the words per row) move per load and store:
// llvmpipe accesses a buffer lane by lane, so wider accesses mean fewer of
// them (measured: 4 words take 0.6 the time of 1 at 1024^3).
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
layout(std430, binding = 5) buffer Count { uint voxel_count; };
// the rows that may hold crossings: j0, k0, and their count along y and z
uniform ivec4 u_rows;

// 0 or ~0 for each component: the parity bit b (0 or 1) spread to all bits
#define SPREAD(b) (WORDS(0u) - (b))

void main() {
    uint nj = uint(u_rows.z), rows = nj * uint(u_rows.w);
    uint wpr = words_per_row();
    uint n = wpr / uint(VEC);
    // the bits past nx stay zero (an open mesh can leave the parity odd)
    uint last_mask = mask_upto(uint(u_dims.x) - 32u * (wpr - 1u) - 1u);
    uint count = 0u;
    for (uint i = 0u; i < uint(ROWS); ++i) {
        uint r = global_index_1d() * uint(ROWS) + i;
        if (r >= rows) break;
        uint row = (uint(u_rows.y) + r / nj) * uint(u_dims.y) + uint(u_rows.x) + r % nj;
        uint base = row * n;
        uint carry = 0u;  // 0 or ~0: parity of the crossings before this load
        for (uint w = 0u; w < n; ++w) {
            WORDS c = grid[base + w];
            if (c == WORDS(0u) && carry == 0u) continue;  // stays zero
            c ^= c << 1u;
            c ^= c << 2u;
            c ^= c << 4u;
            c ^= c << 8u;
            c ^= c << 16u;
#if VEC == 4
            uvec4 t = c >> 31u;  // parity of each word's own crossings
            c ^= SPREAD(uvec4(0u, t.x, t.x ^ t.y, t.x ^ t.y ^ t.z)) ^ carry;
            carry = 0u - (c.w >> 31u);
            if (w + 1u == n) c.w &= last_mask;
            count += uint(bitCount(c.x) + bitCount(c.y) + bitCount(c.z) + bitCount(c.w));
#elif VEC == 2
            uvec2 t = c >> 31u;
            c ^= SPREAD(uvec2(0u, t.x)) ^ carry;
            carry = 0u - (c.y >> 31u);
            if (w + 1u == n) c.y &= last_mask;
            count += uint(bitCount(c.x) + bitCount(c.y));
#else
            c ^= carry;
            carry = 0u - (c >> 31u);
            if (w + 1u == n) c &= last_mask;
            count += uint(bitCount(c));
#endif
            grid[base + w] = c;
        }
    }
    if (count != 0u) atomicAdd(voxel_count, count);
}
