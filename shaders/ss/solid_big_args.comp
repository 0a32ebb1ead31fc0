#version 450
// ss-solid: indirect dispatch arguments of the second voxelization pass
// (ss/solid.comp with FIRST 0): x covers the listed triangles, y and z the
// chunks after the first of the triangle with the most
// (chunk - 1 = y + z * u_max_groups).
layout(local_size_x = 1) in;
layout(std430, binding = 4) readonly buffer Big { uint big_count; uint big_max_chunks; };
layout(std430, binding = 8) writeonly buffer Args { uint args[]; };
uniform uint u_local_size;
uniform uint u_max_groups;

void main() {
    uint y = min(big_max_chunks, u_max_groups);
    args[0] = (big_count + u_local_size - 1u) / u_local_size;
    args[1] = y;
    args[2] = y == 0u ? 0u : (big_max_chunks + y - 1u) / y;
}
