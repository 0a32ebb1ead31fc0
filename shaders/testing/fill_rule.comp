#version 450
// Harness self-test of common/edge.glsl: how many triangles of a 2D mesh own
// each sample point under the top-left fill rule (one invocation per point).
#include "common/edge.glsl"
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Tris { vec2 tri[]; };   // 3 per triangle
layout(std430, binding = 1) readonly buffer Points { vec2 pts[]; };
layout(std430, binding = 2) writeonly buffer Count { uint owners[]; };
uniform uint u_points;
uniform uint u_tris;
void main() {
    uint p = gl_GlobalInvocationID.x;
    if (p >= u_points) return;
    uint c = 0u;
    for (uint t = 0u; t < u_tris; ++t) {
        vec2 v0 = tri[3u * t], v1 = tri[3u * t + 1u], v2 = tri[3u * t + 2u];
        vec2 e0 = v1 - v0, e1 = v2 - v0;
        float orient = (e0.x * e1.y - e0.y * e1.x) >= 0.0 ? 1.0 : -1.0;
        bool inside = true;
        vec2 vs[3] = vec2[3](v0, v1, v2);
        for (int i = 0; i < 3; ++i) {
            vec2 n = edge_normal(vs[i], vs[(i + 1) % 3], orient);
            inside = inside && edge_inside(dot(n, pts[p] - vs[i]), edge_is_top_left(n));
        }
        c += inside ? 1u : 0u;
    }
    owners[p] = c;
}
