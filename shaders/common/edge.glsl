// 2D edge functions of a triangle's projection (Schwarz & Seidel 2010, Eq. 2-3,
// Sec. 3.4 and 4.1).  Points are 2D coordinates in a coordinate plane; `orient`
// is +1 or -1 so that the edge normals point into the triangle.

// Inward edge normal of the edge vi -> vj.
vec2 edge_normal(vec2 vi, vec2 vj, float orient) {
    vec2 e = vj - vi;
    return vec2(-e.y, e.x) * orient;
}

// The edge functions are evaluated relative to the edge's start vertex,
// dot(n, p - vi) + offset, rather than with the paper's precomputed
// d = -dot(n, vi) + offset: the same value in exact arithmetic, but without
// the cancellation that loses exact touches once |vi| is large.

// Conservative corner term (Eq. 2): added to dot(n, p - vi) at a box's
// minimum corner p, it gives the value at the box corner most interior to
// the edge, for a box of extent dp.
float edge_box_term_conservative(vec2 n, vec2 dp) {
    return max(0.0, dp.x * n.x) + max(0.0, dp.y * n.y);
}

// 6-separating term (Sec. 3.4, Huang et al.'s 4-separating line criterion):
// the value at the box center plus half the extent along the dominant axis
// of the edge normal.
float edge_box_term_6sep(vec2 n, vec2 dp) {
    vec2 a = abs(n);
    float half_dominant = a.x >= a.y ? 0.5 * dp.x * a.x : 0.5 * dp.y * a.y;
    return dot(n, 0.5 * dp) + half_dominant;
}

// Top-left fill rule (Sec. 4.1): an edge owns the points exactly on it only
// when it is a left edge (n.x > 0) or a top edge (n.x == 0 and n.y < 0).
bool edge_is_top_left(vec2 n) { return n.x > 0.0 || (n.x == 0.0 && n.y < 0.0); }

// The paper adds the smallest float f to the edge value; GPUs flush such a
// denormal to zero, so the same rule is written out: inside when the value
// is positive, or zero on an edge that owns its points.
bool edge_inside(float value, bool top_left) { return value > 0.0 || (value == 0.0 && top_left); }
