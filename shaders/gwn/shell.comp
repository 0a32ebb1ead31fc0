#version 450
// gwn-solid with shell=true: the conservative surface (ss-conservative's
// passes, in their own buffer) ORed into the solid's bits, words u_first_word
// .. u_first_word + u_words - 1 (the surface's z slices).  The bits the surface
// adds are added to the solid's voxel_count, once per invocation (one word
// each), so the count stays the union's.  Bits past nx are zero in both.
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 0) readonly buffer Surface { uint surface[]; };
layout(std430, binding = 7) buffer Bits { uint bits[]; };
layout(std430, binding = 8) buffer Count { uint voxel_count; };
uniform uint u_first_word;
uniform uint u_words;

void main() {
    uint i = global_index_1d();
    if (i >= u_words) return;
    uint w = u_first_word + i;
    uint s = surface[w];
    if (s == 0u) return;
    uint b = bits[w];
    uint added = s & ~b;
    if (added == 0u) return;
    bits[w] = b | added;
    atomicAdd(voxel_count, uint(bitCount(added)));
}
