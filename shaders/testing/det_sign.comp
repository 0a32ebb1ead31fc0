#version 450
// eis_det_sign of eisemann/column.glsl, the exact sign of a * b - c * d from 64-bit
// integer products, on a list of quadruples: tests/test_eisemann.py compares it with
// exact integers.
#define EIS_AXIS 2
#include "eisemann/column.glsl"
layout(local_size_x = 64) in;
layout(std430, binding = 2) readonly buffer DetIn { ivec4 det_in[]; };
layout(std430, binding = 3) writeonly buffer DetOut { int det_out[]; };
uniform uint u_n;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_n) return;
    ivec4 q = det_in[i];
    det_out[i] = eis_det_sign(q.x, q.y, q.z, q.w);
}
