// The LDI's pixel order (glvox/ldi.py): the two axes other than the ray axis EIS_AXIS in
// increasing order, p-major.  The cyclic frame (u, v) = ((a + 1) % 3, (a + 2) % 3) of the
// renders (eisemann/column.glsl, depth/view.glsl) is (p, q), except along y where it is
// (q, p).  Every per-ray buffer (masks, counts, depths) is indexed by ldi_column.

uniform ivec2 u_grid_uv;  // (n_u, n_v): the whole pixel grid in the cyclic frame

uint ldi_column(ivec2 uv) {
#if EIS_AXIS == 1
    return uint(uv.y * u_grid_uv.x + uv.x);
#else
    return uint(uv.x * u_grid_uv.y + uv.y);
#endif
}
