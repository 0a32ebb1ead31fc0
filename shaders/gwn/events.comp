#version 450
// gwn-solid, pass 1: C, the signed crossings (glvox/reference/winding.py).
// The crossings are ss-solid's (ss/solid.glsl: the same arithmetic and fill
// rule, so a closed mesh gives ss-solid's grid), but counted rather than
// XORed: a crossing of triangle t at the covered column (j, k) adds
// -sign(n_x) to voxel floor(q + 1/2) of the slab's int grid, and
// gwn/rows.comp turns each row into its prefix sums, C at every voxel (the
// count along the ray from the center towards -x).
//
// Rows (j, k) of the slab u_slab = (k0, k1) only: columns outside are
// clipped before they are counted, so each slab's chunks cover its own rows.
// One invocation per triangle and chunk of GWN_CHUNK columns, as ss/solid.comp
// (FIRST 1: the first chunk of every triangle, listing those with more;
// FIRST 0: the listed triangles' other chunks, by an indirect dispatch).
//
// gwn-solid's caps (gwn/caps.glsl) are counted by a second run over the fan
// triangles alone (u_triangle0 on), into planes of their own.
//
// PLANES 1: the counts go into bit planes instead of an int per voxel, eight
// times less memory to clear and for gwn/rows.comp to read.  Two planes count
// the +1 crossings of each voxel (0 to 3), two more the -1 ones, each plane a
// bit grid of the slab (gwn/layout.glsl has their order, and the Carried
// flags that say where plane 1 holds a bit, with CARRY_FLAGS 1).
// A crossing increments its voxel's counter bit-serially with atomicXor: it
// toggles the bit of plane 0 and, where the bit was set (1 -> 0), carries
// into plane 1.  Every plane's toggles are atomic, so plane p ends up toggled
// floor(n / 2^p) times for n crossings in any order: the planes hold n mod 4
// exactly.  A carry out of plane 1 (4 or more crossings of one sign in one
// voxel: nearly coincident sheets) sets `overflow`, and the caller runs the
// slabs again with PLANES 0.
#include "common/voxel_space.glsl"
#include "ss/solid.glsl"
#define SOLID_UNIT 1
#include "ss/solid_input.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
#include "gwn/layout.glsl"
#if PLANES
layout(std430, binding = 0) buffer Events { uint events[]; };
layout(std430, binding = 8) buffer Count { uint count_words[5]; uint overflow; };
layout(std430, binding = 12) writeonly buffer Carried { uint carried[]; };  // gwn/layout.glsl
uniform uint u_carried0;  // this pass's first flag: 0 (the mesh) or slab_rows() (the caps)

// One crossing of sign `step` at voxel i of row (j, k) of the slab.
void add_event(int i, int j, int k, int step) {
    uint at = 2u * (row_base(j, k) / 32u + uint(i) / 32u) + (step > 0 ? 0u : 1u);
    uint b = 1u << (uint(i) & 31u);
    if ((atomicXor(events[at], b) & b) == 0u) return;
#if CARRY_FLAGS
    // a carry into plane 1: flag the row (every writer writes 1: no atomic needed)
    carried[u_carried0 + slab_row(j, k)] = 1u;
#endif
    if ((atomicXor(events[2u * plane_words() + at], b) & b) == 0u) return;
    atomicOr(overflow, 1u);
}
#else
layout(std430, binding = 3) buffer Counts { int counts[]; };
#endif
layout(std430, binding = 4) buffer Big { uint big_count; uint big_max_chunks; uint big_list[]; };
uniform uint u_triangles;
uniform uint u_triangle0;  // the first triangle (the caps' crossings are counted apart)

// The covered-center columns of T inside the grid and the slab, inclusive.
ivec4 slab_columns(SolidTri T) {
    ivec4 c = solid_columns(T, u_dims);
    c.y = max(c.y, u_slab.x);
    c.w = min(c.w, u_slab.y - 1);
    return c;
}

void main() {
#if FIRST
    uint t = global_index_1d();
    uint chunk = 0u;
    if (t >= u_triangles) return;
    t += u_triangle0;
#else
    uint i = gl_GlobalInvocationID.x;
    uint chunk = 1u + gl_WorkGroupID.y + gl_WorkGroupID.z * gl_NumWorkGroups.y;
    if (i >= big_count) return;
    uint t = big_list[i];
#endif
    SolidTri T;
    if (!load_solid_triangle(t, T)) return;
    ivec4 c = slab_columns(T);
    if (c.x > c.z || c.y > c.w) return;
    uint nj = uint(c.z - c.x + 1);
    uint n = nj * uint(c.w - c.y + 1);
    uint chunks = (n + uint(GWN_CHUNK) - 1u) / uint(GWN_CHUNK);
    if (chunk >= chunks) return;
#if FIRST
    if (chunks > 1u) {
        big_list[atomicAdd(big_count, 1u)] = t;
        atomicMax(big_max_chunks, chunks - 1u);
    }
#endif
    // a crossing counts -1 through a face facing +x (n_x > 0: orientation +1), +1 otherwise
    int step = T.sgn > 0 ? -1 : 1;
    uint q0 = chunk * uint(GWN_CHUNK), q1 = min(n, q0 + uint(GWN_CHUNK));
    int j = c.x + int(q0 % nj), k = c.y + int(q0 / nj);
    for (uint q = q0; q < q1; ++q) {
        dvec3 w;
        if (solid_covers(T, solid_center(ivec2(j, k)), w)) {
            int first = solid_first_flip(T, w);
#if PLANES
            if (first < u_dims.x) add_event(max(first, 0), j, k, step);
#else
            if (first < u_dims.x) atomicAdd(counts[cell_index(max(first, 0), j, k)], step);
#endif
        }
        if (++j > c.z) { j = c.x; ++k; }
    }
}
