#version 450
// Active level-1 nodes, pass 1: chunks of OCT_CHUNK work units per item
// (triangles, then wall halves; see ss_octree/activate.glsl).
#include "common/edge.glsl"
#include "common/voxel_space.glsl"
#include "ss/solid.glsl"
#define SOLID_UNIT 1
#include "ss/solid_input.glsl"
#include "ss_octree/common.glsl"
#include "ss_octree/activate.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 5) writeonly buffer Chunks { uint chunks[]; };
void main() {
    uint item = global_index_1d();
    if (item >= u_triangles + 2u * u_walls) return;
    uint units = activation_units(activation_setup(item));
    chunks[item] = (units + uint(OCT_CHUNK) - 1u) / uint(OCT_CHUNK);
}
