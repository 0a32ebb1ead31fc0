#version 450
// Coverage factors (Schwarz & Seidel 2010, Sec. 5.5), bottom-up, one pass
// per level: the number of set voxels in each node's block, counting only
// voxels inside the grid (blocks on the grid's +x, +y, +z faces reach
// beyond it).  Level 0: the set bits of the sub-grid; above: the sum over the
// children, or for a node without children its inside flag times its voxels
// in the grid.  Coverage = count / (4 * 2^L)^3: the paper's average of the
// children's factors, kept as an exact integer (at most 2^30 on the top
// level of a 4096^3 grid).
layout(local_size_x = 256) in;
#include "common/dispatch.glsl"
#include "ss_octree/common.glsl"
layout(std430, binding = 12) readonly buffer Morton { uint morton[]; };
layout(std430, binding = 16) readonly buffer Child { uint child[]; };
layout(std430, binding = 17) readonly buffer Flags { uint flags[]; };
layout(std430, binding = 18) readonly buffer Data { uint data[]; };
layout(std430, binding = 19) buffer Count { uint count[]; };
uniform uint u_level;
uniform uint u_count;
uniform ivec3 u_dims;

// Bits of the SG voxels (x, y, z) with x < e.x, y < e.y, z < e.z (e in 0..4)
// of one data word (z in {z0, z0 + 1}).
uint inside_mask(uvec3 e, uint z0) {
    uint row = (1u << e.x) - 1u;                  // x < e.x, one nibble
    uint plane = 0u;
    for (uint y = 0u; y < 4u; ++y) if (y < e.y) plane |= row << (4u * y);
    uint m = 0u;
    for (uint z = 0u; z < 2u; ++z) if (z0 + z < e.z) m |= plane << (16u * z);
    return m;
}

void main() {
    uint n = global_index_1d();
    if (n >= u_count) return;
    uint L = u_level;
    uint at = u_nbase[L] + n;
    uint side = 4u << L;
    ivec3 lo = ivec3(oct_demorton(morton[at]) * side);
    uvec3 e = uvec3(clamp(u_dims - lo, ivec3(0), ivec3(side)));  // voxels in the grid per axis
    uint c;
    if (L == 0u) {
        c = uint(bitCount(data[2u * n] & inside_mask(e, 0u)))
          + uint(bitCount(data[2u * n + 1u] & inside_mask(e, 2u)));
    } else {
        uint ch = child[u_ubase[L] + n];
        if (ch == OCT_NONE) {
            c = (flags[u_ubase[L] + n] & 1u) != 0u ? e.x * e.y * e.z : 0u;
        } else {
            uint below = u_nbase[L - 1u] + ch;
            c = 0u;
            for (uint k = 0u; k < 8u; ++k) c += count[below + k];
        }
    }
    count[at] = c;
}
