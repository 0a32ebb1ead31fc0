#version 450
// One invocation per (triangle, center) pair: testing/tie_probe.glsl in a compute shader.
// (Both families include common/fixed.glsl; an include is expanded once, whatever #if
// surrounds it, so it comes first, outside the branches.)
#include "common/fixed.glsl"
#if PROBE_EIS
#define EIS_AXIS 2
#include "eisemann/column.glsl"
#else
#include "ss/solid.glsl"
#endif
#include "testing/tie_probe.glsl"
layout(local_size_x = 64) in;
void main() {
    uint p = gl_GlobalInvocationID.x;
    if (p < u_pairs) probe_pair(p);
}
