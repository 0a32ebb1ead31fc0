#version 450
// One fragment per (triangle, center) pair, pair = y * u_width + x:
// testing/tie_probe.glsl with PROBE_EIS 1 in a fragment shader, where eisemann-solid
// decides its columns.
#define EIS_AXIS 2
#define PROBE_EIS 1
#include "eisemann/column.glsl"
#include "testing/tie_probe.glsl"
uniform uint u_width;
layout(location = 0) out uvec4 o_unused;
void main() {
    uint p = uint(gl_FragCoord.y) * u_width + uint(gl_FragCoord.x);
    if (p < u_pairs) probe_pair(p);
    o_unused = uvec4(0u);
}
