#version 450
// glvox sdf, the band pass: the unsigned distance from every voxel center
// within u_radius voxels of a triangle to that triangle, minimum over the
// triangles by atomicMin (glvox/methods/sdf/band.py).
//
// One invocation per (triangle, column): a triangle's box dilated by the
// radius is walked in columns along the axis of its normal's largest
// component (|n_d| >= 1/sqrt(3)), and each column only where it crosses the
// slab |n . (p - a)| <= radius + margin around the triangle's plane (every
// point within the radius of the triangle lies in that slab; the margin,
// set on the CPU, covers how far the vertices stray from the float plane).
// So the work per triangle is its area plus its dilation, not its box, and
// one invocation loops at most 2 sqrt(3) radius + 2 times, far below
// llvmpipe's loop budget.  Column g belongs to the triangle t with
// off[t] <= g < off[t + 1] (a binary search over the prefix sums).
//
// Exactness: the voxel center minus vertex a, and the closest point
// (attributes/closest.glsl, Ericson's Voronoi regions), are computed in
// double, so the distance is exact to float64 before it is rounded once to
// float32 (about 6e-8 relative); it is stored as the bits of a non-negative
// float, whose order as uint is its order as float, hence atomicMin.
#extension GL_ARB_gpu_shader_fp64 : require
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
#include "attributes/closest.glsl"
#include "sdf/closest.glsl"

layout(std430, binding = 0) readonly buffer Geo { double geo[]; };   // a, ab, ac: 9 per triangle (voxel units)
layout(std430, binding = 1) readonly buffer Plane { vec4 plane[]; }; // unit normal, slab half-width
layout(std430, binding = 2) readonly buffer Box { ivec4 box[]; };    // lo.xyz + axis, hi.xyz + 0
layout(std430, binding = 3) readonly buffer Items { uvec2 items[]; }; // triangle, first column
layout(std430, binding = 4) buffer Dist { uint dist[]; };            // float bits, C order (i, j, k)

uniform ivec3 u_dims;
uniform uint u_first;   // first item of this dispatch
uniform uint u_count;   // items of this dispatch
uniform int u_chunk;    // columns per item
uniform float u_radius; // voxels

void main() {
    uint local = global_index_1d();
    if (local >= u_count) return;
    uvec2 item = items[u_first + local];
    int t = int(item.x);
    ivec4 b0 = box[2 * t], b1 = box[2 * t + 1];
    int d = b0.w, u = (d + 1) % 3, v = (d + 2) % 3;
    int nu = b1[u] - b0[u] + 1, columns = nu * (b1[v] - b0[v] + 1);
    dvec3 a = dvec3(geo[9 * t], geo[9 * t + 1], geo[9 * t + 2]);
    dvec3 ab = dvec3(geo[9 * t + 3], geo[9 * t + 4], geo[9 * t + 5]);
    dvec3 ac = dvec3(geo[9 * t + 6], geo[9 * t + 7], geo[9 * t + 8]);
    vec4 pl = plane[t];
    vec3 abf = vec3(ab), acf = vec3(ac), n = pl.xyz;
    float size = length(abf) + length(acf);
    // the box's lowest voxel center relative to a, in float (the slab test has a margin)
    vec3 base = vec3(dvec3(b0.xyz) + 0.5lf - a);
    int c_end = min(int(item.y) + u_chunk, columns);
    for (int c = int(item.y); c < c_end; ++c) {
        ivec3 cell;
        cell[u] = b0[u] + c % nu;
        cell[v] = b0[v] + c / nu;
        // the slab along the column: n_d (p_d - a_d) + s in [-w, w]
        float s = n[u] * (base[u] + float(cell[u] - b0[u])) + n[v] * (base[v] + float(cell[v] - b0[v]));
        float e0 = (-pl.w - s) / n[d], e1 = (pl.w - s) / n[d];
        float lo_d = min(e0, e1) - base[d], hi_d = max(e0, e1) - base[d];  // voxels from b0[d]
        int k0 = b0[d] + max(0, int(ceil(lo_d))), k1 = min(b1[d], b0[d] + int(floor(hi_d)));
        for (int k = k0; k <= k1; ++k) {
            cell[d] = k;
            dvec3 p = dvec3(cell) + 0.5lf - a;
            vec3 pf = vec3(p);
            uint idx = (uint(cell.x) * uint(u_dims.y) + uint(cell.y)) * uint(u_dims.z) + uint(cell.z);
            // skip a triangle that cannot be the nearest: a lower bound (the float distance
            // less a slack far above its rounding) beyond the value stored so far.  The
            // stored value only decreases, so a stale read only skips less.
            float bound = min(uintBitsToFloat(dist[idx]), u_radius);
            float slack = 1e-4 * (1.0 + length(pf) + size);
            if (abs(dot(n, pf)) - slack > bound) continue;
            if (closest_distance_f(pf, abf, acf) - slack > bound) continue;
            dvec3 q = closest_bary(p, dvec3(0.0lf), ab, ac);
            float dist_v = float(bary_distance(p, dvec3(0.0lf), ab, ac, q));
            if (dist_v <= u_radius) atomicMin(dist[idx], floatBitsToUint(dist_v));
        }
    }
}
