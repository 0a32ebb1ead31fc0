// Voxel space and the bit-packed grid layout, shared with glvox/grid.py.
//
// Voxel (i, j, k) is the unit cube [i, i+1] x [j, j+1] x [k, k+1] of voxel
// space; world p maps to (p - origin) / h.  Vertices are uploaded relative to
// the mesh's anchor (its bounding-box center), so u_origin is the grid origin
// minus that anchor: float32 keeps its precision far from the world origin.
//
// Packed grid: a row (j, k) has words_per_row() = ceil(nx / 32) words; voxel
// (i, j, k) is bit i % 32 of word (k * ny + j) * words_per_row() + i / 32.
// With VOX_SLAB defined the grid buffer holds only the z slices u_slab.x ..
// u_slab.x + u_slab.y - 1 (a grid over the storage-block limit, voxelized slab
// by slab): k counts from u_slab.x.

uniform vec3 u_origin;
uniform float u_inv_h;
uniform ivec3 u_dims;
#ifdef VOX_SLAB
uniform ivec2 u_slab;  // (first z slice, slices) held by the grid buffer
#endif

// exact: one subtraction and one product, in this order
vec3 world_to_voxel(vec3 p) {
    precise vec3 v = (p - u_origin) * u_inv_h;
    return v;
}

uint words_per_row() { return (uint(u_dims.x) + 31u) >> 5; }

uint word_index(ivec3 v) {
#ifdef VOX_SLAB
    uint k = uint(v.z - u_slab.x);
#else
    uint k = uint(v.z);
#endif
    return (k * uint(u_dims.y) + uint(v.y)) * words_per_row() + (uint(v.x) >> 5);
}

bool in_grid(ivec3 v) { return all(greaterThanEqual(v, ivec3(0))) && all(lessThan(v, u_dims)); }
