// Packed-grid helpers of the carve passes (common/voxel_space.glsl's layout).

// The bits of word w of a row that are voxels of the grid (bits past nx are not).
uint valid_bits(uint w) {
    uint wpr = words_per_row();
    return w + 1u == wpr ? mask_upto(uint(u_dims.x - 1) & 31u) : 0xFFFFFFFFu;
}

// Words between neighbours along y (1) or z (2) in the packed grid.
uint axis_stride(int axis) {
    return axis == 1 ? words_per_row() : words_per_row() * uint(u_dims.y);
}
