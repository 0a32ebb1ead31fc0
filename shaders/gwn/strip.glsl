// gwn-solid's two kinds of terms of F (glvox/reference/winding.py has the
// derivation): exact strips of boundary edges and chords, and the far-field
// expansion of a cluster (glvox/methods/gwn_tree.py).  Both add to the sums
// of a segment of 4 GWN_SEGV voxels of one row, x centers x0 + 0.5 ..
// x0 + 4 GWN_SEGV - 0.5, in half solid angles (atan2 values; F = sum / (2 pi)).
// The sums are globals of the invocation, not inout parameters: an array
// parameter is copied in and out at every call.
#include "ss/solid.glsl"

vec4 seg_f[GWN_SEGV];    // half solid angles
vec4 seg_bnd[GWN_SEGV];  // the expansions' error bounds, turns

const float GWN_PI = 3.14159265358979;

// The (y, z) edge function of u -> v at the row center c, with the double
// arithmetic that decides triangle crossings (ss/solid.glsl): evaluated from
// the lexicographically smaller end point, negated when the edge runs the
// other way.  A strip of this edge jumps exactly where its sign changes, and
// the owning triangle's crossing of the row starts or stops there too.
// exact: ss/solid.glsl's edge function
double gwn_edge(vec2 u, vec2 v, vec2 c) {
    dvec2 p = dvec2(u), q = dvec2(v);
    bool swap = p.x > q.x || (p.x == q.x && p.y > q.y);
    precise dvec2 pq = p - q, qp = q - p;
    double f = solid_edge_raw(swap ? q : p, swap ? pq : qp, dvec2(c));
    return swap ? -f : f;
}

// |a| + a_x, without cancellation where a_x < 0 (r2 = a_y^2 + a_z^2).
vec4 plus_x(vec4 dx, float r2) {
    vec4 l = sqrt(dx * dx + r2);
    return mix(r2 / (l - dx), l + dx, greaterThanEqual(dx, vec4(0.0)));
}

// atan2 of a strip at the voxels of a row through an end point of its edge,
// ahead of it (the limit from the nudged center; reference: _through_vertex);
// e = the edge's (y, z) projection, x_sign -1 at its start, +1 at its end.
float vertex_angle(vec2 e, float x_sign) {
    if (e.y != 0.0) return atan(-e.y, x_sign * e.x);
    return x_sign * e.x < 0.0 ? -sign(e.x) * GWN_PI : 0.0;
}

// Adds weight * (half the solid angle of the strip of u -> v) at the
// segment's blocks of 4 voxels in `blocks` (bit i: voxels 4 i .. 4 i + 3);
// row center c = (y, z).  An edge parallel to x sweeps a strip of no area:
// nothing.
void add_strip(vec3 u, vec3 v, vec2 c, float x0, float weight, uint blocks) {
    vec2 e = v.yz - u.yz;
    if (e == vec2(0.0)) return;
    vec2 a = u.yz - c, b = v.yz - c;
    float ra2 = dot(a, a), rb2 = dot(b, b), ab = dot(a, b);
    float num = float(gwn_edge(u.yz, v.yz, c));
    // where the edge function is 0, its sign at the center nudged as the
    // top-left rule nudges it (+y, then -z)
    float nudge = e.y != 0.0 ? -sign(e.y) : -sign(e.x);
    float va = vertex_angle(e, -1.0), vb = vertex_angle(e, 1.0);
    for (int i = 0; i < GWN_SEGV; ++i) {
        if ((blocks & (1u << i)) == 0u) continue;
        vec4 xs = vec4(x0 + 0.5) + vec4(4 * i, 4 * i + 1, 4 * i + 2, 4 * i + 3);
        vec4 dxa = u.x - xs, dxb = v.x - xs;
        vec4 den = plus_x(dxa, ra2) * plus_x(dxb, rb2) + ab;
        vec4 h = num != 0.0 ? atan(vec4(num), den) : mix(vec4(0.0), vec4(nudge * GWN_PI), lessThan(den, vec4(0.0)));
        if (ra2 == 0.0) h = mix(h, vec4(va), lessThan(dxa, vec4(0.0)));
        if (rb2 == 0.0) h = mix(h, vec4(vb), lessThan(dxb, vec4(0.0)));
        seg_f[i] += weight * h;
    }
}

// Adds the far-field expansion of a node (gwn_tree.pack_moments: n[0] = (c, r),
// n[1] = (D, tr Q), n[2..6] the symmetric Q, g, symmetric T), in half solid
// angles (Omega / 2), and the bound of its error (turns; the fan's unsigned
// area in n[6].w; glvox.methods.gwn.tree.far_bound):
// area / (4 pi rho^2) * q^3 (4 - 3 q) / (1 - q)^2, q = r / rho < 1.
// Along the row only t = c_x - x varies: the numerator over rho^7 is a
// polynomial in t whose coefficients are set up once.
void add_far(vec4 n[7], vec2 c, float x0, uint blocks) {
    float Y = n[0].y - c.x, Z = n[0].z - c.y;
    float s = Y * Y + Z * Z;
    // D.y + tr Q = A1 t + A0
    float A1 = n[1].x, A0 = n[1].y * Y + n[1].z * Z + n[1].w;
    // 3 y.Q.y + 1.5 g.y = B2 t^2 + B1 t + B0  (Q: xx yy zz xy | xz yz; g: n[3].zw, n[4].x)
    float B2 = 3.0 * n[2].x;
    float B1 = 6.0 * (n[2].w * Y + n[3].x * Z) + 1.5 * n[3].z;
    float B0 = 3.0 * (n[2].y * Y * Y + n[2].z * Z * Z + 2.0 * n[3].y * Y * Z) + 1.5 * (n[3].w * Y + n[4].x * Z);
    // 7.5 T(y, y, y) = C3 t^3 + C2 t^2 + C1 t + C0
    // (T: xxx yyy zzz = n[4].yzw; xxy xxz xyy xzz = n[5]; yyz yzz xyz = n[6].xyz)
    float C3 = 7.5 * n[4].y;
    float C2 = 22.5 * (n[5].x * Y + n[5].y * Z);
    float C1 = 22.5 * (n[5].z * Y * Y + 2.0 * n[6].z * Y * Z + n[5].w * Z * Z);
    float C0 = 7.5 * (n[4].z * Y * Y * Y + 3.0 * n[6].x * Y * Y * Z + 3.0 * n[6].y * Y * Z * Z + n[4].w * Z * Z * Z);
    for (int i = 0; i < GWN_SEGV; ++i) {
        if ((blocks & (1u << i)) == 0u) continue;
        vec4 xs = vec4(x0 + 0.5) + vec4(4 * i, 4 * i + 1, 4 * i + 2, 4 * i + 3);
        vec4 t = n[0].x - xs;
        vec4 r2 = t * t + s;
        vec4 num = r2 * r2 * (A1 * t + A0) - r2 * ((B2 * t + B1) * t + B0) + ((C3 * t + C2) * t + C1) * t + C0;
        vec4 inv = inversesqrt(r2);
        vec4 inv2 = inv * inv;
        vec4 inv3 = inv2 * inv;
        seg_f[i] += 0.5 * num * (inv3 * inv3 * inv);
        vec4 q = n[0].w * inv, p = 1.0 - q;
        seg_bnd[i] += n[6].w * (0.25 / GWN_PI) * q * q * q * (4.0 - 3.0 * q) * inv2 / (p * p);
    }
}
