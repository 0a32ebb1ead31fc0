#version 450
// Leung & Wang 2013 Alg. 1 lines 1-7: T1 by the XOR solid voxelization of Eisemann &
// Decoret on the LOD-C cells.  One fragment = one triangle crossing one ray; it writes
// ones at every cell from its own (ldi/cells.glsl) to the end of the pass, so the XOR of
// all of them leaves bit k = parity of the crossings in cells 0..k.  (eisemann/slices.frag
// would flip from floor(q' + 1/2) = the cell too, but not clamp a crossing on the far face
// into the last cell.)
#include "eisemann/column.glsl"
#include "eisemann/masks.glsl"
#include "ldi/cells.glsl"

uniform ivec2 u_tile_lo;
uniform int u_slice_lo;  // first cell of this pass

flat in uint v_tri;

void main() {
    dvec3 p0, p1, p2;
    eis_triangle(v_tri, p0, p1, p2);
    dvec2 c = dvec2(ivec2(gl_FragCoord.xy) + u_tile_lo) + 0.5;
    dvec3 w;
    if (!eis_covers_at(p0, p1, p2, c, w)) discard;
    int z = ldi_cell(ldi_cell_depth(eis_crossing(p0, p1, p2, w)));
    int first = z - u_slice_lo;
    if (first >= EIS_SLICES) discard;  // XOR with zeros
    eis_write_suffix(first);
}
