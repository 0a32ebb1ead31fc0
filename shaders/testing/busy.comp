#version 450
// Harness self-test: a dispatch long enough for timer queries to measure.
layout(local_size_x = 64) in;
layout(std430, binding = 0) writeonly buffer Out { float result[]; };
uniform int u_iterations;
void main() {
    float x = float(gl_GlobalInvocationID.x);
    for (int i = 0; i < u_iterations; ++i) x = sin(x) + 1.0;
    result[gl_GlobalInvocationID.x] = x;
}
