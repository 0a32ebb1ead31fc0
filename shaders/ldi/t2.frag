#version 450
// Leung & Wang 2013 Alg. 1 lines 8-16: T2 by the OR pass.  A fragment sets the bit of its
// cell z when T1(z) = T1(z - 1) = 0: a cell holding crossings that T1 does not show (an
// even number of them with outside on both sides: a part thinner than a cell).
#include "eisemann/column.glsl"
#include "eisemann/masks.glsl"
#include "ldi/column.glsl"

uniform ivec2 u_tile_lo;
uniform int u_slice_lo;  // first cell of this pass

flat in uint v_tri;

void main() {
    dvec3 p0, p1, p2;
    eis_triangle(v_tri, p0, p1, p2);
    ivec2 pix = ivec2(gl_FragCoord.xy) + u_tile_lo;
    dvec2 c = dvec2(pix) + 0.5;
    dvec3 w;
    if (!eis_covers_at(p0, p1, p2, c, w)) discard;
    int z = ldi_cell(ldi_cell_depth(eis_crossing(p0, p1, p2, w)));
    int s = z - u_slice_lo;
    if (s < 0 || s >= EIS_SLICES) discard;
    uint col = ldi_column(pix);
    if (ldi_t1_bit(col, z) || ldi_t1_bit(col, z - 1)) discard;
    eis_write_bit(s);
}
