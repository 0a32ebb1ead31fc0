// The bit masks a fragment writes into the EIS_TARGETS RGBA32UI render
// targets of one pass: EIS_SLICES = 128 * EIS_TARGETS slices, slice s of the
// pass being bit s % 32 of channel (s / 32) % 4 of target s / 128.
//
// EIS_MASKS 0: bit arithmetic in the shader; 1: a precomputed mask table
// (u_mask_table, EIS_TARGETS x (EIS_SLICES + 1) texels, row r = the mask of
// slice r), as Eisemann & Decoret look the mask up in a texture.
// compare/bench_eisemann_masks.py measures the two.

#define EIS_SLICES (128 * EIS_TARGETS)
#define TARGETS_N EIS_TARGETS
#include "common/each_target.glsl"

layout(location = 0) out uvec4 o_masks[EIS_TARGETS];

#if EIS_MASKS == 1
uniform usampler2D u_mask_table;
#endif

// Ones at every slice >= first of the pass (first <= 0: all; >= EIS_SLICES: none).
void eis_write_suffix(int first) {
#if EIS_MASKS == 1
    int row = clamp(first, 0, EIS_SLICES);
#define EIS_SUFFIX(t) o_masks[t] = texelFetch(u_mask_table, ivec2(t, row), 0);
#else
    // bits of the four words of target t below `first`, 0..32 each; a shift by 32 is undefined
#define EIS_SUFFIX(t) { \
        ivec4 lo = clamp(ivec4(first - 128 * t) - ivec4(0, 32, 64, 96), 0, 32); \
        uvec4 m = uvec4(0xFFFFFFFFu) << uvec4(min(lo, ivec4(31))); \
        o_masks[t] = mix(m, uvec4(0u), equal(lo, ivec4(32))); }
#endif
    EACH_TARGET(EIS_SUFFIX)
}

// The single slice s of the pass (0 <= s < EIS_SLICES).
void eis_write_bit(int s) {
#if EIS_MASKS == 1
#define EIS_BIT(t) o_masks[t] = texelFetch(u_mask_table, ivec2(t, s), 0);
#else
    // rel: s relative to each word of target t; the bit where 0 <= rel < 32
#define EIS_BIT(t) { \
        ivec4 rel = ivec4(s - 128 * t) - ivec4(0, 32, 64, 96); \
        o_masks[t] = mix(uvec4(0u), uvec4(1u) << uvec4(rel & 31), equal(rel >> 5, ivec4(0))); }
#endif
    EACH_TARGET(EIS_BIT)
}

// Zeros in every target (eisemann/clear.frag).
void eis_write_zeros() {
#define EIS_ZERO(t) o_masks[t] = uvec4(0u);
    EACH_TARGET(EIS_ZERO)
}
