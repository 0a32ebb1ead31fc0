#version 450
// The rank of the set voxels in the grid's word order, row by row (a row is
// the words_per_row() words of one (j, k)), so the scan between the two
// passes runs over rows, not words (32x fewer at 1024^3):
//   u_mode 0: row_count[r] = set voxels of row r
//   u_mode 1: word_offset[w] = row_offset[r] + set voxels of the row's words before w
// (row_offset: the exclusive scan of row_count, in place).  A row is at most
// 2048 words (MAX_DIM 65536 voxels), far within the loop budget.
#include "common/voxel_space.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 3) readonly buffer Grid { uint grid[]; };
layout(std430, binding = 9) writeonly buffer Offsets { uint word_offset[]; };
layout(std430, binding = 10) buffer Rows { uint row_count[]; };
uniform uint u_rows;
uniform uint u_total;  // set voxels in all (the scan's total), for the last row
uniform int u_mode;
void main() {
    uint r = global_index_1d();
    if (r >= u_rows) return;
    uint wpr = words_per_row();
    uint sum = u_mode == 0 ? 0u : row_count[r];
    // an empty row's offsets are never read (no set voxel looks them up): skip its writes
    if (u_mode == 1 && (r + 1u < u_rows ? row_count[r + 1u] : u_total) == sum) return;
    for (uint w = r * wpr; w < (r + 1u) * wpr; ++w) {
        if (u_mode == 1) word_offset[w] = sum;
        sum += uint(bitCount(grid[w]));
    }
    if (u_mode == 0) row_count[r] = sum;
}
