#version 450
// vote-solid: the majority of the parities along x, y and z, in glvox's
// packed layout (x words).  maj(X, Y, Z) = (X & Y) | (Z & (X | Y)).
//
// The y and z parities come from ss/solid passes run in rotated frames
// (glvox.methods.ss_solid.rotation): Y is packed along y, rows (k, i), so
// voxel (i, j, k) is bit j % 32 of word (i * nz + k) * wpr_y + j / 32; Z is
// packed along z, rows (i, j): bit k % 32 of word (j * nx + i) * wpr_z + k / 32.
// One invocation takes 32 such words of 32 consecutive i, a 32 x 32 bit
// matrix, and transposes it into 32 x words (common/transpose.glsl).
//
// PASS 1, one invocation per (x word a, y word b, k): the 32 rows j of Y's
// block; X := X & Y in place, OR := X | Y.  PASS 2, one invocation per
// (x word a, z word c, j): X := X & Y | Z & (X | Y), counted.  Every x word
// belongs to one invocation of each pass, so plain stores suffice.
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
#include "common/transpose.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 0) buffer X { uint grid_x[]; };  // X, then X & Y, then the vote
layout(std430, binding = 1) buffer Or { uint grid_or[]; };  // X | Y
layout(std430, binding = 2) readonly buffer Other { uint other[]; };  // Y (pass 1) or Z (pass 2)
layout(std430, binding = 3) buffer Count { uint voxel_count; };

void main() {
    uint nx = uint(u_dims.x), ny = uint(u_dims.y), nz = uint(u_dims.z);
    uint wpr = words_per_row();
#if PASS == 1
    uint n_other = (ny + 31u) >> 5;  // words per row of Y
    uint lines = nz;
#else
    uint n_other = (nz + 31u) >> 5;  // words per row of Z
    uint lines = ny;
#endif
    uint id = global_index_1d();
    if (id >= wpr * n_other * lines) return;
    uint a = id % wpr;
    uint b = (id / wpr) % n_other;
    uint line = id / (wpr * n_other);  // k in pass 1, j in pass 2
    uint m[32];
    for (uint t = 0u; t < 32u; ++t) {
        uint i = 32u * a + t;
#if PASS == 1
        m[t] = i < nx ? other[(i * nz + line) * n_other + b] : 0u;
#else
        m[t] = i < nx ? other[(line * nx + i) * n_other + b] : 0u;
#endif
    }
    transpose32(m);  // m[s]: the x word of j = 32 b + s (pass 1) or k = 32 b + s (pass 2)
    uint count = 0u;
    for (uint s = 0u; s < 32u; ++s) {
        uint c = 32u * b + s;
#if PASS == 1
        if (c >= ny) break;
        uint idx = (line * ny + c) * wpr + a;
        uint x = grid_x[idx];
        grid_x[idx] = x & m[s];
        grid_or[idx] = x | m[s];
#else
        if (c >= nz) break;
        uint idx = (c * ny + line) * wpr + a;
        uint v = grid_x[idx] | (m[s] & grid_or[idx]);
        grid_x[idx] = v;
        count += uint(bitCount(v));
#endif
    }
#if PASS == 2
    if (count != 0u) atomicAdd(voxel_count, count);
#endif
}
