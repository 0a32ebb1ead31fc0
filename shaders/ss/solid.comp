#version 450
// ss-solid (Schwarz & Seidel 2010, Sec. 4.1): one invocation per triangle
// and chunk of SOLID_CHUNK of its bounding-box columns; every covered column
// flips voxels floor(q + 1/2) .. nx - 1 with atomicXor.
// Invocation (t, chunk): t from x (plus u_tri_offset), chunk = y + z * groups y.
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
#include "ss/solid.glsl"
#define SOLID_UNIT 1
#include "ss/solid_input.glsl"
layout(local_size_x = 64) in;
layout(std430, binding = 3) buffer Grid { uint grid[]; };
layout(std430, binding = 5) readonly buffer TriChunks { uint tri_chunks[]; };
uniform uint u_triangles;
uniform uint u_tri_offset;

// Flip voxels first .. nx - 1 of row (j, k); the bits past nx in the last
// word stay zero, so word counts equal voxel counts.
void flip_from(int first, int j, int k) {
    uint wpr = words_per_row();
    uint row = (uint(k) * uint(u_dims.y) + uint(j)) * wpr;
    uint f = uint(max(first, 0));
    uint last_bits = uint(u_dims.x) - 32u * (wpr - 1u);  // 1..32 valid bits in the last word
    for (uint w = f >> 5; w < wpr; ++w) {
        uint m = w == (f >> 5) ? mask_from(f & 31u) : 0xFFFFFFFFu;
        if (w == wpr - 1u) m &= mask_upto(last_bits - 1u);
        atomicXor(grid[row + w], m);
    }
}

void main() {
    uint t = gl_GlobalInvocationID.x + u_tri_offset;
    uint chunk = gl_WorkGroupID.y + gl_WorkGroupID.z * gl_NumWorkGroups.y;
    if (t >= u_triangles || chunk >= tri_chunks[t]) return;
    SolidTri T;
    if (!load_solid_triangle(t, T)) return;
    ivec4 c = solid_columns(T, u_dims);
    uint nj = uint(c.z - c.x + 1), n = nj * uint(c.w - c.y + 1);
    uint q0 = chunk * uint(SOLID_CHUNK), q1 = min(n, q0 + uint(SOLID_CHUNK));
    int j = c.x + int(q0 % nj), k = c.y + int(q0 / nj);
    for (uint q = q0; q < q1; ++q) {
        vec2 center = vec2(j, k) + 0.5;
        if (solid_covers(T, center)) {
            int first = solid_first_flip(T, center);
            if (first < u_dims.x) flip_from(first, j, k);
        }
        if (++j > c.z) { j = c.x; ++k; }
    }
}
