#version 450
// Schwarz & Seidel Sec. 6: every method first transforms the vertices to voxel
// space (once per run; the later stages only read the result).
#include "common/voxel_space.glsl"
layout(local_size_x = 256) in;
#include "common/dispatch.glsl"
layout(std430, binding = 0) readonly buffer Verts { float verts[]; };  // world, relative to the anchor
layout(std430, binding = 1) writeonly buffer VoxVerts { float vox[]; };
uniform uint u_vertices;
void main() {
    uint i = global_index_1d();
    if (i >= u_vertices) return;
    vec3 p = world_to_voxel(vec3(verts[3u * i], verts[3u * i + 1u], verts[3u * i + 2u]));
    vox[3u * i] = p.x;
    vox[3u * i + 1u] = p.y;
    vox[3u * i + 2u] = p.z;
}
