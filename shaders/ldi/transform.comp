#version 450
// Vertices to the LDI's voxel space, in double (Leung & Wang 2013 Sec. III-A, Phase 1 setup).
// Across the rays (u, v) the unit is the grid's voxel: pixel (i, j) is the ray through
// (i + 1/2, j + 1/2).  Along the rays the unit is the LOD-C cell (r_z = LOD-C cells over the
// grid's n_axis voxels), shifted by half a cell: the Eisemann & Decoret XOR pass
// (eisemann/slices.frag, eisemann/setup.comp) flips slice k iff k + 1/2 lies beyond the
// crossing q', so with q' = q_cell - 1/2 bit k of T1 is the parity of the crossings
// below k + 1 cells: the inside state at the top of cell k, the paper's T1(x, y, k).
// The raster stages work on these doubles; the only rounding of the mesh left is its
// float32 upload relative to the anchor (eisemann/column.glsl has the argument).
uniform dvec3 u_origin_d;  // grid origin relative to the mesh anchor, world units
uniform dvec3 u_scale_d;   // per axis: 1 / h, and LOD-C / (n_axis h) along the rays
uniform dvec3 u_shift_d;   // subtracted after scaling: 1/2 along the rays
layout(local_size_x = 256) in;
#include "common/dispatch.glsl"
layout(std430, binding = 0) readonly buffer Verts { float verts[]; };  // world, relative to the anchor
layout(std430, binding = 1) writeonly buffer VoxVerts { double vox[]; };
uniform uint u_vertices;
void main() {
    uint i = global_index_1d();
    if (i >= u_vertices) return;
    dvec3 p = (dvec3(verts[3u * i], verts[3u * i + 1u], verts[3u * i + 2u]) - u_origin_d) * u_scale_d
              - u_shift_d;
    vox[3u * i] = p.x;
    vox[3u * i + 1u] = p.y;
    vox[3u * i + 2u] = p.z;
}
