#version 450
// carve-solid, option close=K: one axis of the separable morphological closing
// of the surface by a box of side K + 1 (glvox.reference.carve.close), on the
// padded grid of carve/pad.comp (u_dims: its dims, nx a multiple of 32).
//
// ERODE 0 (dilation): out[p] = OR of src[p + d] for d in [-u_lo, u_hi] along
// AXIS; ERODE 1 (erosion, after the three dilations): out[p] = AND of
// src[p + d] for d in [-u_hi, u_lo].  Reads beyond the padded grid count as
// empty: the padding is wider than the window, so they only reach voxels
// outside the real grid, which carve/pad.comp drops.  One invocation per
// word; along x the window stays within the word and its two neighbours
// (|d| <= 16, glvox.reference.carve.MAX_CLOSE), along y and z it reads K + 1
// words: at most 33 loop iterations.
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
#include "carve/grid_words.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 0) readonly buffer Src { uint src[]; };
layout(std430, binding = 1) writeonly buffer Dst { uint dst[]; };
uniform int u_lo;
uniform int u_hi;

#if ERODE
#define COMBINE(a, b) ((a) & (b))
#define START 0xFFFFFFFFu
#else
#define COMBINE(a, b) ((a) | (b))
#define START 0u
#endif

void main() {
    uint wpr = words_per_row();
    uint n = wpr * uint(u_dims.y) * uint(u_dims.z);
    uint idx = global_index_1d();
    if (idx >= n) return;
    uint w = idx % wpr;
    uint row = idx / wpr;
    // window [-a, b] of the offsets d, out[p] combining src[p + d]
#if ERODE
    int a = u_hi, b = u_lo;
#else
    int a = u_lo, b = u_hi;
#endif
    uint acc = START;
#if AXIS == 0
    uint cur = src[idx];
    uint prev = w > 0u ? src[idx - 1u] : 0u;
    uint next = w + 1u < wpr ? src[idx + 1u] : 0u;
    for (int d = -a; d <= b; ++d) {
        uint v;
        if (d > 0) v = (cur >> uint(d)) | (next << uint(32 - d));
        else if (d < 0) v = (cur << uint(-d)) | (prev >> uint(32 + d));
        else v = cur;
        acc = COMBINE(acc, v);
    }
#else
    int n_axis = u_dims[AXIS];
    int at = AXIS == 1 ? int(row % uint(u_dims.y)) : int(row / uint(u_dims.y));
    uint stride = axis_stride(AXIS);
    for (int d = -a; d <= b; ++d) {
        int q = at + d;
        uint v = (q < 0 || q >= n_axis) ? 0u : src[uint(int(idx) + d * int(stride))];
        acc = COMBINE(acc, v);
    }
#endif
    dst[idx] = acc;
}
