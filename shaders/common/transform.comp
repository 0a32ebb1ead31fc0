#version 450
// Schwarz & Seidel Sec. 6: every method first transforms the vertices to voxel
// space (once per run; the later stages only read the result):
// p = (v - origin) * scale - shift, in double.  scale is 1/h on every axis for
// the voxel grid; the LDI (Leung & Wang Sec. III-A) counts LOD-C cells along
// its rays and shifts them by half a cell (ldi/cells.glsl has why).
//
// VOX_DOUBLE 0: float32 out, one rounding at the end (ss-*, scanline):
// float32 arithmetic would add up to ~1e-4 voxel of rounding at 1024^3, as
// much as the tie tolerance.  VOX_DOUBLE 1: double out (eisemann-*, ldi), so
// the only rounding of the mesh left is its float32 upload relative to the
// anchor (eisemann/column.glsl has the precision argument).
uniform dvec3 u_origin_d;  // grid origin relative to the mesh anchor, world units
uniform dvec3 u_scale_d;
uniform dvec3 u_shift_d;
// output coordinate c is coordinate u_axes[c] of p: (0, 1, 2) for the grid's own
// frame; a rotation of the axes lets x-column passes run along y or z (vote-solid)
uniform ivec3 u_axes;
// u_snap > 0 (carve-solid): a coordinate within u_snap voxels outside [0, u_snap_dims]
// moves onto that face of the grid, so that float32 rounding cannot push a face lying
// on the grid's boundary out of it (glvox.tolerances.GRID_FACE_SNAP)
uniform double u_snap;
uniform dvec3 u_snap_dims;
layout(local_size_x = 256) in;
#include "common/dispatch.glsl"
#if VOX_DOUBLE
#define VOX_T double
#else
#define VOX_T float
#endif
layout(std430, binding = 0) readonly buffer Verts { float verts[]; };  // world, relative to the anchor
layout(std430, binding = 1) writeonly buffer VoxVerts { VOX_T vox[]; };
uniform uint u_vertices;
void main() {
    uint i = global_index_1d();
    if (i >= u_vertices) return;
    dvec3 p = (dvec3(verts[3u * i], verts[3u * i + 1u], verts[3u * i + 2u]) - u_origin_d) * u_scale_d
              - u_shift_d;
    if (u_snap > 0.0) {
        for (int c = 0; c < 3; ++c) {
            if (p[c] < 0.0 && p[c] >= -u_snap) p[c] = 0.0;
            if (p[c] > u_snap_dims[c] && p[c] <= u_snap_dims[c] + u_snap) p[c] = u_snap_dims[c];
        }
    }
    vox[3u * i] = VOX_T(p[u_axes.x]);
    vox[3u * i + 1u] = VOX_T(p[u_axes.y]);
    vox[3u * i + 2u] = VOX_T(p[u_axes.z]);
}
