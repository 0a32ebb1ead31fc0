#version 450
// Indirect dispatch arguments of the voxelization passes: x covers the
// triangles (u_groups_x for the direct variants; the count of each type for
// the sorted one, which also turns (start, end) into (start, count)), y and z
// the chunks of the triangle with the most (chunk = y + z * u_max_groups).
layout(local_size_x = 1) in;
layout(std430, binding = 4) readonly buffer Stats { uint stats[]; };
layout(std430, binding = 6) buffer Ranges { uint ranges[]; };
layout(std430, binding = 8) writeonly buffer Args { uint args[]; };
uniform uint u_groups_x;    // direct variants
uniform uint u_local_size;
uniform uint u_max_groups;
uniform bool u_sorted;

void chunk_dims(uint chunks, uint at) {
    uint y = min(chunks, u_max_groups);
    args[at + 1u] = y;
    args[at + 2u] = y == 0u ? 0u : (chunks + y - 1u) / y;
}

void main() {
    if (!u_sorted) {
        args[0] = u_groups_x;
        chunk_dims(stats[3], 0u);
        return;
    }
    for (uint type = 0u; type < 3u; ++type) {
        uint start = ranges[2u * type], end = ranges[2u * type + 1u];
        uint count = end > start ? end - start : 0u;
        ranges[2u * type + 1u] = count;
        args[3u * type] = (count + u_local_size - 1u) / u_local_size;
        chunk_dims(count == 0u ? 0u : stats[4u + type], 3u * type);
    }
}
