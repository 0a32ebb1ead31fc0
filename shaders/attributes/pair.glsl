// The attribute passes' voxel hook, replacing ss/write.glsl in ss/surface.comp
// (SS_ATTR_PASS 1 or 2, SS_CRITERION 0): the conservative (triangle, voxel)
// pairs, restricted to the voxels set in the method's grid, with the
// distance from the voxel center to the triangle's closest point.
//   pass 1: atomicMin of the distance as fixed point (2^-31 voxel steps; a touching
//           triangle is at most sqrt(3)/2 voxel away, so it fits in 31 bits).  Fixed
//           point, not float bits: an exact tie (a point on an edge two triangles
//           share, computed from each) may come out as 0 and 1e-17, which float bits
//           would tell apart and the rounding to 2^-31 does not.
//   pass 2: atomicMin of the triangle index among pairs at that minimum, and the
//           voxel's coordinates for the slot (every such pair writes the same)
// A voxel's slot is its rank among the set voxels in the grid's word order:
// word_offset (an exclusive scan of the words' popcounts) plus the set bits
// below it in its word.
#include "attributes/closest.glsl"

layout(std430, binding = 3) readonly buffer Grid { uint grid[]; };
layout(std430, binding = 9) readonly buffer Offsets { uint word_offset[]; };
layout(std430, binding = 10) buffer BestDist { uint best_dist[]; };
layout(std430, binding = 11) buffer BestTri { uint best_tri[]; };
layout(std430, binding = 12) writeonly buffer SlotVoxel { uvec2 slot_voxel[]; };  // (i | j << 16, k)

uint attr_t;
ivec3 attr_base;
dvec3 attr_a, attr_b, attr_c;  // relative to attr_base: exact from the float32 vertices

void attr_begin(uint t, Tri T) {
    attr_t = t;
    attr_base = T.base;
    attr_a = dvec3(T.v0);
    attr_b = dvec3(T.v1);
    attr_c = dvec3(T.v2);
}

void writes_begin() {}
void writes_end() {}

void set_voxel(ivec3 v) {
    uint w = word_index(v);
    uint word = grid[w];
    uint b = bit_of(uint(v.x));
    if ((word & b) == 0u) return;
    uint slot = word_offset[w] + uint(bitCount(word & (b - 1u)));
    dvec3 p = dvec3(v - attr_base) + 0.5lf;
    dvec3 q = closest_bary(p, attr_a, attr_b, attr_c);
    uint key = uint(min(bary_distance(p, attr_a, attr_b, attr_c, q), 1.0lf) * 2147483648.0lf + 0.5lf);
#if SS_ATTR_PASS == 1
    atomicMin(best_dist[slot], key);
#else
    if (key == best_dist[slot]) {
        atomicMin(best_tri[slot], attr_t);
        slot_voxel[slot] = uvec2(uint(v.x) | (uint(v.y) << 16), uint(v.z));
    }
#endif
}
