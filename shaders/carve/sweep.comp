#version 450
// carve-solid: one sweep of the exterior flood fill along AXIS.
//
// ext holds the exterior found so far (packed, a subset of the free voxels,
// those not in the blocker); a sweep spreads it along one axis through the
// free voxels, forward then backward, so after it every free run along that
// axis that held an exterior voxel is exterior.  Sweeps along x, y and z
// repeat until a round of them adds nothing (glvox.methods.carve.sweep): each
// round lets a path turn a corner more.
//
// AXIS 0: one invocation per row; within a word the run is filled by a
// 5-step occluded fill (Kogge-Stone, shifts 1, 2, 4, 8, 16), across words by
// a carry that fills the next word's run from its end bit.  u_seed: the
// first sweep also makes exterior every free voxel on the grid's boundary.
// AXIS 1, 2: one invocation per column of VEC words and segment of at most
// SEGMENT cells (bounding the loop: llvmpipe ends an invocation's loops
// after 65535 iterations), the voxels of the words moving together; a segment starts from its neighbours' boundary cells as
// they are (they only grow, so a stale value is just less progress, and the
// next round sees the rest).  An invocation that adds a voxel sets `changed`.
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
#include "carve/grid_words.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 2) buffer Flags { uint changed; };
// Lines that need no sweep: 1 once a sweep has filled the line, 0 (dirty) again
// when a sweep along another axis adds a voxel to it.  x: a row (j, k) at
// k * ny + j; y: a column of VEC words (v, k) at k * nv + v; z: (v, j) at j * nv + v.
// A sweep skips its clean lines (only sweeps along another axis can have
// grown them), so later rounds only walk where the exterior still moves.
layout(std430, binding = 3) buffer CleanX { uint clean_x[]; };
layout(std430, binding = 4) buffer CleanY { uint clean_y[]; };
layout(std430, binding = 5) buffer CleanZ { uint clean_z[]; };
uniform bool u_seed;

// A voxel was added to the VEC words v of row (j, k): the lines along the other
// axes through them are dirty.
void touched(uint v, uint j, uint k, uint nv) {
#if AXIS != 0
    clean_x[k * uint(u_dims.y) + j] = 0u;
#endif
#if AXIS != 1
    clean_y[k * nv + v] = 0u;
#endif
#if AXIS != 2
    clean_z[j * nv + v] = 0u;
#endif
}

// VEC consecutive words (1, 2 or 4, dividing words_per_row) move together:
// llvmpipe accesses a buffer lane by lane, so wider accesses mean fewer of them
#if VEC == 4
#define WORDS uvec4
#elif VEC == 2
#define WORDS uvec2
#else
#define WORDS uint
#endif
layout(std430, binding = 0) readonly buffer BlockerV { WORDS blocker_v[]; };
layout(std430, binding = 1) coherent buffer ExteriorV { WORDS ext_v[]; };

// The in-grid bits of the VEC words from word v * VEC on.
WORDS valid_words(uint v) {
    WORDS m;
#if VEC == 1
    m = valid_bits(v);
#else
    for (int c = 0; c < VEC; ++c) m[c] = valid_bits(v * uint(VEC) + uint(c));
#endif
    return m;
}

#if AXIS == 0
// Component c of a WORDS value (VEC 1: the value).
#if VEC == 1
#define AT(x, c) (x)
#else
#define AT(x, c) (x)[c]
#endif

void main() {
    uint nv = words_per_row() / uint(VEC);
    uint rows = uint(u_dims.y) * uint(u_dims.z);
    uint row = global_index_1d();
    if (row >= rows) return;
    if (clean_x[row] != 0u) return;
    clean_x[row] = 1u;
    uint j = row % uint(u_dims.y), k = row / uint(u_dims.y);
    bool face = j == 0u || k == 0u || j + 1u == uint(u_dims.y) || k + 1u == uint(u_dims.z);
    uint last = words_per_row() - 1u;
    uint base = row * nv;
    bool grew = false;
    // forward: each word filled upwards from its seeds (occluded fill, shifts 1 .. 16),
    // then the runs from bit 0 of the words the run before reached, word by word
    uint carry = 0u;
    for (uint v = 0u; v < nv; ++v) {
        WORDS f = ~blocker_v[base + v] & valid_words(v);
        WORDS e0 = ext_v[base + v];
        WORDS g = e0;
        if (u_seed) {
            if (face) g |= f;
            else {
                if (v == 0u) AT(g, 0) |= AT(f, 0) & 1u;
                if (v + 1u == nv) AT(g, VEC - 1) |= AT(f, VEC - 1) & bit_of(uint(u_dims.x - 1));
            }
        }
        WORDS p = f;
        g |= p & (g << 1u); p &= p << 1u;
        g |= p & (g << 2u); p &= p << 2u;
        g |= p & (g << 4u); p &= p << 4u;
        g |= p & (g << 8u); p &= p << 8u;
        g |= p & (g << 16u);
        for (int c = 0; c < VEC; ++c) {
            uint fc = AT(f, c);
            // the free run from bit 0: (lowest blocked bit) - 1, all ones when none is
            if (carry != 0u) AT(g, c) |= (~fc & (fc + 1u)) - 1u;
            carry = AT(g, c) >> 31u;
        }
        if (g != e0) { ext_v[base + v] = g; grew = true; touched(v, j, k, nv); }
    }
    // backward: the same downwards, the runs from bit 31 joined word by word
    carry = 0u;
    for (uint v = nv; v-- > 0u;) {
        WORDS f = ~blocker_v[base + v] & valid_words(v);
        WORDS e0 = ext_v[base + v];
        WORDS g = e0;
        WORDS p = f;
        g |= p & (g >> 1u); p &= p >> 1u;
        g |= p & (g >> 2u); p &= p >> 2u;
        g |= p & (g >> 4u); p &= p >> 4u;
        g |= p & (g >> 8u); p &= p >> 8u;
        g |= p & (g >> 16u);
        for (int c = VEC - 1; c >= 0; --c) {
            uint fc = AT(f, c);
            // the free run down from bit 31: above the highest blocked bit
            if (carry != 0u) AT(g, c) |= ~fc == 0u ? 0xFFFFFFFFu : mask_from(uint(findMSB(~fc)) + 1u);
            carry = AT(g, c) & 1u;
        }
        if (g != e0) { ext_v[base + v] = g; grew = true; touched(v, j, k, nv); }
    }
    if (grew) changed = 1u;
}
#else
void main() {
    uint wpr = words_per_row();
    uint nv = wpr / uint(VEC);
    int n = u_dims[AXIS];
    uint segs = (uint(n) + uint(SEGMENT) - 1u) / uint(SEGMENT);
    // columns of VEC words: (v, k) along y, (v, j) along z
    uint lines = nv * uint(AXIS == 1 ? u_dims.z : u_dims.y);
    uint id = global_index_1d();
    if (id >= lines * segs) return;
    uint line = id % lines, seg = id / lines;
    uint v = line % nv, other = line / nv;
    uint stride = axis_stride(AXIS) / uint(VEC);
    uint first = AXIS == 1 ? (other * uint(u_dims.y)) * nv + v : other * nv + v;
    int c0 = int(seg) * SEGMENT, c1 = min(n, c0 + SEGMENT);
    // columns of one segment keep their flag; longer ones are always swept (their
    // segments meet in later rounds)
#if AXIS == 1
    if (segs == 1u) { if (clean_y[line] != 0u) return; clean_y[line] = 1u; }
#else
    if (segs == 1u) { if (clean_z[line] != 0u) return; clean_z[line] = 1u; }
#endif
    WORDS valid = valid_words(v);
    bool grew = false;
    WORDS prev = c0 > 0 ? ext_v[first + uint(c0 - 1) * stride] : WORDS(0u);
    for (int c = c0; c < c1; ++c) {
        uint idx = first + uint(c) * stride;
        WORDS e0 = ext_v[idx];
        WORDS g = e0 | (prev & ~blocker_v[idx] & valid);
        if (g != e0) {
            ext_v[idx] = g;
            grew = true;
            touched(v, AXIS == 1 ? uint(c) : other, AXIS == 1 ? other : uint(c), nv);
        }
        prev = g;
    }
    prev = c1 < n ? ext_v[first + uint(c1) * stride] : WORDS(0u);
    for (int c = c1 - 1; c >= c0; --c) {
        uint idx = first + uint(c) * stride;
        WORDS e0 = ext_v[idx];
        WORDS g = e0 | (prev & ~blocker_v[idx] & valid);
        if (g != e0) {
            ext_v[idx] = g;
            grew = true;
            touched(v, AXIS == 1 ? uint(c) : other, AXIS == 1 ? other : uint(c), nv);
        }
        prev = g;
    }
    if (grew) changed = 1u;
}
#endif
