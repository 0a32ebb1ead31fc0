#version 450
// Octree construction, bottom-up part (Sec. 5.2), over the N active nodes
// ActNodes_L of level L (sorted Morton codes):
//   PHASE 0: FLAG_L[i] = 1 when node i is the last of its level-(L+1) parent's
//            group (the next one has another parent, or there is none); its
//            exclusive scan is PARENTINDEX_L: node i's parent is active
//            level-(L+1) node PARENTINDEX_L[i], and the scan total is
//            their number N_{L+1};
//   PHASE 1: compaction, ActNodes_{L+1}[PARENTINDEX_L[i]] = ActNodes_L[i] >> 3
//            for the flagged nodes.
layout(local_size_x = 256) in;
#include "common/dispatch.glsl"
layout(std430, binding = 9) readonly buffer Act { uint act[]; };
layout(std430, binding = 10) buffer Flag { uint flag[]; };
#if PHASE == 1
layout(std430, binding = 11) writeonly buffer ActNext { uint act_next[]; };
layout(std430, binding = 5) readonly buffer ParentIndex { uint pidx[]; };
#endif
uniform uint u_count;
void main() {
    uint i = global_index_1d();
    if (i >= u_count) return;
#if PHASE == 0
    flag[i] = (i + 1u == u_count || (act[i + 1u] >> 3) != (act[i] >> 3)) ? 1u : 0u;
#else
    if (flag[i] != 0u) act_next[pidx[i]] = act[i] >> 3;
#endif
}
