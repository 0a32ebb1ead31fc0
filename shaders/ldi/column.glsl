// The bit masks of one ray (Leung & Wang 2013 Sec. III-B, III-C) and the fast bit
// checking of Eq. 1-5, carried across the words of the ray.
//
// Layout: ray c (ldi_column) holds u_words = ceil(LOD-C / 32) words from c * u_words; bit k
// of the ray is bit k % 32 of word k / 32; bits past LOD-C are zero.
//   T1 (binding 4): bit k = inside state at the top of cell k (the parity of the crossings
//       in cells 0..k), the XOR solid of Eisemann & Decoret on the LOD-C cells;
//   T2 (binding 5, with LDI_READ_T2): bit k = a fragment falls in cell k while
//       T1(k) = T1(k - 1) = 0 (Alg. 1 lines 8-16: the thin parts T1 misses).
// Cell k is bit k, as in the paper: Eq. 1, T1 & (((~T1) << 1) | 1), is T1(k) & ~T1(k - 1)
// with T1(-1) = 0, and across words its "| 1" becomes the carry of the previous word's top
// bit ("shifting across these 32 integers", Sec. III-E).  Eq. 2 is garbled in print; the
// leaving voxels it stands for are T1(k - 1) & ~T1(k) (Sec. III-B), computed the same way.
//
// Needs EIS_AXIS (the ray axis).
#include "ldi/cells.glsl"
#include "ldi/pixels.glsl"

layout(std430, binding = 4) readonly buffer LdiT1 { uint ldi_t1[]; };
#ifdef LDI_READ_T2
layout(std430, binding = 5) readonly buffer LdiT2 { uint ldi_t2[]; };
#endif

uniform int u_words;  // words per ray

uint ldi_t1_word(uint col, int w) {
    return (w < 0 || w >= u_words) ? 0u : ldi_t1[col * uint(u_words) + uint(w)];
}

// T1(k), with T1(-1) = 0 (outside before the grid).
bool ldi_t1_bit(uint col, int k) {
    return k >= 0 && ((ldi_t1_word(col, k >> 5) >> uint(k & 31)) & 1u) != 0u;
}

#ifdef LDI_READ_T2
uint ldi_t2_word(uint col, int w) {
    return (w < 0 || w >= u_words) ? 0u : ldi_t2[col * uint(u_words) + uint(w)];
}

bool ldi_t2_bit(uint col, int k) {
    return k >= 0 && ((ldi_t2_word(col, k >> 5) >> uint(k & 31)) & 1u) != 0u;
}

// Eq. 1-4 on word w: bits of the cells holding an entering sample (EV: T1 goes 0 -> 1,
// or ELV) and a leaving sample (LV: 1 -> 0, or ELV).  LEVs (T1 = 1 on both sides) are
// taken as solid and give none.
void ldi_marks(uint col, int w, out uint enter, out uint leave) {
    uint t = ldi_t1_word(col, w);
    uint below = (t << 1) | (ldi_t1_word(col, w - 1) >> 31);  // bit k: T1(k - 1)
    uint t2 = ldi_t2_word(col, w);
    enter = (t & ~below) | t2;
    leave = (~t & below) | t2;
}

// Eq. 5: samples of the ray in front of cell z (in cells 0 .. z - 1).  At most
// u_words iterations (LOD-C / 32, far below the loop budget).
int ldi_layers_ahead(uint col, int z) {
    int p = 0;
    int wz = z >> 5;
    uint e, l;
    for (int w = 0; w < wz; ++w) {
        ldi_marks(col, w, e, l);
        p += bitCount(e) + bitCount(l);
    }
    ldi_marks(col, wz, e, l);
    uint below_z = (1u << uint(z & 31)) - 1u;
    return p + bitCount(e & below_z) + bitCount(l & below_z);
}
#endif

// Float32 of a non-negative double, rounded up / down (the samples are rounded outwards,
// so the stored solid still encloses the computed one).
float ldi_round_up(double x) {
    float f = float(x);
    if (double(f) < x) f = uintBitsToFloat(floatBitsToUint(f) + 1u);
    return f;
}

float ldi_round_down(double x) {
    float f = float(x);
    if (double(f) > x) f = uintBitsToFloat(floatBitsToUint(f) - 1u);  // f > x >= 0
    return f;
}
