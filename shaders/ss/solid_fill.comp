#version 450
#if WORD64
#extension GL_ARB_gpu_shader_int64 : require
#endif
// ss-solid, pass 3: turns the crossing bits of ss/solid.comp into voxels, in
// place.  Voxel x of a row is set when an odd number of crossings lie at or
// before x: the prefix XOR along the row, each word a prefix XOR (five shifts
// for 32-bit words, six for 64) flipped by the carry of the words before it.
//
// The grid was cleared before the voxelize pass, so the pass visits only the
// rows of u_rows (the mesh's projected bounding box on the (y, z) plane: no
// other row has a crossing) and writes only the words that change: words with
// crossings or an odd carry.  Every invocation does u_rows_per rows (set by
// glvox.methods.ss.solid_tuning.fill_rows within LOOP_BUDGET); the set voxels
// are counted on the way (voxel_count), so no one counts the grid again on
// the CPU.
//
// VEC words (1, 2 or 4, dividing the row) move per load and store, and
// WORD64 1 makes them 64-bit words (pairs of the grid's 32-bit words, the
// lower one first, which is the same bit order on the little-endian machines
// GL_ARB_gpu_shader_int64 runs on): llvmpipe accesses a buffer lane by lane
// and component by component, so wider accesses mean fewer of them
// (measured at 1024^3: 4 words take 0.6 the time of 1, 64-bit words 0.85
// the time of 32-bit ones).
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
#if WORD64
#define WORD uint64_t
#define BITS 64u
#define COUNT1(v) (bitCount(unpackUint2x32(v)).x + bitCount(unpackUint2x32(v)).y)
#else
#define WORD uint
#define BITS 32u
#define COUNT1(v) bitCount(v)
#endif
#if VEC == 4
#define WORDS_OF(T) T##vec4
#elif VEC == 2
#define WORDS_OF(T) T##vec2
#endif
#if WORD64 && VEC > 1
#define WORDS WORDS_OF(u64)
#elif VEC > 1
#define WORDS WORDS_OF(u)
#else
#define WORDS WORD
#endif
layout(std430, binding = 3) buffer Grid { WORDS grid[]; };
layout(std430, binding = 5) buffer Count { uint voxel_count; };
// the rows that may hold crossings: j0, k0, and their count along y and z
uniform ivec4 u_rows;
uniform uint u_rows_per;

// 0 or ~0 for each component: the parity bit b (0 or 1) spread to all bits
#define SPREAD(b) (WORDS(0u) - (b))

void main() {
    uint nj = uint(u_rows.z), rows = nj * uint(u_rows.w);
    uint wpr = words_per_row();
    uint per_word = BITS / 32u;        // grid words per WORD
    uint n = wpr / (per_word * uint(VEC));
    // the bits past nx stay zero (an open mesh can leave the parity odd)
    uint last_bit = uint(u_dims.x) - BITS * (wpr / per_word - 1u) - 1u;
#if WORD64
    WORD last_mask = last_bit >= 63u ? ~WORD(0u) : (WORD(1u) << (last_bit + 1u)) - WORD(1u);
#else
    WORD last_mask = mask_upto(last_bit);
#endif
    uint count = 0u;
    for (uint i = 0u; i < u_rows_per; ++i) {
        uint r = global_index_1d() * u_rows_per + i;
        if (r >= rows) break;
        uint row = (uint(u_rows.y) + r / nj) * uint(u_dims.y) + uint(u_rows.x) + r % nj;
        uint base = row * n;
        WORD carry = WORD(0u);  // 0 or ~0: parity of the crossings before this load
        for (uint w = 0u; w < n; ++w) {
            WORDS c = grid[base + w];
            if (c == WORDS(0u) && carry == WORD(0u)) continue;  // stays zero
            c ^= c << 1u;
            c ^= c << 2u;
            c ^= c << 4u;
            c ^= c << 8u;
            c ^= c << 16u;
#if WORD64
            c ^= c << 32u;
#endif
            WORDS t = c >> (BITS - 1u);  // parity of each word's own crossings
#if VEC == 4
            c ^= SPREAD(WORDS(0u, t.x, t.x ^ t.y, t.x ^ t.y ^ t.z)) ^ carry;
            carry = WORD(0u) - (c.w >> (BITS - 1u));
            if (w + 1u == n) c.w &= last_mask;
            count += uint(COUNT1(c.x) + COUNT1(c.y) + COUNT1(c.z) + COUNT1(c.w));
#elif VEC == 2
            c ^= SPREAD(WORDS(0u, t.x)) ^ carry;
            carry = WORD(0u) - (c.y >> (BITS - 1u));
            if (w + 1u == n) c.y &= last_mask;
            count += uint(COUNT1(c.x) + COUNT1(c.y));
#else
            c ^= carry;
            carry = WORD(0u) - (c >> (BITS - 1u));
            if (w + 1u == n) c &= last_mask;
            count += uint(COUNT1(c));
#endif
            grid[base + w] = c;
        }
    }
    if (count != 0u) atomicAdd(voxel_count, count);
}
