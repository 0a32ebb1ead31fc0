#version 450
// fixed_det of common/fixed.glsl, a * b - c * d from 64-bit integer products (its
// exact sign and its value rounded once to a double), on a list of quadruples:
// tests/test_eisemann.py compares both with exact integers.
#include "common/fixed.glsl"
layout(local_size_x = 64) in;
layout(std430, binding = 2) readonly buffer DetIn { ivec4 det_in[]; };
layout(std430, binding = 3) writeonly buffer DetOut { int det_out[]; };
layout(std430, binding = 4) writeonly buffer DetValue { double det_value[]; };
uniform uint u_n;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_n) return;
    ivec4 q = det_in[i];
    int sgn;
    det_value[i] = fixed_det(q.x, q.y, q.z, q.w, sgn);
    det_out[i] = sgn;
}
