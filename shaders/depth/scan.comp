#version 450
// Prefix XOR of the flip marks along the view axis, in place: afterwards a voxel's bit is
// the parity of the recorded crossings before its center along that axis.  Along x a row
// is a run of words (XOR within each word by doubling shifts, then a carry); along y and
// z one invocation walks a column of words, slices [u_first, u_first + u_count) per
// dispatch (the caller keeps u_count far below the loop budget and runs the segments in
// order, each continuing from the slice before it).
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
#include "common/voxel_space.glsl"
uniform int u_axis;
uniform uint u_first;
uniform uint u_count;
layout(std430, binding = 0) buffer Flips { uint flips[]; };

void main() {
    uint line = global_index_1d();
    uint wpr = words_per_row();
    uint ny = uint(u_dims.y), nz = uint(u_dims.z);
    if (u_axis == 0) {
        if (line >= ny * nz) return;
        uint base = line * wpr;
        uint carry = 0u;
        for (uint w = 0u; w < wpr; ++w) {
            uint x = flips[base + w];
            x ^= x << 1;
            x ^= x << 2;
            x ^= x << 4;
            x ^= x << 8;
            x ^= x << 16;
            x ^= carry;
            flips[base + w] = x;
            carry = (x >> 31) != 0u ? 0xFFFFFFFFu : 0u;
        }
        return;
    }
    uint stride, start;
    if (u_axis == 1) {  // line = (word w, slice k); steps along j
        if (line >= wpr * nz) return;
        uint w = line % wpr, k = line / wpr;
        stride = wpr;
        start = k * ny * wpr + w;
    } else {            // line = (word w, row j); steps along k
        if (line >= wpr * ny) return;
        uint w = line % wpr, j = line / wpr;
        stride = ny * wpr;
        start = j * wpr + w;
    }
    uint idx = start + u_first * stride;
    uint carry = u_first > 0u ? flips[idx - stride] : 0u;
    for (uint s = 0u; s < u_count; ++s, idx += stride) {
        carry ^= flips[idx];
        flips[idx] = carry;
    }
}
