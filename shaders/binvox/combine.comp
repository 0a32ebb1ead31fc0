#version 450
// binvox-solid: one axis's verdict (the parity words of depth/scan.comp) into the result.
//   u_mode 0 / 1 (carving): carve = P (first axis) / carve &= P: a voxel survives when it
//     lies between the nearest crossings seen from both faces along every axis.
//   u_mode 2 (voting): the parity before the center, P, and the parity beyond it,
//     P ^ (the column's total parity), are two votes; they are added into the 3-bit
//     counters (v0, v1, v2), bit-sliced (at most 6 votes).
// The parity buffer is cleared for the next axis.
layout(local_size_x = 256) in;
#include "common/bits.glsl"
#include "common/dispatch.glsl"
#include "common/voxel_space.glsl"
uniform int u_axis;
uniform int u_mode;
layout(std430, binding = 0) buffer Flips { uint flips[]; };
layout(std430, binding = 1) buffer Carve { uint carve[]; };
layout(std430, binding = 2) buffer V0 { uint v0[]; };
layout(std430, binding = 3) buffer V1 { uint v1[]; };
layout(std430, binding = 4) buffer V2 { uint v2[]; };
layout(std430, binding = 5) readonly buffer Total { uint total[]; };

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
        carve[w] = u_mode == 0 ? p : (carve[w] & p);
        return;
    }
    uint t = 0u;
    if (u_axis == 0) {         // view (u, v) = (y, z): one column for the whole row
        t = total[k * ny + j] != 0u ? valid : 0u;
    } else {
        uint bits = min(32u, nx - wi * 32u);
        for (uint b = 0u; b < bits; ++b) {
            uint i = wi * 32u + b;
            // view (u, v) = (z, x) along y, (x, y) along z
            uint pixel = u_axis == 1 ? i * nz + k : j * nx + i;
            if (total[pixel] != 0u) t |= bit_of(b);
        }
    }
    uint c0 = v0[w], c1 = v1[w], c2 = v2[w];
    uint votes[2] = uint[2](p, (p ^ t) & valid);
    for (int n = 0; n < 2; ++n) {
        uint carry0 = c0 & votes[n];
        c0 ^= votes[n];
        uint carry1 = c1 & carry0;
        c1 ^= carry0;
        c2 |= carry1;
    }
    v0[w] = c0;
    v1[w] = c1;
    v2[w] = c2;
}
