#version 450
// One fragment = one triangle crossing one voxel column.
// EIS_OP 0 (XOR, solid): ones at every slice from the first voxel whose center
// lies beyond the crossing (k + 0.5 > q); XOR over all crossings leaves the
// parity of the crossings below each voxel center.
// EIS_OP 1 (OR, surface): the one slice holding the crossing point
// (Eisemann & Decoret 2006).
#include "eisemann/column.glsl"
#include "eisemann/masks.glsl"

uniform ivec2 u_tile_lo;
uniform int u_slice_lo;
uniform int u_axis_n;  // slices of the whole grid along EIS_AXIS

flat in uint v_tri;

void main() {
    dvec3 p0, p1, p2;
    eis_triangle(v_tri, p0, p1, p2);
    dvec3 n = eis_normal(p0, p1, p2);
    // gl_FragCoord.xy is the pixel center, pixel + 0.5
    dvec2 c = dvec2(ivec2(gl_FragCoord.xy) + u_tile_lo) + 0.5;
#if EIS_COVERAGE == 0
    if (!eis_covers(p0, p1, p2, n.z, c)) discard;
#endif
    double q = eis_crossing(p0, p1, p2, n, c);
#if EIS_OP == 0
    int first = eis_first_flipped(q) - u_slice_lo;
    if (first >= EIS_SLICES) discard;  // XOR with zeros
    eis_write_suffix(first);
#else
    int s = eis_slice_of(q, u_axis_n) - u_slice_lo;
    if (s < 0 || s >= EIS_SLICES) discard;
    eis_write_bit(s);
#endif
}
