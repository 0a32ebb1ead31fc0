#version 450
// Schwarz & Seidel 2010 surface voxelization, one invocation per triangle.
//   SS_CRITERION  0: conservative (Sec. 3.1-3.2), 1: 6-separating (Sec. 3.4)
//   SS_VARIANT    0: simple (every voxel of the bounding box, full test)
//                 1: specialized (1D/2D/3D cases, dominant-axis columns)
//                 2: one bounding-box type SS_BBOX_TYPE of the sorted list
// The 6-separating criterion always uses the dominant-axis columns (Sec. 3.4).
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
#include "common/edge.glsl"
#include "ss/setup.glsl"
#include "ss/write.glsl"

layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 4) buffer Stats { uint stats[]; };  // triangles per case: 1D, 2D, 3D
#if SS_VARIANT == 2
layout(std430, binding = 5) readonly buffer SortedTris { uint sorted_tri[]; };
layout(std430, binding = 6) readonly buffer Ranges { uint ranges[]; };  // (start, count) per type
#endif
uniform uint u_triangles;

ivec3 compose(int u, int v, int w, int iu, int iv, int iw) {
    ivec3 p;
    p[u] = iu;
    p[v] = iv;
    p[w] = iw;
    return p;
}

// Every voxel of the bounding box through the full test.
void voxelize_simple(Tri T) {
    Proj Pz = make_proj(T, 0, 1, 2), Px = make_proj(T, 1, 2, 0), Py = make_proj(T, 2, 0, 1);
    for (int k = T.lo.z; k <= T.hi.z; ++k)
        for (int j = T.lo.y; j <= T.hi.y; ++j)
            for (int i = T.lo.x; i <= T.hi.x; ++i) {
                if (plane_test(T, vec3(i, j, k)) && proj_test(Pz, vec2(i, j)) &&
                    proj_test(Px, vec2(j, k)) && proj_test(Py, vec2(k, i)))
                    set_voxel(ivec3(i, j, k));
            }
}

// 1D bounding box: every voxel it touches is overlapped.
void voxelize_1d(Tri T) {
    for (int k = T.lo.z; k <= T.hi.z; ++k)
        for (int j = T.lo.y; j <= T.hi.y; ++j)
            for (int i = T.lo.x; i <= T.hi.x; ++i) set_voxel(ivec3(i, j, k));
}

// 2D bounding box, one voxel thick along c: a single 2D projection test.
void voxelize_2d(Tri T) {
    int c = T.ext.x == 1 ? 0 : (T.ext.y == 1 ? 1 : 2);
    int a = (c + 1) % 3, b = (c + 2) % 3;
    Proj P = make_proj(T, a, b, c);
    for (int ib = T.lo[b]; ib <= T.hi[b]; ++ib)
        for (int ia = T.lo[a]; ia <= T.hi[a]; ++ia)
            if (proj_test(P, vec2(ia, ib))) set_voxel(compose(a, b, c, ia, ib, T.lo[c]));
}

// 3D bounding box: columns along the dominant axis w of n; the plane gives
// the voxel range in each column, then only the two remaining 2D tests.
void voxelize_3d(Tri T) {
    int w = dominant_axis(T.n);
    int u = (w + 1) % 3, v = (w + 2) % 3;
    Proj Pw = make_proj(T, u, v, w), Pu = make_proj(T, v, w, u), Pv = make_proj(T, w, u, v);
    float du = -T.n[u] / T.n[w], dv = -T.n[v] / T.n[w];  // dw per unit step in u and v
    for (int iv = T.lo[v]; iv <= T.hi[v]; ++iv)
        for (int iu = T.lo[u]; iu <= T.hi[u]; ++iu) {
            if (!proj_test(Pw, vec2(iu, iv))) continue;
            // the plane's w range over the closed column cell [iu, iu+1] x [iv, iv+1]
            float base = T.v0[w] + du * (float(iu) - T.v0[u]) + dv * (float(iv) - T.v0[v]);
            float wmin = base + min(du, 0.0) + min(dv, 0.0);
            float wmax = base + max(du, 0.0) + max(dv, 0.0);
            int k0 = int(ceil(wmin)) - 1, k1 = int(floor(wmax));
            bool single = k0 == k1;  // unclipped: the one voxel is surely overlapped
            for (int k = max(k0, T.lo[w]); k <= min(k1, T.hi[w]); ++k) {
                if (single || (proj_test(Pu, vec2(iv, k)) && proj_test(Pv, vec2(k, iu))))
                    set_voxel(compose(u, v, w, iu, iv, k));
            }
        }
}

// 6-separating (Sec. 3.4): the column center projected along w onto the
// plane picks the voxel (two when it lands exactly on a voxel face).
void voxelize_6sep(Tri T) {
    int w = dominant_axis(T.n);
    int u = (w + 1) % 3, v = (w + 2) % 3;
    Proj Pw = make_proj(T, u, v, w), Pu = make_proj(T, v, w, u), Pv = make_proj(T, w, u, v);
    float du = -T.n[u] / T.n[w], dv = -T.n[v] / T.n[w];
    for (int iv = T.lo[v]; iv <= T.hi[v]; ++iv)
        for (int iu = T.lo[u]; iu <= T.hi[u]; ++iu) {
            if (!proj_test(Pw, vec2(iu, iv))) continue;
            float wc = T.v0[w] + du * (float(iu) + 0.5 - T.v0[u]) + dv * (float(iv) + 0.5 - T.v0[v]);
            float f = floor(wc);
            int k1 = int(f), k0 = wc == f ? k1 - 1 : k1;
            for (int k = max(k0, T.lo[w]); k <= min(k1, T.hi[w]); ++k) {
                if (proj_test(Pu, vec2(iv, k)) && proj_test(Pv, vec2(k, iu)))
                    set_voxel(compose(u, v, w, iu, iv, k));
            }
        }
}

void main() {
    uint g = global_index_1d();
#if SS_VARIANT == 2
    if (g >= ranges[2 * SS_BBOX_TYPE + 1]) return;
    uint t = sorted_tri[ranges[2 * SS_BBOX_TYPE] + g];
#else
    if (g >= u_triangles) return;
    uint t = g;
#endif
    Tri T = setup_triangle(t);
    if (outside_grid(T)) return;
    writes_begin();
    bool degenerate = all(equal(T.n, vec3(0.0)));  // zero area in float32: no dominant axis
#if SS_CRITERION == 1
    if (degenerate) voxelize_simple(T); else voxelize_6sep(T);
#elif SS_VARIANT == 0
    atomicAdd(stats[bbox_type(T)], 1u);
    voxelize_simple(T);
#else
    int type = bbox_type(T);
#if SS_VARIANT == 1
    atomicAdd(stats[type], 1u);
#else
    type = SS_BBOX_TYPE;
#endif
    if (type == 0) voxelize_1d(T);
    else if (type == 1) voxelize_2d(T);
    else if (degenerate) voxelize_simple(T);
    else voxelize_3d(T);
#endif
    writes_end();
}
