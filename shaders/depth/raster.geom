#version 450
// Passalis et al. 2006, Sec. 2-3: one orthographic view along u_axis, drawn tile by tile;
// pixel (x, y) of the render target is voxel column u_tile_origin + (x, y).
//
// Which columns a triangle crosses is decided in the fragment shader exactly as the
// reference decides it (edge functions, top-left rule), in integers on the view's (u, v)
// rounded to multiples of 2^-F voxel (common/fixed.glsl; F = u_fix_bits,
// glvox.gpu.fixed_point.fixed_bits), not by GL's rasterizer:
// GL snaps vertices to a sub-pixel grid (1/256 pixel on llvmpipe, 8 bits on most GPUs),
// which moves a silhouette edge by up to ~0.003 voxel and so adds or drops whole crossing
// pairs next to it, far from any tie (measured: a 256-voxel column of cad_featuretype.stl
// at 256^3).  This shader draws a proxy that contains every pixel center the triangle can
// own with a margin of PROXY_MARGIN pixel, far more than the snapping moves it: the
// triangle with its edges pushed out, or for slivers (long miters) its bounding box.  It
// also sorts triangles into Passalis' two facing classes by the sign of the normal's
// component along the rays (what face culling does), the exact orientation of the rounded
// projection, so that it agrees with the fragment shader.
layout(triangles) in;
layout(triangle_strip, max_vertices = 4) out;
#include "view.glsl"
#include "depth/cover.glsl"
in vec3 v_vox[];
uniform ivec2 u_tile_origin;
uniform ivec2 u_target_size;
uniform int u_class;  // 0: every triangle; +1: n_a > 0 only; -1: n_a < 0 only
uniform int u_fix_bits;
flat out vec3 g_p0;
flat out vec3 g_p1;
flat out vec3 g_p2;
flat out ivec2 g_f0;  // (u, v) of the vertices in units of 2^-F voxel
flat out ivec2 g_f1;
flat out ivec2 g_f2;
flat out int g_sgn;   // the orientation of the rounded projection: the sign of n_a
flat out double g_inv_area2;  // 1 / twice its area, units^2 (the crossing's divisor)
flat out uint g_id;

const double PROXY_MARGIN = 1.0 / 16.0;
const int CULL_CENTERS = 4;
// Miter factor (1 / sin of half the vertex angle) above which the pushed-out triangle is
// replaced by the bounding box: its tips would reach 625 pixels out.
const double MAX_MITER = 1.0e4;

// The triangle's data for the fragments, written with every vertex: GLSL leaves all outputs
// undefined after EmitVertex() (GLSL 4.50 Sec. 8.16), and flat ones are read from each
// primitive's provoking vertex (the last one by default), so setting them once before the
// first vertex works only where a compiler happens to keep them (llvmpipe does).
vec3 t_p0, t_p1, t_p2;
ivec2 t_f0, t_f1, t_f2;
int t_sgn;
double t_inv_area2;

void emit(dvec2 p) {
    g_p0 = t_p0;
    g_p1 = t_p1;
    g_p2 = t_p2;
    g_f0 = t_f0;
    g_f1 = t_f1;
    g_f2 = t_f2;
    g_sgn = t_sgn;
    g_inv_area2 = t_inv_area2;
    g_id = uint(gl_PrimitiveIDIn);
    gl_Position = vec4(vec2(2.0 * p / dvec2(u_target_size) - 1.0), 0.0, 1.0);
    EmitVertex();
}

void main() {
    vec3 p0 = to_view(v_vox[0]);
    vec3 p1 = to_view(v_vox[1]);
    vec3 p2 = to_view(v_vox[2]);
    dvec3 a = dvec3(p0), b = dvec3(p1), c = dvec3(p2);
    ivec2 f0 = fixed_point(p0.xy, u_fix_bits), f1 = fixed_point(p1.xy, u_fix_bits), f2 = fixed_point(p2.xy, u_fix_bits);
    int sgn;
    double area2 = abs(fixed_det(f1.x - f0.x, f2.y - f0.y, f1.y - f0.y, f2.x - f0.x, sgn));
    if (sgn == 0) return;  // parallel to the rays: no crossing, as in the reference
    if (u_class != 0 && ((sgn > 0) != (u_class > 0))) return;
    dvec2 off = dvec2(u_tile_origin);
    dvec2 q[3] = dvec2[3](a.xy - off, b.xy - off, c.xy - off);
    dvec2 lo = min(q[0], min(q[1], q[2]));
    dvec2 hi = max(q[0], max(q[1], q[2]));
    // no pixel center of the target inside the rounded triangle's bounding box along some
    // axis: nothing to own (center j is (2 j + 1) 2^(F-1) units)
    ivec2 flo = min(f0, min(f1, f2)), fhi = max(f0, max(f1, f2));
    int half_unit = 1 << (u_fix_bits - 1);
    ivec2 first = max(-((half_unit - flo) >> u_fix_bits) - u_tile_origin, ivec2(0));
    ivec2 last = min(((fhi - half_unit) >> u_fix_bits) - u_tile_origin, u_target_size - 1);
    if (any(greaterThan(first, last))) return;
    // a box of at most CULL_CENTERS centers none of which the triangle covers (the
    // fragments' own test): nothing to draw; a fine mesh has many such triangles
    ivec2 span = last - first + 1;
    if (span.x * span.y <= CULL_CENTERS) {
        ivec2 fs[3] = ivec2[3](f0, f1, f2);
        bool any_covered = false;
        for (int k = 0; k < span.x * span.y; ++k) {
            dvec3 w_unused;
            ivec2 pix = first + ivec2(k % span.x, k / span.x) + u_tile_origin;
            any_covered = any_covered || covers(fs, sgn, fixed_center(pix, u_fix_bits), w_unused);
        }
        if (!any_covered) return;
    }

    t_p0 = p0;
    t_p1 = p1;
    t_p2 = p2;
    t_f0 = f0;
    t_f1 = f1;
    t_f2 = f2;
    t_sgn = sgn;
    t_inv_area2 = 1.0lf / area2;

    double s = double(sgn);
    bool pushed = true;
    dvec2 nrm[3];
    for (int i = 0; i < 3; ++i) {
        dvec2 e = q[(i + 1) % 3] - q[i];
        double len = sqrt(dot(e, e));
        if (len == 0.0) pushed = false;
        nrm[i] = s * dvec2(e.y, -e.x) / max(len, 1.0e-300lf);  // outward unit normal
    }
    dvec2 corner[3];
    for (int j = 0; j < 3; ++j) {
        dvec2 n1 = nrm[(j + 2) % 3];
        dvec2 n2 = nrm[j];
        // the offset lines of the two edges at vertex j meet at q_j + m (n1 + n2) / (1 + n1.n2)
        double d = 1.0 + dot(n1, n2);
        if (d < 2.0 / (MAX_MITER * MAX_MITER)) pushed = false;
        corner[j] = q[j] + PROXY_MARGIN * (n1 + n2) / max(d, 1.0e-300lf);
    }
    if (pushed) {
        emit(corner[0]);
        emit(corner[1]);
        emit(corner[2]);
    } else {
        dvec2 l = max(lo - PROXY_MARGIN, dvec2(-1.0));
        dvec2 h = min(hi + PROXY_MARGIN, dvec2(u_target_size) + 1.0);
        emit(l);
        emit(dvec2(h.x, l.y));
        emit(dvec2(l.x, h.y));
        emit(h);
    }
    EndPrimitive();
}
