#version 450
// ss-solid-tiled (Schwarz & Seidel 2010, Sec. 4.2), tile assignment: the
// tiles of TILE x TILE columns a triangle may cover, found by testing each
// tile of its covered-center range at the critical column center of every
// edge (ss/solid.glsl, solid_may_cover).
//   EMIT 0: count them per triangle (counts[t], one atomicAdd per invocation);
//   EMIT 1: write the (tile, triangle) pairs, taking slots from cursor[t],
//           which starts as the exclusive scan of the counts.
// Invocation (t, chunk): t from x, chunk = y + z * groups y; SOLID_CHUNK tiles each.
#include "common/voxel_space.glsl"
#include "ss/solid.glsl"
#define SOLID_UNIT TILE
#include "ss/solid_input.glsl"
layout(local_size_x = 64) in;
layout(std430, binding = 5) readonly buffer TriChunks { uint tri_chunks[]; };
layout(std430, binding = 6) buffer Counts { uint counts[]; };  // EMIT 0: counts; 1: cursors
layout(std430, binding = 7) writeonly buffer Keys { uint keys[]; };
layout(std430, binding = 8) writeonly buffer Values { uint values[]; };
uniform uint u_triangles;

void main() {
    uint t = gl_GlobalInvocationID.x;
    uint chunk = gl_WorkGroupID.y + gl_WorkGroupID.z * gl_NumWorkGroups.y;
    if (t >= u_triangles || chunk >= tri_chunks[t]) return;
    SolidTri T;
    if (!load_solid_triangle(t, T)) return;
    ivec4 c = solid_columns(T, u_dims);
    uvec4 units = solid_units(T);
    uint tiles_y = (uint(u_dims.y) + uint(TILE) - 1u) / uint(TILE);
    uint q0 = chunk * uint(SOLID_CHUNK), q1 = min(units.w, q0 + uint(SOLID_CHUNK));
    uint found = 0u;
    for (uint q = q0; q < q1; ++q) {
        ivec2 tile = ivec2(units.x + q % units.z, units.y + q / units.z);
        // the covered-center columns of this tile
        ivec2 lo = max(c.xy, tile * TILE), hi = min(c.zw, tile * TILE + (TILE - 1));
        if (!solid_may_cover(T, vec2(lo) + 0.5, vec2(hi) + 0.5)) continue;
#if EMIT
        uint slot = atomicAdd(counts[t], 1u);
        keys[slot] = uint(tile.y) * tiles_y + uint(tile.x);
        values[slot] = t;
#else
        ++found;
#endif
    }
#if !EMIT
    if (found > 0u) atomicAdd(counts[t], found);
#endif
}
