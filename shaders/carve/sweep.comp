#version 450
// carve-solid: one sweep of the exterior flood fill along AXIS.
//
// ext holds the exterior found so far (packed, a subset of the free voxels,
// those not in the blocker); a sweep spreads it along one axis through the
// free voxels, forward then backward, so after it every free run along that
// axis that held an exterior voxel is exterior.  Sweeps along x, y and z
// repeat until a round of them adds nothing (glvox.methods.carve): each
// round lets a path turn a corner more.
//
// AXIS 0: one invocation per row; within a word the run is filled by a
// 5-step occluded fill (Kogge-Stone, shifts 1, 2, 4, 8, 16), across words by
// a carry.  u_seed: the first sweep also makes exterior every free voxel on
// the grid's boundary.  AXIS 1, 2: one invocation per word column and
// segment of at most SEGMENT cells (bounding the loop: llvmpipe ends an
// invocation's loops after 65535 iterations), the 32 voxels of a word
// moving together; a segment starts from its neighbours' boundary cells as
// they are (they only grow, so a stale value is just less progress, and the
// next round sees the rest).  An invocation that adds a voxel sets `changed`.
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
#include "carve/grid_words.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 0) readonly buffer Blocker { uint blocker[]; };
layout(std430, binding = 1) coherent buffer Exterior { uint ext[]; };
layout(std430, binding = 2) buffer Flags { uint changed; };
uniform bool u_seed;

uint free_bits(uint idx, uint w) { return ~blocker[idx] & valid_bits(w); }

#if AXIS == 0
void main() {
    uint wpr = words_per_row();
    uint rows = uint(u_dims.y) * uint(u_dims.z);
    uint row = global_index_1d();
    if (row >= rows) return;
    uint j = row % uint(u_dims.y), k = row / uint(u_dims.y);
    bool face = j == 0u || k == 0u || j + 1u == uint(u_dims.y) || k + 1u == uint(u_dims.z);
    uint base = row * wpr;
    bool grew = false;
    uint carry = 0u;
    for (uint w = 0u; w < wpr; ++w) {
        uint f = free_bits(base + w, w);
        uint e0 = ext[base + w];
        uint g = e0 | (carry & f & 1u);
        if (u_seed) {
            uint edge = (w == 0u ? 1u : 0u) | (w + 1u == wpr ? bit_of(uint(u_dims.x - 1)) : 0u);
            g |= f & (face ? 0xFFFFFFFFu : edge);
        }
        uint p = f;
        g |= p & (g << 1u); p &= p << 1u;
        g |= p & (g << 2u); p &= p << 2u;
        g |= p & (g << 4u); p &= p << 4u;
        g |= p & (g << 8u); p &= p << 8u;
        g |= p & (g << 16u);
        carry = g >> 31u;
        if (g != e0) { ext[base + w] = g; grew = true; }
    }
    carry = 0u;
    for (uint w = wpr; w-- > 0u;) {
        uint f = free_bits(base + w, w);
        uint e0 = ext[base + w];
        uint g = e0 | ((carry << 31u) & f);
        uint p = f;
        g |= p & (g >> 1u); p &= p >> 1u;
        g |= p & (g >> 2u); p &= p >> 2u;
        g |= p & (g >> 4u); p &= p >> 4u;
        g |= p & (g >> 8u); p &= p >> 8u;
        g |= p & (g >> 16u);
        carry = g & 1u;
        if (g != e0) { ext[base + w] = g; grew = true; }
    }
    if (grew) changed = 1u;
}
#else
void main() {
    uint wpr = words_per_row();
    int n = u_dims[AXIS];
    uint segs = (uint(n) + uint(SEGMENT) - 1u) / uint(SEGMENT);
    // word columns: (w, k) along y, (w, j) along z
    uint lines = wpr * uint(AXIS == 1 ? u_dims.z : u_dims.y);
    uint id = global_index_1d();
    if (id >= lines * segs) return;
    uint line = id % lines, seg = id / lines;
    uint w = line % wpr, other = line / wpr;
    uint stride = axis_stride(AXIS);
    uint first = AXIS == 1 ? (other * uint(u_dims.y)) * wpr + w : other * wpr + w;
    int c0 = int(seg) * SEGMENT, c1 = min(n, c0 + SEGMENT);
    uint valid = valid_bits(w);
    bool grew = false;
    uint prev = c0 > 0 ? ext[first + uint(c0 - 1) * stride] : 0u;
    for (int c = c0; c < c1; ++c) {
        uint idx = first + uint(c) * stride;
        uint e0 = ext[idx];
        uint g = e0 | (prev & ~blocker[idx] & valid);
        if (g != e0) { ext[idx] = g; grew = true; }
        prev = g;
    }
    prev = c1 < n ? ext[first + uint(c1) * stride] : 0u;
    for (int c = c1 - 1; c >= c0; --c) {
        uint idx = first + uint(c) * stride;
        uint e0 = ext[idx];
        uint g = e0 | (prev & ~blocker[idx] & valid);
        if (g != e0) { ext[idx] = g; grew = true; }
        prev = g;
    }
    if (grew) changed = 1u;
}
#endif
