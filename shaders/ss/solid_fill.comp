#version 450
// ss-solid, pass 3: one invocation per row (j, k) turns the row's crossing
// bits (ss/solid.comp) into voxels: voxel x is set when an odd number of
// crossings lie at or before x, the prefix XOR along the row.  Each word is
// a 32-bit prefix XOR (five shifts) flipped by the carry of the words
// before it.  Every word of the grid is written (no clear needed), and the
// crossing words are zeroed as they are read, so the crossing grid is clean
// for the next run without a separate clear.  The set voxels are counted on
// the way (voxel_count), so no one counts 128 MiB again on the CPU.
//
// VEC words (1, 2 or 4, dividing the words per row) move per load and store:
// llvmpipe runs an invocation per SIMD lane, and each lane walks its own row,
// so wider loads mean fewer gathers (measured: 4 words take 0.6 the time of 1
// at 1024^3).
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
layout(std430, binding = 3) buffer Crossings { WORDS crossings[]; };
layout(std430, binding = 4) writeonly buffer Grid { WORDS grid[]; };
layout(std430, binding = 5) buffer Count { uint voxel_count; };

shared uint group_count;

// 0 or ~0 for each component: the parity bit b (0 or 1) spread to all bits
#define SPREAD(b) (WORDS(0u) - (b))

void main() {
    if (gl_LocalInvocationIndex == 0u) group_count = 0u;
    barrier();
    uint r = global_index_1d();
    uint count = 0u;
    if (r < uint(u_dims.y) * uint(u_dims.z)) {
        uint wpr = words_per_row();
        uint n = wpr / uint(VEC);
        uint base = r * n;
        uint carry = 0u;  // 0 or ~0: parity of the crossings before this load
        // the bits past nx stay zero (an open mesh can leave the parity odd)
        uint last_mask = mask_upto(uint(u_dims.x) - 32u * (wpr - 1u) - 1u);
        for (uint w = 0u; w < n; ++w) {
            WORDS c = crossings[base + w];
            if (c != WORDS(0u)) crossings[base + w] = WORDS(0u);
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
    if (count != 0u) atomicAdd(group_count, count);
    barrier();
    if (gl_LocalInvocationIndex == 0u && group_count != 0u) atomicAdd(voxel_count, group_count);
}
