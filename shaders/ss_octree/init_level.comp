#version 450
// Octree construction: allocate-and-initialize the nodes of level u_level
// (Sec. 5.2), top level first.
//   Below the top, node n is child c = n % 8 of active level-(L+1) node
//   g = n / 8 (ActNodes_{L+1}[g]): Morton code 8 ActNodes_{L+1}[g] + c, the
//   parent pointer, and the parent's child pointer (written by child 0);
//   x-neighbour pointers between the two children of a pair with the same
//   parent (the pointers across parents follow in link_x.comp).
//   The top level holds all 4 x 4 x 4 nodes (index = Morton code), linked
//   along x to every neighbour.
// The level-(L+1) parent of ActNodes_{L+1}[g] sits at 8 PARENTINDEX_{L+1}[g]
// + (ActNodes_{L+1}[g] & 7) in its level, or at its Morton code on the top level.
layout(local_size_x = 256) in;
#include "common/dispatch.glsl"
#include "ss_octree/common.glsl"
layout(std430, binding = 11) readonly buffer ActUp { uint act_up[]; };       // ActNodes_{L+1}
layout(std430, binding = 5) readonly buffer ParentIndexUp { uint pidx_up[]; };  // PARENTINDEX_{L+1}
layout(std430, binding = 12) writeonly buffer Morton { uint morton[]; };
layout(std430, binding = 13) writeonly buffer Parent { uint parent[]; };
layout(std430, binding = 14) writeonly buffer XNext { uint x_next[]; };
layout(std430, binding = 15) writeonly buffer XPrev { uint x_prev[]; };
layout(std430, binding = 16) buffer Child { uint child[]; };
layout(std430, binding = 17) writeonly buffer Flags { uint flags[]; };
layout(std430, binding = 18) writeonly buffer Data { uint data[]; };
uniform uint u_level;
uniform uint u_top;
uniform uint u_count;  // nodes of this level
void main() {
    uint n = global_index_1d();
    if (n >= u_count) return;
    uint L = u_level;
    uint at = u_nbase[L] + n;
    uint c = n & 7u;
    if (L == u_top) {
        uvec3 p = oct_demorton(n);
        morton[at] = n;
        parent[at] = OCT_NONE;
        x_next[at] = p.x < 3u ? oct_morton(p + uvec3(1u, 0u, 0u)) : OCT_NONE;
        x_prev[at] = p.x > 0u ? oct_morton(p - uvec3(1u, 0u, 0u)) : OCT_NONE;
    } else {
        uint g = n >> 3;
        uint up = act_up[g];
        uint par = L + 1u == u_top ? up : 8u * pidx_up[g] + (up & 7u);
        morton[at] = 8u * up + c;
        parent[at] = par;
        x_next[at] = (c & 1u) == 0u ? n + 1u : OCT_NONE;
        x_prev[at] = (c & 1u) == 1u ? n - 1u : OCT_NONE;
        if (c == 0u) child[u_ubase[L + 1u] + par] = n;
    }
    if (L >= 1u) {
        child[u_ubase[L] + n] = OCT_NONE;
        flags[u_ubase[L] + n] = 0u;
    } else {
        data[2u * n] = 0u;
        data[2u * n + 1u] = 0u;
    }
}
