// 2D edge functions of a triangle's projection (Schwarz & Seidel 2010, Eq. 2-3,
// Sec. 3.4 and 4.1).  Points are 2D coordinates in a coordinate plane; `orient`
// is +1 or -1 so that the edge normals point into the triangle.
//
// Exactness convention (every shader): a function whose result is claimed
// exact, or bit-identical to a CPU reference or to another pass, carries a
// `// exact:` comment line right above it, and every arithmetic result in it
// lands in a `precise` variable.  GLSL 4.50 Sec. 4.9 then forbids the compiler
// to fuse a*b+c into fma, reassociate or reorder those operations; Sec. 4.7.1
// allows all of that otherwise, and `precise` covers only the r-values that a
// precise l-value consumes in the same function, so a helper returns a precise
// local, never an expression (tests/test_shaders.py checks this statically).

// Inward edge normal of the edge vi -> vj.
// exact: negation and a product by +-1
vec2 edge_normal(vec2 vi, vec2 vj, float orient) {
    precise vec2 e = vj - vi;
    precise vec2 n = vec2(-e.y, e.x) * orient;
    return n;
}

// The edge functions are evaluated relative to the edge's start vertex,
// dot(n, p - vi) + offset, rather than with the paper's precomputed
// d = -dot(n, vi) + offset: the same value in exact arithmetic, but without
// the cancellation that loses exact touches once |vi| is large.

// Conservative corner term (Eq. 2): added to dot(n, p - vi) at a box's
// minimum corner p, it gives the value at the box corner most interior to
// the edge, for a box of extent dp.
// exact: S&S's offsets, shared by the GPU and its CPU mirror
float edge_box_term_conservative(vec2 n, vec2 dp) {
    precise float r = max(0.0, dp.x * n.x) + max(0.0, dp.y * n.y);
    return r;
}

// 6-separating term (Sec. 3.4, Huang et al.'s 4-separating line criterion):
// the value at the box center plus half the extent along the dominant axis
// of the edge normal.
// exact: S&S's offsets, shared by the GPU and its CPU mirror
float edge_box_term_6sep(vec2 n, vec2 dp) {
    vec2 a = abs(n);
    precise float half_dominant = a.x >= a.y ? 0.5 * dp.x * a.x : 0.5 * dp.y * a.y;
    precise vec2 h = 0.5 * dp;
    precise float r = (n.x * h.x + n.y * h.y) + half_dominant;
    return r;
}

// Top-left fill rule (Sec. 4.1): an edge owns the points exactly on it only
// when it is a left edge (n.x > 0) or a top edge (n.x == 0 and n.y < 0).
bool edge_is_top_left(vec2 n) { return n.x > 0.0 || (n.x == 0.0 && n.y < 0.0); }

// The paper adds the smallest float f to the edge value; GPUs flush such a
// denormal to zero, so the same rule is written out: inside when the value
// is positive, or zero on an edge that owns its points.
bool edge_inside(float value, bool top_left) { return value > 0.0 || (value == 0.0 && top_left); }
