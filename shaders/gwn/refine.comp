#version 450
// gwn-solid, pass 4: the blocks gwn/field.comp could not decide, exactly.
// One invocation per listed segment (its id and its mask of undecided
// blocks of 4 voxels) sums, over those blocks, the exact strips of the boundary
// edges u_edges.x .. u_edges.y - 1 (one chunk of the edge list, within the
// loop budget); with several chunks the sums so far live in Sums; the last
// chunk writes w = C + F, the bits and the count (gwn/segment.glsl).
#include "common/voxel_space.glsl"
#include "gwn/layout.glsl"
#include "gwn/strip.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 1) readonly buffer VoxVerts { float vox[]; };
layout(std430, binding = 3) buffer Cells { ivec4 cells[]; };
layout(std430, binding = 4) buffer Sums { vec4 sums[]; };  // GWN_SEGV per listed segment
layout(std430, binding = 5) readonly buffer Edges { uvec2 edges[]; };
layout(std430, binding = 7) buffer Bits { uint bits[]; };
layout(std430, binding = 8) buffer Count { uint voxel_count; uint refine_count; };
layout(std430, binding = 11) readonly buffer Refine { uint refine_list[]; };
uniform float u_threshold;
uniform uint u_items;   // listed segments
uniform ivec2 u_edges;
uniform bool u_first, u_last;
uniform ivec4 u_rows;
uniform ivec2 u_segs;
#include "gwn/segment.glsl"

void main() {
    uint item = global_index_1d();
    if (item >= u_items) return;
    Segment S;
    segment_of(refine_list[2u * item], S);
    uint blocks = refine_list[2u * item + 1u];
    for (int i = 0; i < GWN_SEGV; ++i) seg_f[i] = u_first ? vec4(0.0) : sums[item * uint(GWN_SEGV) + uint(i)];
    for (int e = u_edges.x; e < u_edges.y; ++e) {
        uvec2 ed = edges[e];
        add_strip(vertex(ed.x), vertex(ed.y), S.c, S.x0, 1.0, blocks);
    }
    if (!u_last) {
        for (int i = 0; i < GWN_SEGV; ++i) sums[item * uint(GWN_SEGV) + uint(i)] = seg_f[i];
        return;
    }
    vec4 w[GWN_SEGV];
    for (int i = 0; i < GWN_SEGV; ++i) w[i] = vec4(cells[S.cell / 4u + uint(i)]) + seg_f[i] * (0.5 / GWN_PI);
    finish_segment(S, w, blocks);
}
