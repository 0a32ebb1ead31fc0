#version 450
// Harness self-test: the helpers of common/bits.glsl on given inputs.
#include "common/bits.glsl"
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Lo { uint lo[]; };
layout(std430, binding = 1) readonly buffer Hi { uint hi[]; };
layout(std430, binding = 2) writeonly buffer Out { uvec4 result[]; };
uniform uint u_count;
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    result[i] = uvec4(mask_from(lo[i]), mask_upto(hi[i]), mask_range(lo[i], hi[i]),
                      uint(count_below(hi[i] * 2654435761u, lo[i])));
}
