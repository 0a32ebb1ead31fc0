#version 450
// Pass 1 of every ss-conservative / ss-6sep variant: the case of each
// triangle (Sec. 3.2 "Implementation") and its work in chunks.
//   variants 0, 1 and 6-sep: chunks per triangle, and their maximum;
//   variant 2 (sorted): a sort key type (2 bits) | axis (2 bits) | work
//   (SS_WORK_BITS bits, clamped) with the triangle id as value, and the
//   maximum chunks per type.
// Type 3 marks triangles outside the grid: no work; they sort last.
#include "common/voxel_space.glsl"
#include "common/edge.glsl"
#include "ss/setup.glsl"
#include "ss/work.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 4) buffer Stats { uint stats[]; };  // [0..2] cases, [3] max chunks, [4..6] per type
layout(std430, binding = 5) writeonly buffer TriChunks { uint tri_chunks[]; };  // or sorted values
layout(std430, binding = 7) writeonly buffer Keys { uint keys[]; };
uniform uint u_triangles;

#if SS_VARIANT == 2
// The work's part of the sort key: the work clamped to SS_WORK_BITS bits
// (triangles of similar work side by side, so that the lanes of a SIMD batch
// loop about as long; fewer key bits, fewer sort passes).
uint work_key(uint work) { return min(work, (1u << SS_WORK_BITS) - 1u); }
#endif

void main() {
    uint t = global_index_1d();
    if (t >= u_triangles) return;
    Tri T = setup_triangle(t);
    if (outside_grid(T)) {
#if SS_VARIANT == 2
        keys[t] = 3u << (SS_WORK_BITS + 2);
        tri_chunks[t] = t;
#else
        tri_chunks[t] = 0u;
#endif
        return;
    }
    int type = bbox_type(T);
    uint work = work_units(T, type);
    uint chunks = chunks_of(work);
#if SS_CRITERION == 0
    atomicAdd(stats[type], 1u);
#endif
#if SS_VARIANT == 2
    keys[t] = (uint(type) << (SS_WORK_BITS + 2)) | (uint(case_axis(T, type)) << SS_WORK_BITS) | work_key(work);
    tri_chunks[t] = t;
    atomicMax(stats[4 + type], chunks);
#else
    tri_chunks[t] = chunks;
    atomicMax(stats[3], chunks);
#endif
}
