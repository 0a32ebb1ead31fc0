#version 450
// Hierarchical inside/outside propagation (Schwarz & Seidel 2010, Sec. 5.4),
// one pass per PHASE and level u_level:
//   PHASE 0 (level 0): one invocation per node; a head of an x-linked string
//     of level-0 nodes (no -x neighbour) walks the string in +x, and every SG
//     column whose voxel at local x = 3 is set flips the whole column of the
//     next node.  Afterwards each column's bits are the parity of the
//     crossings since the string's head.
//   PHASE 1 (level L >= 1): a node with children whose +x-side child (1, 0, 0)
//     ends a string of level-(L-1) nodes takes that child's state as its flip
//     flag: the bit at x = 3 of SG column (0, 0) for level-0 children, the
//     child's flip flag above.  Every column (or child) on that face agrees
//     where the next nodes are uniform; the min-corner one is inside the grid
//     whenever the node meets it (columns outside the grid carry no crossings).
//   PHASE 2 (level L >= 1): heads walk their string; a node with its flip flag
//     set flips both the flip and the inside flag of its +x neighbour.
//   PHASE 3 (level L >= 1, top level first): a node with children and its
//     inside flag set flips its children's inside flags, or all their SG
//     voxels on level 1.
// String walks are bounded by the level's extent in nodes along x (at most
// 1024 steps), far below LOOP_BUDGET.
layout(local_size_x = 256) in;
#include "common/dispatch.glsl"
#include "ss_octree/common.glsl"
layout(std430, binding = 14) readonly buffer XNext { uint x_next[]; };
layout(std430, binding = 15) readonly buffer XPrev { uint x_prev[]; };
layout(std430, binding = 16) readonly buffer Child { uint child[]; };
layout(std430, binding = 17) buffer Flags { uint flags[]; };
layout(std430, binding = 18) buffer Data { uint data[]; };
uniform uint u_level;
uniform uint u_count;
uniform uint u_max_steps;  // nodes along x at this level

// All four bits of every SG column whose bit at local x = 3 is set.
uint columns_with_x3(uint w) { return ((w >> 3) & 0x11111111u) * 0xFu; }

void main() {
    uint n = global_index_1d();
    if (n >= u_count) return;
    uint L = u_level;
    uint nb = u_nbase[L];
#if PHASE == 0
    if ((n & 1u) != 0u || x_prev[nb + n] != OCT_NONE) return;
    uint cur = n;
    for (uint s = 0u; s < u_max_steps; ++s) {
        uint nxt = x_next[nb + cur];
        if (nxt == OCT_NONE) break;
        data[2u * nxt] ^= columns_with_x3(data[2u * cur]);
        data[2u * nxt + 1u] ^= columns_with_x3(data[2u * cur + 1u]);
        cur = nxt;
    }
#elif PHASE == 1
    uint ch = child[u_ubase[L] + n];
    if (ch == OCT_NONE) return;
    uint c1 = ch + 1u;  // child (1, 0, 0)
    if (x_next[u_nbase[L - 1u] + c1] != OCT_NONE) return;
    uint flip = L == 1u ? (data[2u * c1] >> 3) & 1u : (flags[u_ubase[L - 1u] + c1] >> 1) & 1u;
    flags[u_ubase[L] + n] = flip << 1;
#elif PHASE == 2
    uint ub = u_ubase[L];
    if (x_prev[nb + n] != OCT_NONE) return;
    uint cur = n;
    for (uint s = 0u; s < u_max_steps; ++s) {
        uint nxt = x_next[nb + cur];
        if (nxt == OCT_NONE) break;
        if ((flags[ub + cur] & 2u) != 0u) flags[ub + nxt] ^= 3u;
        cur = nxt;
    }
#else
    uint ub = u_ubase[L];
    uint ch = child[ub + n];
    if (ch == OCT_NONE || (flags[ub + n] & 1u) == 0u) return;
    for (uint c = 0u; c < 8u; ++c) {
        if (L == 1u) {
            data[2u * (ch + c)] ^= 0xFFFFFFFFu;
            data[2u * (ch + c) + 1u] ^= 0xFFFFFFFFu;
        } else {
            flags[u_ubase[L - 1u] + ch + c] ^= 1u;
        }
    }
#endif
}
