#version 450
// The render targets of one pass and tile -> glvox's packed grid
// (common/voxel_space.glsl: bit i % 32 of word (k * ny + j) * ceil(nx / 32) + i / 32).
//
// Pixel (pu, pv) of the tile holds the column at u = u_tile_lo.x + pu,
// v = u_tile_lo.y + pv (u, v = (a + 1) % 3, (a + 2) % 3) and its slices
// [u_slice_lo, u_slice_hi) along a as 4 words per target.
// EIS_AXIS 0: the slices are x, so a pixel's words are the grid's words of row
// (j, k) = (u, v): a copy, one invocation per pixel.  EIS_AXIS 2 (x = u) and 1 (x = v): one invocation
// takes 32 pixels consecutive in x and one target, four 32 x 32 bit matrices
// (one per channel), and transposes them into 4 x 32 grid words (128 rows,
// one x word each).
// Tiles start at multiples of 32 along x, so every grid word is written by
// exactly one invocation of one (tile, pass), with plain stores; each
// invocation adds the set bits of the words it stored to voxel_count once,
// so the count is the grid's.
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
#include "common/bits.glsl"
#include "common/voxel_space.glsl"

layout(rgba32ui, binding = 0) readonly uniform uimage2D u_target0;
#if EIS_TARGETS > 1
layout(rgba32ui, binding = 1) readonly uniform uimage2D u_target1;
#endif
#if EIS_TARGETS > 2
layout(rgba32ui, binding = 2) readonly uniform uimage2D u_target2;
#endif
#if EIS_TARGETS > 3
layout(rgba32ui, binding = 3) readonly uniform uimage2D u_target3;
#endif
#if EIS_TARGETS > 4
layout(rgba32ui, binding = 4) readonly uniform uimage2D u_target4;
#endif
#if EIS_TARGETS > 5
layout(rgba32ui, binding = 5) readonly uniform uimage2D u_target5;
#endif
#if EIS_TARGETS > 6
layout(rgba32ui, binding = 6) readonly uniform uimage2D u_target6;
#endif
#if EIS_TARGETS > 7
layout(rgba32ui, binding = 7) readonly uniform uimage2D u_target7;
#endif

layout(std430, binding = 2) writeonly buffer Grid { uint grid[]; };
layout(std430, binding = 3) buffer Count { uint voxel_count; };

uniform ivec2 u_tile_lo;
uniform ivec2 u_tile_size;
uniform int u_slice_lo;
uniform int u_slice_hi;
uniform int u_words_x;  // ceil(tile extent along x / 32) (axes 1, 2)
uniform uint u_invocations;

// Target t (0 .. EIS_TARGETS - 1) of pixel p: slices 128 t .. 128 t + 127 of the pass.
uvec4 slice_words(ivec2 p, int t) {
    switch (t) {
        case 0: return imageLoad(u_target0, p);
#if EIS_TARGETS > 1
        case 1: return imageLoad(u_target1, p);
#endif
#if EIS_TARGETS > 2
        case 2: return imageLoad(u_target2, p);
#endif
#if EIS_TARGETS > 3
        case 3: return imageLoad(u_target3, p);
#endif
#if EIS_TARGETS > 4
        case 4: return imageLoad(u_target4, p);
#endif
#if EIS_TARGETS > 5
        case 5: return imageLoad(u_target5, p);
#endif
#if EIS_TARGETS > 6
        case 6: return imageLoad(u_target6, p);
#endif
#if EIS_TARGETS > 7
        case 7: return imageLoad(u_target7, p);
#endif
    }
    return uvec4(0u);
}

uint row_word(int j, int k, int xw) { return word_index(ivec3(32 * xw, j, k)); }

void main() {
    uint g = global_index_1d();
    if (g >= u_invocations) return;
    uint n_set = 0u;
#if EIS_AXIS == 0
    // one invocation per pixel: the pass's grid words of row (j, k) = (u, v), 4 per
    // target, stored in order.  The target is the loop's, the same in every
    // invocation: a target picked per invocation made neighbouring invocations take
    // different branches of slice_words (llvmpipe: each ran all of them; a GPU's
    // warp runs them one after the other), 2.6x the time at 1024^3 on llvmpipe.
    ivec2 p = ivec2(int(g % uint(u_tile_size.x)), int(g / uint(u_tile_size.x)));
    uint row = row_word(u_tile_lo.x + p.x, u_tile_lo.y + p.y, 0);
    for (int t = 0; t < EIS_TARGETS; ++t) {
        uvec4 words = slice_words(p, t);
        for (int c = 0; c < 4; ++c) {
            int xw = (u_slice_lo >> 5) + 4 * t + c;
            int x0 = 32 * xw;
            if (x0 >= u_slice_hi) break;
            uint value = words[c];
            if (x0 + 32 > u_slice_hi) value &= mask_upto(uint(u_slice_hi - 1 - x0));  // past the grid
            grid[row + uint(xw)] = value;
            n_set += uint(bitCount(value));
        }
    }
#else
    // one invocation per 32 pixels consecutive in x and one target: four 32 x 32
    // bit matrices (one per channel), transposed together in uvec4 lanes
    int xw = int(g % uint(u_words_x));
    uint rest = g / uint(u_words_x);
#if EIS_AXIS == 2
    int other_n = u_tile_size.y, x_n = u_tile_size.x;  // pixel = (x, y)
#else
    int other_n = u_tile_size.x, x_n = u_tile_size.y;  // pixel = (z, x)
#endif
    int other = int(rest % uint(other_n));
    int t = int(rest / uint(other_n));
    uvec4 a[32];
    for (int b = 0; b < 32; ++b) {
        int x = 32 * xw + b;
#if EIS_AXIS == 2
        a[b] = x < x_n ? slice_words(ivec2(x, other), t) : uvec4(0u);
#else
        a[b] = x < x_n ? slice_words(ivec2(other, x), t) : uvec4(0u);
#endif
    }
    // 32 x 32 bit transpose by recursive block swaps: afterwards bit b of a[c]
    // is the former bit c of a[b], so a[c] holds slice c of the 32 columns.
    // Stage j swaps, for every k with bit j clear, the bits of a[k] in the upper
    // half of each 2j-bit block (~m) with those of a[k + j] in the lower half (m).
    // Written out: with constant indices a[] stays in registers, where a loop's
    // computed ones put it in memory (llvmpipe: the pack at 512^3 took 2.6x as
    // long).
#define EIS_SWAP(k, j, m) { uvec4 d = ((a[k] >> j) ^ a[k + j]) & m; a[k + j] ^= d; a[k] ^= d << j; }
    // j = 16, m = 0x0000FFFFu
    EIS_SWAP(0, 16, 0x0000FFFFu) EIS_SWAP(1, 16, 0x0000FFFFu) EIS_SWAP(2, 16, 0x0000FFFFu) EIS_SWAP(3, 16, 0x0000FFFFu)
    EIS_SWAP(4, 16, 0x0000FFFFu) EIS_SWAP(5, 16, 0x0000FFFFu) EIS_SWAP(6, 16, 0x0000FFFFu) EIS_SWAP(7, 16, 0x0000FFFFu)
    EIS_SWAP(8, 16, 0x0000FFFFu) EIS_SWAP(9, 16, 0x0000FFFFu) EIS_SWAP(10, 16, 0x0000FFFFu) EIS_SWAP(11, 16, 0x0000FFFFu)
    EIS_SWAP(12, 16, 0x0000FFFFu) EIS_SWAP(13, 16, 0x0000FFFFu) EIS_SWAP(14, 16, 0x0000FFFFu) EIS_SWAP(15, 16, 0x0000FFFFu)
    // j = 8, m = 0x00FF00FFu
    EIS_SWAP(0, 8, 0x00FF00FFu) EIS_SWAP(1, 8, 0x00FF00FFu) EIS_SWAP(2, 8, 0x00FF00FFu) EIS_SWAP(3, 8, 0x00FF00FFu)
    EIS_SWAP(4, 8, 0x00FF00FFu) EIS_SWAP(5, 8, 0x00FF00FFu) EIS_SWAP(6, 8, 0x00FF00FFu) EIS_SWAP(7, 8, 0x00FF00FFu)
    EIS_SWAP(16, 8, 0x00FF00FFu) EIS_SWAP(17, 8, 0x00FF00FFu) EIS_SWAP(18, 8, 0x00FF00FFu) EIS_SWAP(19, 8, 0x00FF00FFu)
    EIS_SWAP(20, 8, 0x00FF00FFu) EIS_SWAP(21, 8, 0x00FF00FFu) EIS_SWAP(22, 8, 0x00FF00FFu) EIS_SWAP(23, 8, 0x00FF00FFu)
    // j = 4, m = 0x0F0F0F0Fu
    EIS_SWAP(0, 4, 0x0F0F0F0Fu) EIS_SWAP(1, 4, 0x0F0F0F0Fu) EIS_SWAP(2, 4, 0x0F0F0F0Fu) EIS_SWAP(3, 4, 0x0F0F0F0Fu)
    EIS_SWAP(8, 4, 0x0F0F0F0Fu) EIS_SWAP(9, 4, 0x0F0F0F0Fu) EIS_SWAP(10, 4, 0x0F0F0F0Fu) EIS_SWAP(11, 4, 0x0F0F0F0Fu)
    EIS_SWAP(16, 4, 0x0F0F0F0Fu) EIS_SWAP(17, 4, 0x0F0F0F0Fu) EIS_SWAP(18, 4, 0x0F0F0F0Fu) EIS_SWAP(19, 4, 0x0F0F0F0Fu)
    EIS_SWAP(24, 4, 0x0F0F0F0Fu) EIS_SWAP(25, 4, 0x0F0F0F0Fu) EIS_SWAP(26, 4, 0x0F0F0F0Fu) EIS_SWAP(27, 4, 0x0F0F0F0Fu)
    // j = 2, m = 0x33333333u
    EIS_SWAP(0, 2, 0x33333333u) EIS_SWAP(1, 2, 0x33333333u) EIS_SWAP(4, 2, 0x33333333u) EIS_SWAP(5, 2, 0x33333333u)
    EIS_SWAP(8, 2, 0x33333333u) EIS_SWAP(9, 2, 0x33333333u) EIS_SWAP(12, 2, 0x33333333u) EIS_SWAP(13, 2, 0x33333333u)
    EIS_SWAP(16, 2, 0x33333333u) EIS_SWAP(17, 2, 0x33333333u) EIS_SWAP(20, 2, 0x33333333u) EIS_SWAP(21, 2, 0x33333333u)
    EIS_SWAP(24, 2, 0x33333333u) EIS_SWAP(25, 2, 0x33333333u) EIS_SWAP(28, 2, 0x33333333u) EIS_SWAP(29, 2, 0x33333333u)
    // j = 1, m = 0x55555555u
    EIS_SWAP(0, 1, 0x55555555u) EIS_SWAP(2, 1, 0x55555555u) EIS_SWAP(4, 1, 0x55555555u) EIS_SWAP(6, 1, 0x55555555u)
    EIS_SWAP(8, 1, 0x55555555u) EIS_SWAP(10, 1, 0x55555555u) EIS_SWAP(12, 1, 0x55555555u) EIS_SWAP(14, 1, 0x55555555u)
    EIS_SWAP(16, 1, 0x55555555u) EIS_SWAP(18, 1, 0x55555555u) EIS_SWAP(20, 1, 0x55555555u) EIS_SWAP(22, 1, 0x55555555u)
    EIS_SWAP(24, 1, 0x55555555u) EIS_SWAP(26, 1, 0x55555555u) EIS_SWAP(28, 1, 0x55555555u) EIS_SWAP(30, 1, 0x55555555u)
#undef EIS_SWAP
#if EIS_AXIS == 2
    int x_word = (u_tile_lo.x >> 5) + xw;
    int j = u_tile_lo.y + other;
#else
    int x_word = (u_tile_lo.y >> 5) + xw;
    int k = u_tile_lo.x + other;
#endif
    for (int ch = 0; ch < 4; ++ch) {
        int s0 = u_slice_lo + 128 * t + 32 * ch;
        for (int c = 0; c < 32; ++c) {
            if (s0 + c >= u_slice_hi) break;
#if EIS_AXIS == 2
            grid[row_word(j, s0 + c, x_word)] = a[c][ch];
#else
            grid[row_word(s0 + c, k, x_word)] = a[c][ch];
#endif
            n_set += uint(bitCount(a[c][ch]));
        }
    }
#endif
    if (n_set != 0u) atomicAdd(voxel_count, n_set);
}
