#version 450
// Vertices to voxel space, kept in double (Schwarz & Seidel Sec. 6: transform
// first, once per run).  The raster stages test pixel centers against the
// triangles and intersect the columns with their planes in double, so the only
// rounding of the mesh left is the float32 upload relative to the anchor
// (see column.glsl for the precision argument).
uniform dvec3 u_origin_d;  // grid origin relative to the mesh anchor
uniform double u_inv_h_d;
layout(local_size_x = 256) in;
#include "common/dispatch.glsl"
layout(std430, binding = 0) readonly buffer Verts { float verts[]; };  // world, relative to the anchor
layout(std430, binding = 1) writeonly buffer VoxVerts { double vox[]; };
uniform uint u_vertices;
void main() {
    uint i = global_index_1d();
    if (i >= u_vertices) return;
    dvec3 p = (dvec3(verts[3u * i], verts[3u * i + 1u], verts[3u * i + 2u]) - u_origin_d) * u_inv_h_d;
    vox[3u * i] = p.x;
    vox[3u * i + 1u] = p.y;
    vox[3u * i + 2u] = p.z;
}
