#version 450
// The indirect dispatch of scanline/voxelize.comp's scan (FROM_LIST) over the
// triangles its table pass listed. One invocation.
layout(local_size_x = 1) in;
#include "common/dispatch.glsl"
layout(std430, binding = 6) buffer Scan { uint scan_n; uint scan_args[3]; };
uniform uint u_local_size;
uniform uint u_max_groups;

void main() {
    uvec3 a = dispatch_args_1d(scan_n, u_local_size, u_max_groups);
    scan_args[0] = a.x;
    scan_args[1] = a.y;
    scan_args[2] = a.z;
}
