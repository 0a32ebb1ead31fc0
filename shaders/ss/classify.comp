#version 450
// Sorted variant, pass 1 (Sec. 3.2 "Implementation"): the case of each
// triangle and its work, as a sort key: type (2 bits) | axis (2 bits) | work (26 bits).
// Type 3 marks triangles outside the grid; they sort last and are never processed.
#define SS_CRITERION 0
#include "common/voxel_space.glsl"
#include "common/edge.glsl"
#include "ss/setup.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 3) writeonly buffer Keys { uint keys[]; };
layout(std430, binding = 4) buffer Stats { uint stats[]; };
layout(std430, binding = 5) writeonly buffer Values { uint values[]; };
uniform uint u_triangles;
void main() {
    uint t = global_index_1d();
    if (t >= u_triangles) return;
    Tri T = setup_triangle(t);
    uint key;
    if (outside_grid(T)) {
        key = 3u << 28;
    } else {
        int type = bbox_type(T);
        ivec3 size = T.hi - T.lo + 1;
        int axis = type == 2 ? dominant_axis(T.n) : (T.ext.x == 1 ? 0 : (T.ext.y == 1 ? 1 : 2));
        // columns for 3D cases, voxels otherwise
        int work = type == 2 ? size[(axis + 1) % 3] * size[(axis + 2) % 3] : size.x * size.y * size.z;
        key = (uint(type) << 28) | (uint(axis) << 26) | uint(min(work, (1 << 26) - 1));
        atomicAdd(stats[type], 1u);
    }
    keys[t] = key;
    values[t] = t;
}
