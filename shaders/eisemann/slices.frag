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

#if EIS_TRACE
// EIS_TRACE 1 (glvox.testing.tie_probe.trace): every fragment of the first pass
// as (triangle, column u with bit 31 set where the triangle does not cover the
// center, column v, first slice flipped), so that a fragment the rasterizer
// never made tells itself apart from a coverage decided otherwise.
layout(std430, binding = 5) buffer EisTrace { uint eis_trace_n; uint eis_trace[]; };

void eis_trace_fragment(ivec2 column, bool covered, int first) {
    if (u_slice_lo != 0) return;
    uint at = atomicAdd(eis_trace_n, 1u);
    if (4u * at + 3u >= uint(eis_trace.length())) return;
    eis_trace[4u * at] = v_tri;
    eis_trace[4u * at + 1u] = uint(column.x) | (covered ? 0u : 0x80000000u);
    eis_trace[4u * at + 2u] = uint(column.y);
    eis_trace[4u * at + 3u] = uint(first);
}
#endif

void main() {
    dvec3 p0, p1, p2;
    eis_triangle(v_tri, p0, p1, p2);
    // gl_FragCoord.xy is the pixel center, pixel + 0.5
    ivec2 column = ivec2(gl_FragCoord.xy) + u_tile_lo;
    dvec2 c = dvec2(column) + 0.5;
    dvec3 w;
#if EIS_COVERAGE == 0
    bool covered = eis_covers_at(p0, p1, p2, c, w);
#else
    ivec3 s_unused;
    int sgn_unused;
    ivec2 f_unused[3];
    eis_weights(p0, p1, p2, c, w, s_unused, sgn_unused, f_unused);
    bool covered = true;
#endif
#if EIS_TRACE
    eis_trace_fragment(column, covered, covered ? eis_first_flipped(eis_crossing(p0, p1, p2, w)) : 0);
#endif
    if (!covered) discard;
    double q = eis_crossing(p0, p1, p2, w);
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
