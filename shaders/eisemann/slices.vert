#version 450
// Eisemann & Decoret 2008: one orthographic render of the mesh along EIS_AXIS,
// the viewport being the tile [u_tile_lo, u_tile_lo + u_tile_size) of the
// voxel columns: clip = 2 (w - u_tile_lo) / u_tile_size - 1 for a corner w in
// grid pixels, so pixel centers are column centers.  No vertex attributes:
// each vertex reads its triangle's setup (eisemann/setup.comp) by
// gl_VertexID, 3 per triangle.  Depth is unused (z = 0, no depth test): the
// fragment computes its crossing.  Triangles outside the tile, or whose
// crossings cannot touch this pass's slices [u_slice_lo, u_slice_hi), are
// culled: all their vertices at one point, no fragment.
#include "eisemann/column.glsl"

struct EisSetup { ivec2 box_lo; ivec2 box_hi; ivec2 slices; vec2 corner[3]; };
layout(std430, binding = 3) readonly buffer EisSetups { EisSetup eis_setup[]; };

uniform ivec2 u_tile_lo;
uniform ivec2 u_tile_size;
uniform int u_slice_lo;
uniform int u_slice_hi;

flat out uint v_tri;

void main() {
    uint t = uint(gl_VertexID) / 3u;
    v_tri = t;
    EisSetup s = eis_setup[t];
    ivec2 c_lo = max(s.box_lo, u_tile_lo);
    ivec2 c_hi = min(s.box_hi, u_tile_lo + u_tile_size - 1);
    if (any(greaterThan(c_lo, c_hi)) || s.slices.x >= u_slice_hi || s.slices.y < u_slice_lo) {
        gl_Position = vec4(-2.0, -2.0, 0.0, 1.0);
        return;
    }
    vec2 w = s.corner[gl_VertexID % 3] - vec2(u_tile_lo);
    gl_Position = vec4(2.0 * w / vec2(u_tile_size) - 1.0, 0.0, 1.0);
}
