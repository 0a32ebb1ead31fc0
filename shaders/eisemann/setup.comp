#version 450
// Per-triangle setup of the render (once per run, one invocation per
// triangle), so that the vertex stage only reads it:
//   box:    columns i_lo..i_hi, j_lo..j_hi whose centers lie in the triangle's
//           bounding box, clipped to the grid; empty (i_lo > i_hi) for
//           triangles parallel to the axis or outside the grid;
//   slices: [s_lo, s_hi], the slices its crossings can touch: for XOR the
//           first flipped slice floor(q + 1/2) >= floor(a_lo + 1/2) and every
//           slice after it, for OR the crossing's slice floor(q) in
//           [floor(a_lo), floor(a_hi)];
//   corner: the three corners to draw, in pixels of the grid.
//
// EIS_COVERAGE 0 (exact): the fragment shader decides coverage exactly, so
// the drawn triangle must contain every column center the triangle covers,
// whatever the rasterizer's snapping and the float rounding of the corners
// do.  It is the triangle with each edge moved outwards by EIS_GROW pixels
// (corners on the miter): it contains every point within EIS_GROW of the
// triangle, so moving its corners by less than EIS_GROW keeps every point of
// the triangle inside.  They move by at most: the snap, half a step of
// 2^-GL_SUBPIXEL_BITS (GL guarantees at least 4 bits: 1/32); the float
// rounding of a corner below EIS_FLOAT_SAFE = 2^16 pixels (2^-8) and of its
// offset to the tile (2^-8); the clip and viewport transforms (~2^-13 for
// tiles up to 2^11): together under 0.04 < EIS_GROW = 1/16.  Where a sharp
// corner would push its miter further than EIS_MITER_MAX pixels, or
// coordinates reach EIS_FLOAT_SAFE, the triangle (x0, y0), (x0 + 2w, y0),
// (x0, y0 + 2h) around the box's pixel rectangle [x0, x0 + w] x [y0, y0 + h]
// (integer corners, snapped exactly) is drawn instead; every pixel center of
// the box lies inside it, at least 0.35 pixel from its edges.
// EIS_COVERAGE 1 (raster): the triangle itself, and the box grown by one
// pixel: the snapped triangle may cover a center just outside the exact box,
// and there the rasterizer decides, as in the paper.
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
#include "eisemann/column.glsl"

#define EIS_GROW 0.0625
#define EIS_MITER_MAX 2.0
#define EIS_FLOAT_SAFE 65536.0
#define EIS_CULL_CENTERS 4

struct EisSetup { ivec2 box_lo; ivec2 box_hi; ivec2 slices; vec2 corner[3]; };
layout(std430, binding = 3) writeonly buffer EisSetups { EisSetup eis_setup_out[]; };

uniform uint u_triangles;
uniform ivec3 u_dims;  // grid dims (x, y, z)

void main() {
    uint t = global_index_1d();
    if (t >= u_triangles) return;
    dvec3 p0, p1, p2;
    eis_triangle(t, p0, p1, p2);
    int orient = eis_orientation(p0, p1, p2);  // exact; 0: parallel to the axis
    ivec2 n_uv = ivec2(u_dims[EIS_U], u_dims[EIS_V]);
    dvec2 lo = min(min(p0.xy, p1.xy), p2.xy) - double(EIS_COVERAGE);
    dvec2 hi = max(max(p0.xy, p1.xy), p2.xy) + double(EIS_COVERAGE);
    ivec2 c_lo = max(ivec2(eis_to_int(ceil(lo.x - 0.5)), eis_to_int(ceil(lo.y - 0.5))), ivec2(0));
    ivec2 c_hi = min(ivec2(eis_to_int(floor(hi.x - 0.5)), eis_to_int(floor(hi.y - 0.5))), n_uv - 1);
    double a_lo = min(min(p0.z, p1.z), p2.z);
    double a_hi = max(max(p0.z, p1.z), p2.z);
#if EIS_OP == 0
    ivec2 slices = ivec2(eis_first_flipped(a_lo), 1073741824);
#else
    ivec2 slices = ivec2(eis_slice_of(a_lo, u_dims[EIS_AXIS]), eis_slice_of(a_hi, u_dims[EIS_AXIS]));
#endif
    EisSetup s;
    s.slices = slices;
    s.box_lo = c_lo;
    s.box_hi = orient == 0 ? c_lo - 1 : c_hi;
    dvec2 p[3] = dvec2[3](p0.xy, p1.xy, p2.xy);
#if EIS_COVERAGE == 0
    bool miter = orient != 0 && all(lessThan(abs(lo), dvec2(EIS_FLOAT_SAFE)))
                 && all(lessThan(abs(hi), dvec2(EIS_FLOAT_SAFE)));
    // outward unit normals of the edges p[i] -> p[i+1]
    double sgn = double(orient);
    dvec2 nrm[3];
    for (int i = 0; i < 3; ++i) {
        dvec2 e = p[(i + 1) % 3] - p[i];
        double len = length(e);
        miter = miter && len > 0.0;
        nrm[i] = len > 0.0 ? dvec2(e.y, -e.x) * (sgn / len) : dvec2(0.0);
    }
    for (int i = 0; i < 3; ++i) {
        dvec2 a = nrm[(i + 2) % 3];  // the edge ending at p[i]
        dvec2 b = nrm[i];            // the edge starting at p[i]
        // the miter is EIS_GROW * |a + b| / c = EIS_GROW * sqrt(2 / c) long (|a + b|^2 = 2c);
        // tested on c alone: at a sliver's tip a + b rounds to 0 with c, and the
        // quotient's test would pass a corner that is not pushed out at all
        double c = 1.0 + dot(a, b);
        miter = miter && c * (EIS_MITER_MAX * EIS_MITER_MAX) >= 2.0 * (EIS_GROW * EIS_GROW);
        s.corner[i] = vec2(p[i] + EIS_GROW * (a + b) / max(c, 1e-300));
    }
    if (!miter) {
        vec2 x0 = vec2(c_lo);
        vec2 wh = vec2(c_hi + 1 - c_lo);
        s.corner[0] = x0;
        s.corner[1] = x0 + vec2(2.0 * wh.x, 0.0);
        s.corner[2] = x0 + vec2(0.0, 2.0 * wh.y);
    }
    // A small box: no draw at all where the triangle covers none of its centers (the
    // fragments' own exact test, eis_covers_at), so the rasterizer never sees the many
    // triangles of a fine mesh that fall between column centers.
    ivec2 span = c_hi - c_lo + 1;
    if (orient != 0 && all(greaterThan(span, ivec2(0))) && span.x * span.y <= EIS_CULL_CENTERS) {
        bool covers = false;
        for (int k = 0; k < span.x * span.y; ++k) {
            dvec3 w_unused;
            ivec2 col = c_lo + ivec2(k % span.x, k / span.x);
            covers = covers || eis_covers_at(p0, p1, p2, dvec2(col) + 0.5, w_unused);
        }
        if (!covers) s.box_hi = c_lo - 1;
    }
#else
    for (int i = 0; i < 3; ++i) s.corner[i] = vec2(p[i]);
#endif
    eis_setup_out[t] = s;
}
