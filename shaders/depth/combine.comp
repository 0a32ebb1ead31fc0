#version 450
// Combine one direction's verdict (the parity words of depth/scan.comp) with the others
// (Passalis et al. 2006, Sec. 2: a voxel is inside when every direction says so), and
// clear the parity buffer for the next direction.  u_last 1 (the last direction of
// modes 0 / 1, whose acc0 is the result): the set bits of acc0 are added to voxel_count,
// once per invocation (one word each).
//   u_mode 0 / 1: acc0 = P (first direction) / acc0 &= P.
//   u_mode 2 / 3 (Sec. 3.2, double-layer buffers): C = the voxels whose column along this
//   direction held at most CLASSIFIABLE_COUNT crossings, so its verdict is complete;
//   acc0 = AND over directions of (P or not C): every complete direction says inside;
//   acc1 = AND of P: every direction says inside (the verdict where none is complete);
//   acc2 = OR of C: some direction is complete.
layout(local_size_x = 256) in;
#include "common/bits.glsl"
#include "common/dispatch.glsl"
#include "common/voxel_space.glsl"
uniform int u_axis;
uniform int u_mode;
uniform int u_last;
layout(std430, binding = 0) buffer Flips { uint flips[]; };
layout(std430, binding = 1) buffer Acc0 { uint acc0[]; };
layout(std430, binding = 2) buffer Acc1 { uint acc1[]; };
layout(std430, binding = 3) buffer Acc2 { uint acc2[]; };
layout(std430, binding = 4) readonly buffer Crowded { uint crowded[]; };
layout(std430, binding = 5) buffer Count { uint voxel_count[]; };

void main() {
    uint w = global_index_1d();
    uint wpr = words_per_row();
    uint nx = uint(u_dims.x), ny = uint(u_dims.y), nz = uint(u_dims.z);
    if (w >= wpr * ny * nz) return;
    uint wi = w % wpr, row = w / wpr, j = row % ny, k = row / ny;
    uint valid = wi == wpr - 1u ? mask_upto((nx - 1u) & 31u) : 0xFFFFFFFFu;
    uint p = flips[w] & valid;
    flips[w] = 0u;
    if (u_mode < 2) {
        uint a = u_mode == 0 ? p : (acc0[w] & p);
        acc0[w] = a;
        uint n = uint(bitCount(a));
        if (u_last != 0 && n != 0u) atomicAdd(voxel_count[0], n);
        return;
    }
    uint c = 0u;
    if (u_axis == 0) {         // view (u, v) = (y, z): one column for the whole row
        c = crowded[k * ny + j] == 0u ? valid : 0u;
    } else {
        uint bits = min(32u, nx - wi * 32u);
        for (uint b = 0u; b < bits; ++b) {
            uint i = wi * 32u + b;
            // view (u, v) = (z, x) along y, (x, y) along z
            uint pixel = u_axis == 1 ? i * nz + k : j * nx + i;
            if (crowded[pixel] == 0u) c |= bit_of(b);
        }
    }
    uint verdict = p | (~c & valid);
    if (u_mode == 2) {
        acc0[w] = verdict;
        acc1[w] = p;
        acc2[w] = c;
    } else {
        acc0[w] &= verdict;
        acc1[w] &= p;
        acc2[w] |= c;
    }
}
