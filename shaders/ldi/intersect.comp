#version 450
// The intersecting volume of Leung & Wang 2013 Sec. V-A: masks of the overlap of two
// solids A and B from their own (T1, T2) on the same rays and cells.
//   T1 = T1_A & T1_B (the AND of the two solid voxelizations, the paper's T_res);
//   T2 = cells where both solids reach (each is inside at one of the cell's faces or has a
//        thin part in it: T2_X | T1_X(k) | T1_X(k - 1)) while the overlap is outside at both
//        faces.  The paper uses T_res alone, which drops an overlap thinner than a cell;
//        with this T2 such a cell becomes an ELV, and the depth pass (drawing both meshes)
//        bounds it by the nearest and farthest crossing of either mesh in the cell, which
//        are the overlap's end points or beyond them: the result stays conservative.
// One invocation per word.
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"

layout(std430, binding = 0) writeonly buffer OutT1 { uint out_t1[]; };
layout(std430, binding = 1) writeonly buffer OutT2 { uint out_t2[]; };
layout(std430, binding = 8) readonly buffer A1 { uint a1[]; };
layout(std430, binding = 9) readonly buffer A2 { uint a2[]; };
layout(std430, binding = 10) readonly buffer B1 { uint b1[]; };
layout(std430, binding = 11) readonly buffer B2 { uint b2[]; };

uniform int u_words;
uniform int u_cells;
uniform uint u_invocations;

// bit k: x(k - 1), carrying the previous word's top bit
uint below(uint x, uint x_prev) { return (x << 1) | (x_prev >> 31); }

void main() {
    uint i = global_index_1d();
    if (i >= u_invocations) return;
    int w = int(i % uint(u_words));
    uint prev = w > 0 ? i - 1u : i;
    uint ap = w > 0 ? a1[prev] : 0u;
    uint bp = w > 0 ? b1[prev] : 0u;
    uint t1 = a1[i] & b1[i];
    uint reach_a = a2[i] | a1[i] | below(a1[i], ap);
    uint reach_b = b2[i] | b1[i] | below(b1[i], bp);
    uint t2 = reach_a & reach_b & ~t1 & ~below(t1, ap & bp);
    int valid = u_cells - 32 * w;
    if (valid < 32) t2 &= (1u << uint(valid)) - 1u;
    out_t1[i] = t1;
    out_t2[i] = t2;
}
