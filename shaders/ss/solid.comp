#version 450
// ss-solid (Schwarz & Seidel 2010, Sec. 4.1): one invocation per triangle
// and chunk of SOLID_CHUNK of its covered-center columns.  The paper flips
// voxels floor(q + 1/2) .. nx - 1 of every covered column with atomicXor;
// here each crossing flips the single bit floor(q + 1/2) of a crossing grid
// (one atomic instead of up to nx / 32), and ss/solid_fill.comp turns the
// rows into their prefix XOR afterwards, in place: the same voxels, since XOR
// commutes.
//
// VOX_SLAB (FLIP_AXIS 0 only): the crossing grid holds the z slices of u_slab,
// and only their rows are visited (ss/solid_input.glsl's pass_columns).
//
// FIRST 1: one invocation per triangle (glvox.methods._gpu.dispatch_1d) does
// the triangle's first chunk and lists the triangles with more (nearly none:
// a chunk is thousands of columns), so no separate pass sets triangles up
// only to count their chunks.  FIRST 0: invocation (i, chunk - 1) of an
// indirect dispatch (ss/solid_big_args.comp) does chunk `chunk` of the i-th
// listed triangle, chunk - 1 = y + z * groups y.
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
#include "ss/solid.glsl"
#define SOLID_UNIT 1
#include "ss/solid_input.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 3) buffer Crossings { uint crossings[]; };
layout(std430, binding = 4) buffer Big { uint big_count; uint big_max_chunks; uint big_list[]; };
uniform uint u_triangles;

#ifndef FLIP_AXIS
#define FLIP_AXIS 0
#endif

// Record a crossing that flips voxels first .. nx - 1 of row (j, k).
// FLIP_AXIS 1, 2 (vote-solid): the vertices were rotated so that the rows run
// along the grid's y (frame (x, y, z) = grid (y, z, x)) or z (= grid (z, x,
// y)); the crossing bit goes to the grid's own x-packed layout, and
// ss/solid_fill_axis.comp turns it into voxels along that axis.
void flip_from(int first, int j, int k) {
    uint f = uint(max(first, 0));
#if FLIP_AXIS == 1
    // grid voxel (k, f, j); the grid's dims are (u_dims.z, u_dims.x, u_dims.y)
    uint wpr = (uint(u_dims.z) + 31u) >> 5;
    atomicXor(crossings[(uint(j) * uint(u_dims.x) + f) * wpr + (uint(k) >> 5)], bit_of(uint(k)));
#elif FLIP_AXIS == 2
    // grid voxel (j, k, f); the grid's dims are (u_dims.y, u_dims.z, u_dims.x)
    uint wpr = (uint(u_dims.y) + 31u) >> 5;
    atomicXor(crossings[(f * uint(u_dims.z) + uint(k)) * wpr + (uint(j) >> 5)], bit_of(uint(j)));
#else
    atomicXor(crossings[word_index(ivec3(int(f), j, k))], bit_of(f));  // k from u_slab.x with VOX_SLAB
#endif
}

#if SOLID_TRACE
// SOLID_TRACE 1 (glvox.testing.tie_probe.trace): every crossing as (triangle,
// j, k, first voxel flipped), before the grid's bounds are applied.
layout(std430, binding = 6) buffer SolidTrace { uint trace_n; uint trace[]; };
uint g_triangle;

void trace_crossing(int j, int k, int first) {
    uint at = atomicAdd(trace_n, 1u);
    if (4u * at + 3u >= uint(trace.length())) return;
    trace[4u * at] = g_triangle;
    trace[4u * at + 1u] = uint(j);
    trace[4u * at + 2u] = uint(k);
    trace[4u * at + 3u] = uint(first);
}
#endif

// Columns chunk * SOLID_CHUNK .. of the covered-center range c (n columns).
void voxelize_chunk(SolidTri T, ivec4 c, uint n, uint chunk) {
    uint nj = uint(c.z - c.x + 1);
    uint q0 = chunk * uint(SOLID_CHUNK), q1 = min(n, q0 + uint(SOLID_CHUNK));
    int j = c.x + int(q0 % nj), k = c.y + int(q0 / nj);
    for (uint q = q0; q < q1; ++q) {
        dvec3 w;
        if (solid_covers(T, solid_center(ivec2(j, k)), w)) {
            int first = solid_first_flip(T, w);
#if SOLID_TRACE
            trace_crossing(j, k, first);
#endif
            if (first < u_dims.x) flip_from(first, j, k);
        }
        if (++j > c.z) { j = c.x; ++k; }
    }
}

void main() {
#if FIRST
    uint t = global_index_1d();
    uint chunk = 0u;
    if (t >= u_triangles) return;
#else
    uint i = gl_GlobalInvocationID.x;
    uint chunk = 1u + gl_WorkGroupID.y + gl_WorkGroupID.z * gl_NumWorkGroups.y;
    if (i >= big_count) return;
    uint t = big_list[i];
#endif
    SolidTri T;
#if SOLID_TRACE
    g_triangle = t;
#endif
    if (!load_solid_triangle(t, T)) return;
    uint n = solid_units(T).w;
    uint chunks = (n + uint(SOLID_CHUNK) - 1u) / uint(SOLID_CHUNK);
    if (chunk >= chunks) return;
#if FIRST
    if (chunks > 1u) {
        big_list[atomicAdd(big_count, 1u)] = t;
        atomicMax(big_max_chunks, chunks - 1u);
    }
#endif
    voxelize_chunk(T, pass_columns(T), n, chunk);
}
