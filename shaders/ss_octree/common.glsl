// Sparse solid octree of Schwarz & Seidel 2010, Sec. 5: what every pass shares.
//
// Levels.  Voxel (i, j, k) of the grid is sub-grid (SG) voxel (i % 4, j % 4,
// k % 4) of level-0 node (i / 4, j / 4, k / 4); a level-L node covers
// 4 * 2^L voxels per axis.  The top level OCT_TOP holds all 4 x 4 x 4 nodes of
// a cube of 16 * 2^OCT_TOP voxels that contains the grid (two levels below
// a root that is not stored, Sec. 5.2).
//
// Node arrays.  The nodes of level L are stored contiguously in Morton order
// (Sec. 5.1: code ... k1 j1 i1 k0 j0 i0 of the node's level coordinates), so
// the eight children of a node are contiguous and the first one's index is a
// multiple of 8; child c = i0 | j0 << 1 | k0 << 2 of its parent.  All levels
// share one buffer per field, level L starting at u_nbase[L] (levels 0..top:
// Morton code, parent, +x and -x neighbour, coverage count) or u_ubase[L]
// (levels 1..top: first child, flags).  Pointers are indices within the
// level they point into; OCT_NONE marks none.
//
// Bindings of the octree buffers (all passes):
//   12 morton  13 parent  14 x_next  15 x_prev  16 child  17 flags  18 data  19 count
// Flags of a level >= 1 node: bit 0 inside, bit 1 flip (Sec. 5.4).
// Data of level-0 node n: the 4^3 SG voxels as 64 bits in words 2n (z < 2)
// and 2n + 1 (z >= 2); SG voxel (x, y, z) is bit x + 4 y + 16 (z & 1).

const uint OCT_NONE = 0xFFFFFFFFu;

// Node offsets per level (the Python side writes OCT_MAX_LEVELS entries).
#define OCT_MAX_LEVELS 12
uniform uint u_nbase[OCT_MAX_LEVELS];
uniform uint u_ubase[OCT_MAX_LEVELS];

// Spread the low 10 bits of v to every third bit (Morton interleave).
uint oct_spread3(uint v) {
    v &= 0x3FFu;
    v = (v | (v << 16)) & 0x030000FFu;
    v = (v | (v << 8)) & 0x0300F00Fu;
    v = (v | (v << 4)) & 0x030C30C3u;
    v = (v | (v << 2)) & 0x09249249u;
    return v;
}

uint oct_compact3(uint v) {
    v &= 0x09249249u;
    v = (v | (v >> 2)) & 0x030C30C3u;
    v = (v | (v >> 4)) & 0x0300F00Fu;
    v = (v | (v >> 8)) & 0x030000FFu;
    v = (v | (v >> 16)) & 0x3FFu;
    return v;
}

// Morton code of level coordinates p (each < 1024).
uint oct_morton(uvec3 p) { return oct_spread3(p.x) | (oct_spread3(p.y) << 1) | (oct_spread3(p.z) << 2); }

uvec3 oct_demorton(uint m) { return uvec3(oct_compact3(m), oct_compact3(m >> 1), oct_compact3(m >> 2)); }
