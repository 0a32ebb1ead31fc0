#version 450
// Voxelization into the octree (Schwarz & Seidel 2010, Sec. 5.3).
//   VOX_WORK 1: chunks of OCT_CHUNK tiles per triangle (pass 1);
//   VOX_WORK 0: one invocation per chunk (ss_octree/work_expand.glsl): the
//   triangle's tiles of 4 x 4 columns (the (y, z) extent of a level-0 node)
//   are tested with solid_may_cover, then their columns with solid_covers;
//   a covered column's crossing flips SG voxels (q_bar mod 4) .. 3 of its
//   column in the level-0 node holding voxel q_bar, with atomicXor.  The rest
//   of the column is flipped by the propagation pass.
// The crossing arithmetic is ss/solid.glsl's, shared with ss-solid, so the
// octree decodes to exactly ss-solid's grid.  q_bar < 0 (geometry left of
// the grid) flips the column from voxel 0; q_bar >= nx flips nothing.
// A node is found by descent from the top level, cached while the next
// crossing falls into the same one.  A crossing whose node is missing (the
// activation pass would have to have missed it) is counted in stats[0].
#include "common/voxel_space.glsl"
#include "ss/solid.glsl"
#define SOLID_UNIT 4
#include "ss/solid_input.glsl"
#include "ss_octree/common.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 4) buffer Stats { uint stats[]; };  // [0] lost crossings, [1] crossings
uniform uint u_triangles;
uniform uint u_top;
#if VOX_WORK
layout(std430, binding = 5) writeonly buffer Chunks { uint chunks[]; };
void main() {
    uint t = global_index_1d();
    if (t >= u_triangles) return;
    SolidTri T;
    uint units = load_solid_triangle(t, T) ? solid_units(T).w : 0u;
    chunks[t] = (units + uint(OCT_CHUNK) - 1u) / uint(OCT_CHUNK);
}
#else
#include "ss_octree/work_expand.glsl"
layout(std430, binding = 16) readonly buffer Child { uint child[]; };
layout(std430, binding = 18) buffer Data { uint data[]; };

// Index of the level-0 node at level-0 coordinates p, or OCT_NONE.
uint find_node(uvec3 p) {
    uint idx = oct_morton(p >> u_top);
    for (uint L = u_top; L >= 1u; --L) {
        uint ch = child[u_ubase[L] + idx];
        if (ch == OCT_NONE) return OCT_NONE;
        uvec3 b = (p >> (L - 1u)) & 1u;
        idx = ch + (b.x | (b.y << 1) | (b.z << 2));
    }
    return idx;
}

void main() {
    uint g = global_index_1d();
    if (g >= chunk_total[0]) return;
    uint t = chunk_item(g, u_triangles);
    uint chunk = g - chunk_offsets[t];
    SolidTri T;
    if (!load_solid_triangle(t, T)) return;
    ivec4 cols = solid_columns(T, u_dims);
    uvec4 units = solid_units(T);
    uint q0 = chunk * uint(OCT_CHUNK), q1 = min(units.w, q0 + uint(OCT_CHUNK));
    uint tj = units.x + q0 % units.z, tk = units.y + q0 / units.z;
    uint cached_key = OCT_NONE, cached_node = OCT_NONE;
    uint crossings = 0u, lost = 0u;
    for (uint q = q0; q < q1; ++q) {
        ivec2 c0 = max(ivec2(4u * uvec2(tj, tk)), cols.xy);
        ivec2 c1 = min(ivec2(4u * uvec2(tj, tk)) + 3, cols.zw);
        cached_key = OCT_NONE;  // a new tile: other nodes
        if (solid_may_cover(T, vec2(c0) + 0.5, vec2(c1) + 0.5)) {
            for (int k = c0.y; k <= c1.y; ++k) {
                for (int j = c0.x; j <= c1.x; ++j) {
                    dvec3 w;
                    if (!solid_covers(T, solid_center(ivec2(j, k)), w)) continue;
                    int first = solid_first_flip(T, w);
                    if (first >= u_dims.x) continue;
                    uint x = uint(max(first, 0));
                    uint key = x >> 2;  // the tile fixes the node's y and z
                    if (key != cached_key) {
                        cached_key = key;
                        cached_node = find_node(uvec3(key, tj, tk));
                    }
                    if (cached_node == OCT_NONE) { ++lost; continue; }
                    uint z = uint(k) & 3u, y = uint(j) & 3u;
                    uint mask = ((0xFu << (x & 3u)) & 0xFu) << (4u * y + 16u * (z & 1u));
                    atomicXor(data[2u * cached_node + (z >> 1)], mask);
                    ++crossings;
                }
            }
        }
        if (++tj >= units.x + units.z) { tj = units.x; ++tk; }
    }
    if (lost != 0u) atomicAdd(stats[0], lost);
    if (crossings != 0u) atomicAdd(stats[1], crossings);
}
#endif
