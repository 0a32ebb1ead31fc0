#version 450
// Schwarz & Seidel Sec. 6: every method first transforms the vertices to voxel
// space (once per run; the later stages only read the result):
// p = vertex_to_voxel(v) * stretch - shift, in double.  vertex_to_voxel is the
// one world -> voxel transform with the plane snap (common/snap.glsl); the LDI
// (Leung & Wang Sec. III-A) stretches its ray axis into LOD-C cells and shifts
// them by half a cell (ldi/cells.glsl has why), after the snap, so it snaps in
// voxel space like everyone else.
//
// VOX_DOUBLE 0: float32 out, one rounding at the end (ss-*): float32
// arithmetic would add up to ~1e-4 voxel of rounding at 1024^3, as much as the
// tie tolerance.  VOX_DOUBLE 1: double out (eisemann-*, ldi), so the only
// rounding of the mesh left is its float32 upload relative to the anchor
// (eisemann/column.glsl has the precision argument).
uniform dvec3 u_origin_d;  // grid origin relative to the mesh anchor, world units
uniform double u_inv_h_d;
uniform dvec3 u_stretch_d;
uniform dvec3 u_shift_d;
// output coordinate c is coordinate u_axes[c] of p: (0, 1, 2) for the grid's own
// frame; a rotation of the axes lets x-column passes run along y or z (vote-solid)
uniform ivec3 u_axes;
layout(local_size_x = 256) in;
#include "common/dispatch.glsl"
#include "common/snap.glsl"
#if VOX_DOUBLE
#define VOX_T double
#else
#define VOX_T float
#endif
layout(std430, binding = 0) readonly buffer Verts { float verts[]; };  // world, relative to the anchor
layout(std430, binding = 1) writeonly buffer VoxVerts { VOX_T vox[]; };
#ifndef VOX_MOTION
#define VOX_MOTION 0
#endif
#if VOX_MOTION
// VOX_MOTION 1: how far the snap moved the vertex (largest coordinate, voxels, rounded
// up to float32): the LDI widens its samples by what that can do (ldi/depths.frag)
layout(std430, binding = 2) writeonly buffer Motion { float motion[]; };
#endif
#ifndef VOX_FIX_AXIS
#define VOX_FIX_AXIS -1
#endif
#if VOX_FIX_AXIS >= 0
// VOX_FIX_AXIS a (with VOX_DOUBLE): the output coordinates other than a rounded to
// multiples of 2^-u_fix_bits voxel, the fixed point eisemann/column.glsl decides
// coverage in (products with powers of two, exact; ties to even)
uniform int u_fix_bits;
#endif
uniform uint u_vertices;
// exact: bit for bit glvox.gpu.transform (p * stretch - shift must not fuse)
void main() {
    uint i = global_index_1d();
    if (i >= u_vertices) return;
    vec3 w = vec3(verts[3u * i], verts[3u * i + 1u], verts[3u * i + 2u]);
    precise dvec3 p = vertex_to_voxel(w, u_origin_d, u_inv_h_d) * u_stretch_d - u_shift_d;
    precise dvec3 o = dvec3(p[u_axes.x], p[u_axes.y], p[u_axes.z]);
#if VOX_FIX_AXIS >= 0
    for (int c = 0; c < 3; ++c) {
        if (c == VOX_FIX_AXIS) continue;
        precise double units = o[c] * double(1 << u_fix_bits);
        // 2^-F from its bits (GLSL lets a division be 2.5 ulp off)
        precise double rounded = roundEven(units) * packDouble2x32(uvec2(0u, uint(1023 - u_fix_bits) << 20));
        o[c] = rounded;
    }
#endif
    vox[3u * i] = VOX_T(o.x);
    vox[3u * i + 1u] = VOX_T(o.y);
    vox[3u * i + 2u] = VOX_T(o.z);
#if VOX_MOTION
    precise dvec3 raw = (dvec3(w) - u_origin_d) * u_inv_h_d;  // vertex_to_voxel before the snap
    precise dvec3 moved = abs(vertex_to_voxel(w, u_origin_d, u_inv_h_d) - raw);
    double m = max(moved.x, max(moved.y, moved.z));
    float f = float(m);
    motion[i] = double(f) < m ? uintBitsToFloat(floatBitsToUint(f) + 1u) : f;
#endif
}
