// gwn-solid's two kinds of terms of F (glvox/reference/winding.py has the
// derivation): exact strips of boundary edges and chords, and the far-field
// expansion of a cluster (glvox/methods/gwn_tree.py).  Both add to the sums
// of a segment of 4 GWN_SEGV voxels of one row, x centers x0 + 0.5 ..
// x0 + 4 GWN_SEGV - 0.5, in half solid angles (atan2 values; F = sum / (2 pi)).
// The sums are globals of the invocation, not inout parameters: an array
// parameter is copied in and out at every call.
#include "ss/solid.glsl"

#if GWN_SEGV != 8
#error "GWN_EACH_BLOCK spells out 8 blocks"
#endif
// M(0) .. M(7): a loop over the segment's blocks written out, so that seg_f and
// seg_bnd are indexed by constants (common/each_target.glsl has why).
#define GWN_EACH_BLOCK(M) M(0) M(1) M(2) M(3) M(4) M(5) M(6) M(7)
vec4 seg_f[GWN_SEGV];    // half solid angles
vec4 seg_bnd[GWN_SEGV];  // the expansions' error bounds, turns

const float GWN_PI = 3.14159265358979;

// The (y, z) edge function of u -> v at the row center c, in voxel^2, from the
// integers that decide triangle crossings (ss/solid.glsl: the vertices' (y, z)
// in its fixed point): its sign exact, its value rounded once.  A strip of this
// edge jumps exactly where its sign changes, and the owning triangle's crossing
// of the row starts or stops there too.
// exact: ss/solid.glsl's edge function
double gwn_edge(ivec2 u, ivec2 v, ivec2 c) {
    int s;
    precise double f = fixed_edge(u, v, c, s) * solid_unit2();
    return f;
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

// A strip's set-up at row center c = (y, z): what its value at the voxels of
// the row needs, computed once per row (strip_eval evaluates it).  Not for an
// edge parallel to x (strip_empty), which sweeps a strip of no area.
struct Strip {
    float ra2, rb2, ab;   // (y, z) distances of the end points, their dot
    float num, nudge;     // the edge function; its sign where that is 0
    float va, vb;         // the limits through an end point (vertex_angle)
};

// Whether the edge u -> v is parallel to x in the fixed point the crossings see.
bool strip_empty(vec3 u, vec3 v) { return solid_fixed(u.yz) == solid_fixed(v.yz); }

Strip strip_setup(vec3 u, vec3 v, vec2 c) {
    Strip s;
    // the edge and the end points at the center as the crossings see them: in the
    // fixed point, so that the strip's special cases fall where theirs do
    ivec2 uf = solid_fixed(u.yz), vf = solid_fixed(v.yz), cf = solid_fixed(c);
    vec2 e = vec2(vf - uf);
    vec2 a = uf == cf ? vec2(0.0) : u.yz - c, b = vf == cf ? vec2(0.0) : v.yz - c;
    s.ra2 = dot(a, a);
    s.rb2 = dot(b, b);
    s.ab = dot(a, b);
    s.num = float(gwn_edge(uf, vf, cf));
    // where the edge function is 0, its sign at the center nudged as the
    // top-left rule nudges it (+y, then -z)
    s.nudge = e.y != 0.0 ? -sign(e.y) : -sign(e.x);
    s.va = vertex_angle(e, -1.0);
    s.vb = vertex_angle(e, 1.0);
    return s;
}

// Half the solid angle of the strip of u -> v at the x centers xs of the row
// strip_setup was given.
vec4 strip_eval(Strip s, vec3 u, vec3 v, vec4 xs) {
    vec4 dxa = u.x - xs, dxb = v.x - xs;
    vec4 den = plus_x(dxa, s.ra2) * plus_x(dxb, s.rb2) + s.ab;
    vec4 h = s.num != 0.0 ? atan(vec4(s.num), den) : mix(vec4(0.0), vec4(s.nudge * GWN_PI), lessThan(den, vec4(0.0)));
    if (s.ra2 == 0.0) h = mix(h, vec4(s.va), lessThan(dxa, vec4(0.0)));
    if (s.rb2 == 0.0) h = mix(h, vec4(s.vb), lessThan(dxb, vec4(0.0)));
    return h;
}

// Adds weight * (half the solid angle of the strip of u -> v) at the
// segment's blocks of 4 voxels in `blocks` (bit i: voxels 4 i .. 4 i + 3);
// row center c = (y, z).
void add_strip(vec3 u, vec3 v, vec2 c, float x0, float weight, uint blocks) {
    if (strip_empty(u, v)) return;
    Strip s = strip_setup(u, v, c);
#define GWN_STRIP_BLOCK(i) if ((blocks & (1u << i)) != 0u) \
        seg_f[i] += weight * strip_eval(s, u, v, vec4(x0 + 0.5) + vec4(4 * i, 4 * i + 1, 4 * i + 2, 4 * i + 3));
    GWN_EACH_BLOCK(GWN_STRIP_BLOCK)
}

// Half the solid angle of the strip of u -> v at the point p.
float strip_at(vec3 u, vec3 v, vec3 p) {
    return strip_empty(u, v) ? 0.0 : strip_eval(strip_setup(u, v, p.yz), u, v, vec4(p.x)).x;
}

// Adds the far-field expansion of a node (gwn_tree.pack_moments: n[0] = (c, r),
// n[1] = (D, tr Q), n[2..6] the symmetric Q, g, symmetric T), in half solid
// angles (Omega / 2), and the bound of its error (turns; the fan's unsigned
// area in n[6].w; glvox.methods.gwn.tree.far_bound):
// area / (4 pi rho^2) * q^3 (4 - 3 q) / (1 - q)^2, q = r / rho < 1.
// Along the row only t = c_x - x varies: the numerator over rho^7 is a
// polynomial in t whose coefficients are set up once.
// The polynomials of a node's expansion along the row through c = (y, z).
struct Far {
    float s;                  // the row's squared (y, z) distance from the center
    float A1, A0, B2, B1, B0, C3, C2, C1, C0;
};

Far far_setup(vec4 n[7], vec2 c) {
    Far f;
    float Y = n[0].y - c.x, Z = n[0].z - c.y;
    f.s = Y * Y + Z * Z;
    // D.y + tr Q = A1 t + A0
    f.A1 = n[1].x;
    f.A0 = n[1].y * Y + n[1].z * Z + n[1].w;
    // 3 y.Q.y + 1.5 g.y = B2 t^2 + B1 t + B0  (Q: xx yy zz xy | xz yz; g: n[3].zw, n[4].x)
    f.B2 = 3.0 * n[2].x;
    f.B1 = 6.0 * (n[2].w * Y + n[3].x * Z) + 1.5 * n[3].z;
    f.B0 = 3.0 * (n[2].y * Y * Y + n[2].z * Z * Z + 2.0 * n[3].y * Y * Z) + 1.5 * (n[3].w * Y + n[4].x * Z);
    // 7.5 T(y, y, y) = C3 t^3 + C2 t^2 + C1 t + C0
    // (T: xxx yyy zzz = n[4].yzw; xxy xxz xyy xzz = n[5]; yyz yzz xyz = n[6].xyz)
    f.C3 = 7.5 * n[4].y;
    f.C2 = 22.5 * (n[5].x * Y + n[5].y * Z);
    f.C1 = 22.5 * (n[5].z * Y * Y + 2.0 * n[6].z * Y * Z + n[5].w * Z * Z);
    f.C0 = 7.5 * (n[4].z * Y * Y * Y + 3.0 * n[6].x * Y * Y * Z + 3.0 * n[6].y * Y * Z * Z + n[4].w * Z * Z * Z);
    return f;
}

// The expansion (half solid angles) at the x centers xs of the row, and its
// error bound (turns) in the out parameter.
vec4 far_eval(Far f, vec4 n[7], vec4 xs, out vec4 bound) {
    vec4 t = n[0].x - xs;
    vec4 r2 = t * t + f.s;
    vec4 num = r2 * r2 * (f.A1 * t + f.A0) - r2 * ((f.B2 * t + f.B1) * t + f.B0)
               + ((f.C3 * t + f.C2) * t + f.C1) * t + f.C0;
    vec4 inv = inversesqrt(r2);
    vec4 inv2 = inv * inv;
    vec4 inv3 = inv2 * inv;
    vec4 q = n[0].w * inv, p = 1.0 - q;
    bound = n[6].w * (0.25 / GWN_PI) * q * q * q * (4.0 - 3.0 * q) * inv2 / (p * p);
    return 0.5 * num * (inv3 * inv3 * inv);
}

// Adds the far-field expansion of a node (gwn_tree.pack_moments: n[0] = (c, r),
// n[1] = (D, tr Q), n[2..6] the symmetric Q, g, symmetric T), in half solid
// angles (Omega / 2), and the bound of its error (turns; the fan's unsigned
// area in n[6].w; glvox.methods.gwn.tree.far_bound):
// area / (4 pi rho^2) * q^3 (4 - 3 q) / (1 - q)^2, q = r / rho < 1.
// Along the row only t = c_x - x varies: the numerator over rho^7 is a
// polynomial in t whose coefficients are set up once.
void add_far(vec4 n[7], vec2 c, float x0, uint blocks) {
    Far f = far_setup(n, c);
    vec4 bound;
#define GWN_FAR_BLOCK(i) if ((blocks & (1u << i)) != 0u) { \
        seg_f[i] += far_eval(f, n, vec4(x0 + 0.5) + vec4(4 * i, 4 * i + 1, 4 * i + 2, 4 * i + 3), bound); \
        seg_bnd[i] += bound; }
    GWN_EACH_BLOCK(GWN_FAR_BLOCK)
}

// The expansion at the point p (half solid angle) and its error bound (turns).
vec2 far_at(vec4 n[7], vec3 p) {
    vec4 bound;
    float v = far_eval(far_setup(n, p.yz), n, vec4(p.x), bound).x;
    return vec2(v, bound.x);
}
