// Coverage in integers: the exact 2D predicates of the parity solids
// (eisemann/column.glsl, ss/solid.glsl) on fixed-point coordinates.
//
// A caller rounds each vertex's two coordinates across the rays once, the same
// way for every triangle that has it, to integers in units of 2^-F voxel, with
// F chosen per run (glvox.gpu.fixed_point.fixed_bits) so that every coordinate
// and column center is below 2^29 units and every difference below 2^30.  Each
// edge function and orientation is then a * b - c * d on such differences, whose
// exact sign imulExtended's 64-bit products and a borrow give: no floating
// point takes part in a coverage decision, so no compiler's rounding, fusing or
// reordering can change one (GLSL gives doubles no precision guarantee beyond
// single precision; integers it defines exactly).  The rounded mesh is closed
// where the true one is, and the top-left rule counts a center on a shared edge
// or vertex exactly once.

// A float32 point in units of 2^-bits voxel: rounded to the nearest, ties to even (a
// vertex), or exactly (a column center).  |p| < 2^(29 - bits) (fixed_bits).
// exact: a float product by a power of two (exact: GLSL's float * is correctly rounded), then roundEven
ivec2 fixed_point(vec2 p, int bits) {
    precise vec2 x = p * float(1 << bits);
    return ivec2(roundEven(x));
}

// The center of column (j, k) in units of 2^-bits voxel: (2 j + 1, 2 k + 1) 2^(bits-1).
ivec2 fixed_center(ivec2 jk, int bits) { return (2 * jk + 1) << (bits - 1); }

// 2^-bits (bits 0..1022), from its bits: GLSL lets a division be 2.5 ulp off.
double fixed_unit(int bits) { return packDouble2x32(uvec2(0u, uint(1023 - bits) << 20)); }

// a * b - c * d exactly, as the two's-complement 64-bit integer hi * 2^32 + lo, from
// the 64-bit products of imulExtended (|a|..|d| < 2^30: the difference is below 2^61).
// exact: integer arithmetic
void fixed_det_words(int a, int b, int c, int d, out int hi, out uint lo) {
    int ab_hi, ab_lo, cd_hi, cd_lo;
    imulExtended(a, b, ab_hi, ab_lo);
    imulExtended(c, d, cd_hi, cd_lo);
    uint borrow;
    lo = usubBorrow(uint(ab_lo), uint(cd_lo), borrow);
    hi = ab_hi - cd_hi - int(borrow);
}

// The sign of the 64-bit integer hi * 2^32 + lo.
int fixed_sign(int hi, uint lo) { return hi < 0 ? -1 : (hi > 0 || lo != 0u ? 1 : 0); }

// The 64-bit integer hi * 2^32 + lo (below 2^61 in magnitude) rounded once to a double.
// exact: one rounding
double fixed_value(int hi, uint lo) {
    precise double v = double(hi) * 4294967296.0lf + double(lo);
    return v;
}

// a * b - c * d: its exact sign, and its value rounded once to a double.
// exact: integer arithmetic, then one rounding
double fixed_det(int a, int b, int c, int d, out int sgn) {
    int hi;
    uint lo;
    fixed_det_words(a, b, c, d, hi, lo);
    sgn = fixed_sign(hi, lo);
    return fixed_value(hi, lo);
}

// The sign of a * b - c * d, exactly.
// exact: integer arithmetic
int fixed_det_sign(int a, int b, int c, int d) {
    int sgn;
    fixed_det(a, b, c, d, sgn);
    return sgn;
}

// The edge function of p -> q at c, (q - p) x (c - p), in units of 2^-2F voxel^2: its
// exact sign, and its value rounded once.
// exact: integer arithmetic; opposite for the two triangles of an edge
double fixed_edge(ivec2 p, ivec2 q, ivec2 c, out int sgn) {
    ivec2 e = q - p;
    ivec2 r = c - p;
    return fixed_det(e.x, r.y, e.y, r.x, sgn);
}

// The projected triangle's orientation: +1 counter-clockwise (the normal's component
// along the rays positive), -1 clockwise, 0 parallel to the rays (no crossing).
// exact: integer arithmetic
int fixed_orientation(ivec2 f[3]) {
    return fixed_det_sign(f[1].x - f[0].x, f[2].y - f[0].y, f[1].y - f[0].y, f[2].x - f[0].x);
}

// Does edge i (vertex i -> i + 1) own the centers exactly on it?  Only a left edge
// (inward normal n_u > 0) or a top edge (n_u == 0, n_v < 0) does; sgn: the
// orientation.
// exact: integer differences and signs
bool fixed_top_left(ivec2 f[3], int i, int sgn) {
    ivec2 e = f[(i + 1) % 3] - f[i];
    int nu = -sign(e.y) * sgn;
    int nv = sign(e.x) * sgn;
    return nu > 0 || (nu == 0 && nv < 0);
}
