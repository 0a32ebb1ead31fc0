#version 450
// Schwarz & Seidel 2010 surface voxelization: one invocation per triangle and
// chunk of its work (see ss/work.glsl; nearly every triangle has one chunk).
//   SS_CRITERION  0: conservative (Sec. 3.1-3.2), 1: 6-separating (Sec. 3.4)
//   SS_VARIANT    0: simple (every voxel of the bounding box, full test)
//                 1: specialized (1D/2D/3D cases, dominant-axis columns)
//                 2: one bounding-box type SS_BBOX_TYPE of the sorted list
// The 6-separating criterion always uses the dominant-axis columns (Sec. 3.4).
//   SS_ATTR_PASS  (defined) the attribute passes' hook instead of the writes
//   SS_FIRST      (simple and specialized, no attribute pass) 1: one invocation
//                 per triangle (glvox.gpu.dispatch.dispatch_1d) counts its case, does
//                 its first chunk and lists the triangles with more (nearly none: a
//                 chunk is thousands of units), so no separate pass sets every
//                 triangle up only to count its chunks (ss/classify.comp).  0:
//                 invocation (i, chunk - 1) of an indirect dispatch
//                 (ss/solid_big_args.comp) does chunk `chunk` of the i-th listed
//                 triangle, chunk - 1 = y + z * groups y.  As ss/solid.comp does.
// Otherwise invocation (t, chunk): t from x (plus u_tri_offset), chunk = y + z * max groups.
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
#include "common/edge.glsl"
#include "ss/setup.glsl"
#include "ss/work.glsl"
#ifdef SS_ATTR_PASS
#include "attributes/pair.glsl"
#else
#include "ss/write.glsl"
#endif

layout(local_size_x = 64) in;
#if SS_VARIANT == 2
layout(std430, binding = 5) readonly buffer SortedTris { uint sorted_tri[]; };
layout(std430, binding = 6) readonly buffer Ranges { uint ranges[]; };  // (start, count) per type
#elif defined(SS_FIRST)
#if defined(SS_ATTR_PASS)
#error "SS_FIRST counts cases in Stats: the attribute passes run after ss/classify.comp"
#endif
#include "common/dispatch.glsl"
layout(std430, binding = 5) buffer Big { uint big_count; uint big_max_chunks; uint big_list[]; };
#else
layout(std430, binding = 5) readonly buffer TriChunks { uint tri_chunks[]; };
#endif
uniform uint u_triangles;
uniform uint u_tri_offset;

ivec3 compose(int u, int v, int w, int iu, int iv, int iw) {
    ivec3 p;
    p[u] = iu;
    p[v] = iv;
    p[w] = iw;
    return p;
}

// Units q0..q1-1 of the bounding box's voxels, x fastest, through the full
// test (simple) or none (1D boxes, whose touched voxels are all overlapped).
void voxelize_voxels(Tri T, uint q0, uint q1, bool full_test) {
    Proj Pz = make_proj(T, 0, 1, 2), Px = make_proj(T, 1, 2, 0), Py = make_proj(T, 2, 0, 1);
    uint sx = uint(T.hi.x - T.lo.x + 1), sy = uint(T.hi.y - T.lo.y + 1);
    int i = T.lo.x + int(q0 % sx), j = T.lo.y + int((q0 / sx) % sy), k = T.lo.z + int(q0 / (sx * sy));
    for (uint q = q0; q < q1; ++q) {
        if (!full_test || (plane_test(T, ivec3(i, j, k)) && proj_test(Pz, ivec2(i, j)) &&
                           proj_test(Px, ivec2(j, k)) && proj_test(Py, ivec2(k, i))))
            set_voxel(ivec3(i, j, k));
        if (++i > T.hi.x) { i = T.lo.x; if (++j > T.hi.y) { j = T.lo.y; ++k; } }
    }
}

// 2D bounding box, one voxel thick along c: a single 2D projection test.
void voxelize_2d(Tri T, uint q0, uint q1) {
    int c = case_axis(T, 1);
    int a = (c + 1) % 3, b = (c + 2) % 3;
    Proj P = make_proj(T, a, b, c);
    uint sa = uint(T.hi[a] - T.lo[a] + 1);
    int ia = T.lo[a] + int(q0 % sa), ib = T.lo[b] + int(q0 / sa);
    for (uint q = q0; q < q1; ++q) {
        if (proj_test(P, ivec2(ia, ib))) set_voxel(compose(a, b, c, ia, ib, T.lo[c]));
        if (++ia > T.hi[a]) { ia = T.lo[a]; ++ib; }
    }
}

// The smallest integer m with m * b >= a, and the largest with m * b <= a (b > 0).
// The float quotient only gives the first guess: where a and b are exact (dyadic
// geometry on a power-of-two grid) the comparisons decide exactly, so a plane that
// passes exactly through a voxel face or between two centers is not lost to the
// rounding of a / b (issue 20: it dropped touched voxels of slanted triangles).
// exact: the comparisons decide exactly
int ceil_div(float a, float b) {
    int m = int(ceil(a / b));
    precise float below = float(m - 1) * b;
    if (below >= a) return m - 1;
    precise float at = float(m) * b;
    return at < a ? m + 1 : m;
}

// exact: the comparisons decide exactly
int floor_div(float a, float b) {
    int m = int(floor(a / b));
    precise float above = float(m + 1) * b;
    if (above <= a) return m + 1;
    precise float at = float(m) * b;
    return at > a ? m - 1 : m;
}

// Columns along the dominant axis w of n (3D boxes, and every 6-sep triangle).
// Conservative: the plane gives the column's voxel range, then only the two
// remaining 2D tests (none when the range is one voxel).  6-separating: the
// column center projected onto the plane picks the voxel (two on a face).
// The plane's w is a / |n_w| with a the products below (no division before
// the comparisons of ceil_div / floor_div).
// exact: the plane's w range
void voxelize_columns(Tri T, uint q0, uint q1) {
    int w = dominant_axis(T.n);
    int u = (w + 1) % 3, v = (w + 2) % 3;
    Proj Pw = make_proj(T, u, v, w), Pu = make_proj(T, v, w, u), Pv = make_proj(T, w, u, v);
    float sw = T.n[w] >= 0.0 ? 1.0 : -1.0, b = abs(T.n[w]);
    precise float gu = -sw * T.n[u], gv = -sw * T.n[v];  // a's change per unit step in u and v
    uint su = uint(T.hi[u] - T.lo[u] + 1);
    int iu = T.lo[u] + int(q0 % su), iv = T.lo[v] + int(q0 / su);
    for (uint q = q0; q < q1; ++q) {
        if (proj_test(Pw, ivec2(iu, iv))) {
            // in the triangle's local frame (relative to T.base)
            float lu = float(iu - T.base[u]), lv = float(iv - T.base[v]);
#if SS_CRITERION == 1
            precise float a = b * T.v0[w] + gu * (lu + 0.5 - T.v0[u]) + gv * (lv + 0.5 - T.v0[v]);
            int f = floor_div(a, b);
            precise float fb = float(f) * b;
            int k1 = f + T.base[w], k0 = fb == a ? k1 - 1 : k1;
            bool single = false;
#else
            // the plane's w range over the closed column cell [iu, iu+1] x [iv, iv+1]
            precise float a = b * T.v0[w] + gu * (lu - T.v0[u]) + gv * (lv - T.v0[v]);
            precise float alo = a + min(gu, 0.0) + min(gv, 0.0);
            precise float ahi = a + max(gu, 0.0) + max(gv, 0.0);
            int k0 = ceil_div(alo, b) - 1 + T.base[w];
            int k1 = floor_div(ahi, b) + T.base[w];
            bool single = k0 == k1;  // unclipped: the one voxel is surely overlapped
#endif
            for (int k = max(k0, T.lo[w]); k <= min(k1, T.hi[w]); ++k) {
                if (single || (proj_test(Pu, ivec2(iv, k)) && proj_test(Pv, ivec2(k, iu))))
                    set_voxel(compose(u, v, w, iu, iv, k));
            }
        }
        if (++iu > T.hi[u]) { iu = T.lo[u]; ++iv; }
    }
}

void main() {
    uint g = gl_GlobalInvocationID.x;
    uint chunk = gl_WorkGroupID.y + gl_WorkGroupID.z * gl_NumWorkGroups.y;
#if SS_VARIANT == 2
    if (g >= ranges[2 * SS_BBOX_TYPE + 1]) return;
    uint t = sorted_tri[ranges[2 * SS_BBOX_TYPE] + g];
#elif SS_FIRST
    uint t = global_index_1d();
    chunk = 0u;
    if (t >= u_triangles) return;
#elif defined(SS_FIRST)
    if (g >= big_count) return;
    uint t = big_list[g];
    chunk += 1u;
#else
    uint t = g + u_tri_offset;
    if (t >= u_triangles || chunk >= tri_chunks[t]) return;
#endif
    Tri T = setup_triangle(t);
    if (outside_grid(T)) return;
#ifdef SS_ATTR_PASS
    attr_begin(t, T);  // the attribute passes revisit these pairs (attributes/pair.glsl)
#endif
#if SS_VARIANT == 2
    int type = SS_BBOX_TYPE;
#else
    int type = bbox_type(T);
#endif
    uint work = work_units(T, type);
#if defined(SS_FIRST) && SS_FIRST
#if SS_CRITERION == 0
    atomicAdd(stats[type], 1u);  // Table 1's case counts, as ss/classify.comp counts them
#endif
    uint chunks = chunks_of(work);
    if (chunks > 1u) {
        big_list[atomicAdd(big_count, 1u)] = t;
        atomicMax(big_max_chunks, chunks - 1u);
    }
#endif
    uint q0 = chunk * uint(SS_CHUNK);
    if (q0 >= work) return;
    uint q1 = min(work, q0 + uint(SS_CHUNK));
    writes_begin();
#if SS_CRITERION == 1
    if (degenerate(T)) voxelize_voxels(T, q0, q1, true); else voxelize_columns(T, q0, q1);
#elif SS_VARIANT == 0
    voxelize_voxels(T, q0, q1, true);
#else
    // one call of voxelize_voxels for both of its cases: a SIMD batch (a warp)
    // that holds both would run two calls' code one after the other
    bool deg = degenerate(T);
    if (deg || type == 0) voxelize_voxels(T, q0, q1, deg && type != 0);
    else if (type == 1) voxelize_2d(T, q0, q1);
    else voxelize_columns(T, q0, q1);
#endif
    writes_end();
}
