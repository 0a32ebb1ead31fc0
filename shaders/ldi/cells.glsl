// LOD-C cells along a ray (Leung & Wang 2013 Sec. III-A): cell z is [z, z + 1) in cell
// units, z = 0 .. u_cells - 1, covering the grid's range along the axis.  The vertices
// arrive shifted by half a cell (common/transform.comp, scaled and shifted by glvox/methods/ldi/leung_wang.py), so a crossing q' of
// eisemann/column.glsl is at q' + 1/2 cells.
//
// A crossing at or beyond the far face (q = u_cells: a face on the grid's boundary, or
// geometry outside the grid) belongs to the last cell, one before the near face to the
// first: the same clamped cell is used by T1, T2 and the depth pass, so the masks and
// the fragments always agree, and every crossing of the ray is counted (T1 of the last
// cell is the parity of all of them: 0 on a closed mesh).

uniform int u_cells;  // LOD-C

// The crossing in cell units (unshifted).
// exact: one addition
double ldi_cell_depth(double q_shifted) {
    precise double q = q_shifted + 0.5;
    return q;
}

// The cell holding a crossing at qc cell units.
int ldi_cell(double qc) { return int(clamp(floor(qc), 0.0, double(u_cells - 1))); }
