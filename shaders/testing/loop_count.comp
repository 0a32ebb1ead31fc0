#version 450
// Counts the iterations of a triple loop of u_n^3 (the driver-limit probe of tests/test_context.py).
layout(local_size_x = 1) in;
layout(std430, binding = 0) writeonly buffer Out { uint count; };
uniform int u_n;
void main() {
    uint c = 0u;
    for (int k = 0; k < u_n; ++k)
        for (int j = 0; j < u_n; ++j)
            for (int i = 0; i < u_n; ++i) c++;
    count = c;
}
