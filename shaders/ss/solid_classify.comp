#version 450
// ss-solid / ss-solid-tiled, pass 1: the work of each triangle in chunks of
// SOLID_CHUNK units (columns or tiles, see ss/solid_input.glsl) and the
// largest chunk count (stats[3]), which sizes the indirect dispatch of the
// next pass (ss/dispatch_args.comp).  Chunks bound the loop iterations of one
// invocation (LOOP_BUDGET in glvox/methods/_gpu.py).
#include "common/voxel_space.glsl"
#include "ss/solid.glsl"
#include "ss/solid_input.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 4) buffer Stats { uint stats[]; };
layout(std430, binding = 5) writeonly buffer TriChunks { uint tri_chunks[]; };
uniform uint u_triangles;
void main() {
    uint t = global_index_1d();
    if (t >= u_triangles) return;
    SolidTri T;
    uint chunks = 0u;
    if (load_solid_triangle(t, T)) {
        uint units = solid_units(T).w;
        chunks = (units + uint(SOLID_CHUNK) - 1u) / uint(SOLID_CHUNK);
        if (units > 0u) atomicAdd(stats[0], 1u);  // triangles that cover a column center's box
    }
    tri_chunks[t] = chunks;
    atomicMax(stats[3], chunks);
}
