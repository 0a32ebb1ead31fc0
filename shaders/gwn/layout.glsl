// gwn-solid's per-voxel slab buffer: one 32-bit cell per voxel of the z
// slices u_slab.x .. u_slab.y - 1, rows of 32 * words_per_row() cells
// (padded to whole words, so a word's 32 voxels are 8 aligned uvec4).  A
// cell holds C (int) after gwn/rows.comp, then w, or C plus the part of F
// summed so far, as float bits after a gwn/field.comp chunk.
uniform ivec2 u_slab;  // z slices k0 .. k1 - 1

uint row_cells() { return 32u * words_per_row(); }

// Row (j, k) of the slab, k inside it: its index among the slab's rows, and its first cell.
uint slab_row(int j, int k) { return uint(k - u_slab.x) * uint(u_dims.y) + uint(j); }

uint row_base(int j, int k) { return slab_row(j, k) * row_cells(); }

uint cell_index(int i, int j, int k) { return row_base(j, k) + uint(i); }

// The Bits buffer (the packed result) holds z slices u_bits_k0 on: 0 where it
// holds the whole grid, the slab's first slice where a grid over the storage
// block limit is streamed slab by slab.
uniform int u_bits_k0;

uint bits_row(int j, int k) { return (uint(k - u_bits_k0) * uint(u_dims.y) + uint(j)) * words_per_row(); }

// gwn/events.comp's bit planes of the slab (PLANES 1), in uints: plane 0 of
// the +1 and of the -1 counts side by side for each grid word (the slab's
// rows as in the bit grid), then plane 1 the same way.  Plane 1 takes a
// carry, two or more crossings of one sign in a voxel, which is rare: with
// CARRY_FLAGS 1 (large grids: CARRY_FLAGS_MIN_VOXELS in
// glvox/methods/gwn/plan.py) the Carried buffer has a flag per row of the
// slab, set where plane 1 holds a bit of the row (the mesh's rows, then the
// caps'), so gwn/rows.comp reads plane 0 alone, half the bytes, in every
// other row.
uint slab_rows() { return uint(u_slab.y - u_slab.x) * uint(u_dims.y); }

uint plane_words() { return slab_rows() * words_per_row(); }
