#version 450
// gwn-solid, pass 3: F at the voxels of a row segment from the cluster tree,
// then w = C + F and the bits, where the expansion's error bound cannot
// change them.
//
// One invocation per row segment of SEG = 4 GWN_SEGV voxels (a whole number
// of them per 32-bit word).  It walks the boundary chain's cluster tree
// (glvox/methods/gwn_tree.py) from the roots of its chunk: a node far from
// the whole segment adds its expansion minus its chord's strip, and its
// error bound; a near leaf adds its edges' exact strips; a near inner node
// is replaced by its children.  Far: at distance >= u_beta * r from the
// node's center c, and the ball (c, r) out of reach of the ray towards -x
// from every voxel (behind it, or beside it), so no strip of the node's
// closed polygons passes there.  The walk decides by blocks of 4 voxels:
// each stack entry carries the blocks still near its parent.
//
// A dispatch handles the roots u_roots.x .. u_roots.y - 1 (one chunk of the
// tree, so that an invocation stays within llvmpipe's loop budget:
// glvox.methods.gwn.field.plan_chunks).  With several chunks the sums so far live
// in Acc (F, bound).  The last chunk decides: a voxel whose
// |C + F - threshold| exceeds the bound plus u_margin is decided, its bit
// set when w >= threshold; a block of 4 voxels with an undecided one is
// left to gwn/refine.comp, which redoes it exactly (the segment is listed
// with the mask of such blocks).
//
// With BRICKS 1 the invocations take the segments gwn/todo.comp listed (an
// indirect dispatch), and only their blocks gwn/rows.comp left (the rest are
// decided and set).
#include "common/voxel_space.glsl"
#include "gwn/layout.glsl"
#include "gwn/strip.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 1) readonly buffer VoxVerts { float vox[]; };
layout(std430, binding = 3) buffer Cells { ivec4 cells[]; };
layout(std430, binding = 4) buffer Acc { vec4 acc_f[]; };  // F, bound: 2 vec4 per 4 cells
layout(std430, binding = 5) readonly buffer Edges { uvec2 edges[]; };
layout(std430, binding = 6) readonly buffer Nodes { vec4 nodes[]; };
layout(std430, binding = 9) readonly buffer Links { ivec4 links[]; };
layout(std430, binding = 10) readonly buffer Roots { int roots[]; };
layout(std430, binding = 7) buffer Bits { uint bits[]; };
layout(std430, binding = 8) buffer Count { uint voxel_count; uint refine_count; uint todo_count; };
layout(std430, binding = 11) buffer Refine { uint refine_list[]; };
#if BRICKS
layout(std430, binding = 2) readonly buffer Todo { uint todo[]; };  // segment id, its blocks left
#endif
uniform float u_threshold;
uniform float u_beta;
uniform float u_margin;
uniform ivec2 u_roots;
uniform bool u_first, u_last;
// rows j0 .. j0 + nj - 1, slices k0 .. k0 + nk - 1 (inside the slab),
// segments s0 .. s0 + ns - 1: the part of the grid evaluated
uniform ivec4 u_rows;   // j0, nj, k0, nk
uniform ivec2 u_segs;   // s0, ns
#include "gwn/segment.glsl"
#include "gwn/winding2d.glsl"

// the walk's stack: a binary tree's depth first walk holds at most one node
// per level plus one (glvox.methods.gwn.field.TREE_STACK checks the depth)
const int GWN_STACK = 64;

// The blocks of 4 voxels among `blocks` (bit i: voxels 4 i .. 4 i + 3 of the
// segment) at distance >= u_beta r from the node (c, r) = cr, split by where
// the ball lies: out of reach of their rays towards -x (behind the blocks,
// or beside the row), or `ahead`: wholly crossed by those rays (the row
// passes through the ball's (y, z) disk and the block starts past c_x + r).
uint far_blocks(vec4 cr, vec2 c, float x0, uint blocks, out uint ahead) {
    vec2 d = cr.yz - c;
    float s = dot(d, d);
    float reach = u_beta * cr.w;
    bool beside = s > cr.w * cr.w;
    uint far = 0u;
    ahead = 0u;
    for (int i = 0; i < GWN_SEGV; ++i) {
        float b0 = x0 + float(4 * i) + 0.5, b1 = b0 + 3.0;
        float dx = max(max(b0 - cr.x, cr.x - b1), 0.0);
        if (dx * dx + s < reach * reach) continue;
        if (beside || b1 < cr.x - cr.w) far |= 1u << i;
        else if (b0 > cr.x + cr.w) ahead |= 1u << i;
    }
    ahead &= blocks;
    return far & blocks;
}

// Adds `value` to every voxel of the blocks in `blocks`.
void add_blocks(float value, uint blocks) {
    for (int i = 0; i < GWN_SEGV; ++i)
        if ((blocks & (1u << i)) != 0u) seg_f[i] += vec4(value);
}

void main() {
    uint id = global_index_1d();
    Segment S;
#if BRICKS
    if (id >= todo_count) return;
    uint mask = todo[2u * id + 1u];
    id = todo[2u * id];
#endif
    if (!segment_of(id, S)) return;
#if !BRICKS
    uint mask = ~0u;
#endif
    for (int i = 0; i < GWN_SEGV; ++i) { seg_f[i] = vec4(0.0); seg_bnd[i] = vec4(0.0); }
    // the segment's blocks inside the grid (and left by gwn/rows.comp)
    uint all_blocks = ((1u << uint(min(GWN_SEGV, (u_dims.x - S.seg * SEG + 3) / 4))) - 1u) & mask;
    ivec2 stack[GWN_STACK];
    for (int r = u_roots.x; r < u_roots.y; ++r) {
        int sp = 0;
        stack[sp++] = ivec2(roots[r], all_blocks);
        while (sp > 0) {
            ivec2 top = stack[--sp];
            int n = top.x;
            uint blocks = uint(top.y);
            vec4 cr = nodes[GWN_NODE_VEC4 * n];
            uint ahead;
            uint far = far_blocks(cr, S.c, S.x0, blocks, ahead);
            ivec4 lk = links[2 * n];
            ivec4 chord = links[2 * n + 1];
            // blocks ahead of the ball: their rays cross the whole fan P, C_P = -(the
            // winding number of the node's polygons around the row), so the node
            // adds w_P + that number minus the chord's strip.  Only when no block
            // is left near, so that an edge is counted once per walk (the loop
            // budget's charge, plan_chunks), and not on a row through an edge.
            if (ahead != 0u && (far | ahead) == blocks) {
                bool tie = false;
                int wn = node_winding(lk, chord, S.c, tie);
                if (tie) ahead = 0u;
                else add_blocks(2.0 * GWN_PI * float(wn), ahead);
            } else {
                ahead = 0u;
            }
            far |= ahead;
            if (far != 0u) {
                vec4 rec[7];
                for (int q = 0; q < 7; ++q) rec[q] = nodes[GWN_NODE_VEC4 * n + q];
                add_far(rec, S.c, S.x0, far);
                if (chord.x >= 0) add_strip(vertex(uint(chord.x)), vertex(uint(chord.y)), S.c, S.x0, -1.0, far);
            }
            uint near = blocks & ~far;
            if (near == 0u) continue;
            if (lk.z < 0) {
                for (int e = lk.x; e < lk.x + lk.y; ++e) {
                    uvec2 ed = edges[e];
                    add_strip(vertex(ed.x), vertex(ed.y), S.c, S.x0, 1.0, near);
                }
            } else {
                stack[sp++] = ivec2(lk.w, near);
                stack[sp++] = ivec2(lk.z, near);
            }
        }
    }
    uint base = S.cell / 4u;
    if (!u_first) {
        for (int i = 0; i < GWN_SEGV; ++i) {
            seg_f[i] += acc_f[2u * (base + uint(i))];
            seg_bnd[i] += acc_f[2u * (base + uint(i)) + 1u];
        }
    }
    if (!u_last) {
        for (int i = 0; i < GWN_SEGV; ++i) {
            acc_f[2u * (base + uint(i))] = seg_f[i];
            acc_f[2u * (base + uint(i)) + 1u] = seg_bnd[i];
        }
        return;
    }
    uint undecided = 0u;
    vec4 w[GWN_SEGV];
    for (int i = 0; i < GWN_SEGV; ++i) {
        w[i] = vec4(cells[base + uint(i)]) + seg_f[i] * (0.5 / GWN_PI);
        bvec4 near = lessThanEqual(abs(w[i] - u_threshold), seg_bnd[i] + u_margin);
        if (any(near)) undecided |= 1u << i;
    }
    undecided &= all_blocks;
    if (undecided != 0u) {
        uint slot = atomicAdd(refine_count, 1u);
        refine_list[2u * slot] = id;
        refine_list[2u * slot + 1u] = undecided;
    }
    finish_segment(S, w, all_blocks & ~undecided);
}
