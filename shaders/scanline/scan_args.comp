#version 450
// The indirect dispatch of scanline/voxelize.comp's scan (FROM_LIST) over the
// triangles its table pass listed: groups of u_local_size, more than
// u_max_groups groups split along y (as glvox.gpu.dispatch.dispatch_1d does).
// One invocation.
layout(local_size_x = 1) in;
layout(std430, binding = 6) buffer Scan { uint scan_n; uint scan_args[3]; };
uniform uint u_local_size;
uniform uint u_max_groups;

void main() {
    uint groups = (scan_n + u_local_size - 1u) / u_local_size;
    uint x = min(groups, u_max_groups);
    scan_args[0] = x;
    scan_args[1] = x == 0u ? 0u : (groups + x - 1u) / x;
    scan_args[2] = 1u;
}
