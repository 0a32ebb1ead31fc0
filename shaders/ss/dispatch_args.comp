#version 450
// Sorted variant: turn (start, end) per type into (start, count) and write the
// indirect dispatch arguments of the three per-type passes (x split along y
// beyond the work group count limit, as dispatch_1d does).
layout(local_size_x = 1) in;
layout(std430, binding = 1) buffer Ranges { uint ranges[]; };
layout(std430, binding = 2) writeonly buffer Args { uint args[]; };  // 3 x (x, y, z)
uniform uint u_local_size;
uniform uint u_max_groups;
void main() {
    for (uint type = 0u; type < 3u; ++type) {
        uint start = ranges[2u * type], end = ranges[2u * type + 1u];
        uint count = end > start ? end - start : 0u;
        ranges[2u * type + 1u] = count;
        uint groups = (count + u_local_size - 1u) / u_local_size;
        uint gx = min(groups, u_max_groups);
        args[3u * type] = gx;
        args[3u * type + 1u] = gx == 0u ? 1u : (groups + gx - 1u) / gx;
        args[3u * type + 2u] = 1u;
    }
}
