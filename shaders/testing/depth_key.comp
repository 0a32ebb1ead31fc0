#version 450
// depth_code, code_slot and depth_key of depth/key.glsl on a list of depths (voxel units):
// tests/test_depth.py compares them with their numpy model and checks what the
// z-buffers rely on (keys monotone in q, equal keys only within one slot).
#include "depth/key.glsl"
layout(local_size_x = 64) in;
layout(std430, binding = 2) readonly buffer Depths { double depths[]; };
layout(std430, binding = 3) writeonly buffer Keys { uvec2 keys[]; };  // (key bits, slot)
uniform uint u_n;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_n) return;
    double q = depths[i];
    uint code = depth_code(q);
    keys[i] = uvec2(floatBitsToUint(depth_key(code)), code_slot(code));
}
