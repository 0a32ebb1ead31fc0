// The verdict of one (triangle, column center) pair by the exact tie functions of
// ss/solid.glsl (PROBE_EIS 0: float32 voxel-space vertices with (y, z) in its fixed point,
// columns along x, centers in (y, z)) or eisemann/column.glsl (PROBE_EIS 1: double
// vertices in its fixed point, EIS_AXIS 2: columns along z, centers in (x, y)), with
// every intermediate the verdict rests on,
// PROBE_WORDS uint32 words per pair:
//   0      1 where the triangle takes part (its exact orientation across the ray != 0)
//   1-2    the normal component along the ray, double bits (low, high)
//   3-8    the three edge functions at the center, oriented inside-positive, double bits
//          in voxel^2 (from exact 64-bit integers, rounded once)
//   9-11   the three top-left flags
//   12     1 where the center is covered
//   13     the first voxel the crossing flips (covered pairs only)
// Run by compare/probe_ties.py in a compute shader (tie_probe.comp) and, for
// eisemann, in a fragment shader (tie_probe.frag), as the method runs it.
#define PROBE_WORDS 14

layout(std430, binding = 2) readonly buffer ProbeCenters { vec2 probe_centers[]; };
layout(std430, binding = 3) writeonly buffer ProbeOut { uint probe_out[]; };
uniform uint u_pairs;
uniform uint u_centers;

#if PROBE_EIS
// eisemann/column.glsl (with EIS_AXIS) is included by the caller: vertices from EisVox
// (binding 0), faces from EisFaces (binding 1).  Its coverage is integer: word 0 is 1
// where the exact orientation is not 0, words 1-2 the double normal component, words
// 3-8 the edge functions from their exact 64-bit values, rounded once to doubles, in
// voxel^2 (so that they do not depend on F).
void probe_pair(uint p) {
    uint t = p / u_centers;
    dvec2 c = dvec2(probe_centers[p % u_centers]);
    dvec3 p0, p1, p2;
    eis_triangle(t, p0, p1, p2);
    dvec3 n = eis_normal(p0, p1, p2);
    ivec2 f[3] = ivec2[3](eis_fixed(p0.xy), eis_fixed(p1.xy), eis_fixed(p2.xy));
    int sgn = fixed_orientation(f);
    uint o = p * uint(PROBE_WORDS);
    uvec2 nb = unpackDouble2x32(n.z);
    probe_out[o] = sgn != 0 ? 1u : 0u;
    probe_out[o + 1u] = nb.x;
    probe_out[o + 2u] = nb.y;
    ivec2 cf = eis_fixed(c);
    for (int i = 0; i < 3; ++i) {
        int s;
        double unit = eis_unit();  // voxel^2 per unit^2: exact
        uvec2 fb = unpackDouble2x32(fixed_edge(f[i], f[(i + 1) % 3], cf, s) * double(sgn == 0 ? 1 : sgn) * unit * unit);
        probe_out[o + 3u + 2u * uint(i)] = fb.x;
        probe_out[o + 4u + 2u * uint(i)] = fb.y;
        probe_out[o + 9u + uint(i)] = fixed_top_left(f, i, sgn == 0 ? 1 : sgn) ? 1u : 0u;
    }
    dvec3 w;
    bool covered = eis_covers_at(p0, p1, p2, c, w);
    probe_out[o + 12u] = covered ? 1u : 0u;
    probe_out[o + 13u] = covered ? uint(eis_first_flipped(eis_crossing(p0, p1, p2, w))) : 0u;
}
#else
// ss/solid.glsl is included by the caller, its coverage integer as eisemann's: the same
// words, the normal component that of the (y, z) rounded to its fixed point.
layout(std430, binding = 0) readonly buffer ProbeTris { float probe_tris[]; };  // 9 per triangle

vec3 probe_vertex(uint t, uint k) {
    uint b = 9u * t + 3u * k;
    return vec3(probe_tris[b], probe_tris[b + 1u], probe_tris[b + 2u]);
}

void probe_pair(uint p) {
    uint t = p / u_centers;
    vec2 c = probe_centers[p % u_centers];
    SolidTri T;
    bool ok = solid_setup(probe_vertex(t, 0u), probe_vertex(t, 1u), probe_vertex(t, 2u), T);
    int so = T.sgn == 0 ? 1 : T.sgn;
    double unit = fixed_unit(u_solid_fix_bits);
    dvec2 q0 = dvec2(T.f[0]) * unit, q1 = dvec2(T.f[1]) * unit, q2 = dvec2(T.f[2]) * unit;
    precise dvec2 e0 = q1 - q0;
    precise dvec2 e1 = q2 - q0;
    precise double n = e0.x * e1.y - e0.y * e1.x;
    uint o = p * uint(PROBE_WORDS);
    uvec2 nb = unpackDouble2x32(n);
    probe_out[o] = ok ? 1u : 0u;
    probe_out[o + 1u] = nb.x;
    probe_out[o + 2u] = nb.y;
    ivec2 cf = solid_fixed(c);
    for (int i = 0; i < 3; ++i) {
        int s;
        uvec2 fb = unpackDouble2x32(fixed_edge(T.f[i], T.f[(i + 1) % 3], cf, s) * double(so) * solid_unit2());
        probe_out[o + 3u + 2u * uint(i)] = fb.x;
        probe_out[o + 4u + 2u * uint(i)] = fb.y;
        probe_out[o + 9u + uint(i)] = fixed_top_left(T.f, i, so) ? 1u : 0u;
    }
    dvec3 w;
    bool covered = ok && solid_covers(T, c, w);
    probe_out[o + 12u] = covered ? 1u : 0u;
    probe_out[o + 13u] = covered ? uint(solid_first_flip(T, w)) : 0u;
}
#endif
