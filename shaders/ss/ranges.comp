#version 450
// Sorted variant, after the sort: where each bounding-box type starts and
// ends in the sorted key list (ends[type] = one past its last element): the
// type is the key's top two bits (ss/classify.comp).
layout(local_size_x = 256) in;
#include "common/dispatch.glsl"
layout(std430, binding = 7) readonly buffer Keys { uint keys[]; };
layout(std430, binding = 6) buffer Ranges { uint ranges[]; };  // (start, end) per type 0..3
uniform uint u_count;
void main() {
    uint i = global_index_1d();
    if (i >= u_count) return;
    uint type = keys[i] >> (SS_WORK_BITS + 2);
    if (i == 0u || (keys[i - 1u] >> (SS_WORK_BITS + 2)) != type) ranges[2u * type] = i;
    if (i + 1u == u_count || (keys[i + 1u] >> (SS_WORK_BITS + 2)) != type) ranges[2u * type + 1u] = i + 1u;
}
