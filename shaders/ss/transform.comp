#version 450
// Schwarz & Seidel Sec. 6: every method first transforms the vertices to voxel
// space (once per run; the later stages only read the result).
// The grid origin (relative to the mesh anchor) and 1/h, in double precision.
uniform dvec3 u_origin_d;
uniform double u_inv_h_d;
layout(local_size_x = 256) in;
#include "common/dispatch.glsl"
layout(std430, binding = 0) readonly buffer Verts { float verts[]; };  // world, relative to the anchor
layout(std430, binding = 1) writeonly buffer VoxVerts { float vox[]; };
uniform uint u_vertices;
void main() {
    uint i = global_index_1d();
    if (i >= u_vertices) return;
    // in double: float32 would add up to ~1e-4 voxel of rounding at 1024^3,
    // as much as the tie tolerance; one rounding to float32 at the end remains
    dvec3 p = (dvec3(verts[3u * i], verts[3u * i + 1u], verts[3u * i + 2u]) - dvec3(u_origin_d))
              * u_inv_h_d;
    vox[3u * i] = float(p.x);
    vox[3u * i + 1u] = float(p.y);
    vox[3u * i + 2u] = float(p.z);
}
