#version 450
// carve-solid, option close=K: the surface into a grid padded by one word
// along x and u_margin voxels along y and z (UNPAD 0), and the closed surface
// back (UNPAD 1), so that the closing (carve/close.comp on the padded grid)
// sees the grid going on, empty, beyond its border: the border neither seals
// a gap nor opens one (glvox.reference.carve.close).
//
// u_dims: the grid; padded: words_per_row() + 2 words per row, ny + 2 u_margin
// rows, nz + 2 u_margin slices; voxel (i, j, k) is voxel (i + 32, j + u_margin,
// k + u_margin) there.  UNPAD 0 writes every padded word (no clear needed),
// UNPAD 1 every word of the grid, bits past nx cleared.
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
#include "carve/grid_words.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 0) buffer Grid { uint grid[]; };
layout(std430, binding = 1) buffer Padded { uint padded[]; };
uniform int u_margin;

void main() {
    uint wpr = words_per_row(), pw = wpr + 2u;
    uint py = uint(u_dims.y + 2 * u_margin), pz = uint(u_dims.z + 2 * u_margin);
    uint idx = global_index_1d();
#if UNPAD
    if (idx >= wpr * uint(u_dims.y) * uint(u_dims.z)) return;
    uint w = idx % wpr, row = idx / wpr;
    uint j = row % uint(u_dims.y), k = row / uint(u_dims.y);
    uint at = ((k + uint(u_margin)) * py + j + uint(u_margin)) * pw + w + 1u;
    grid[idx] = padded[at] & valid_bits(w);
#else
    if (idx >= pw * py * pz) return;
    uint w = idx % pw, row = idx / pw;
    int j = int(row % py) - u_margin, k = int(row / py) - u_margin;
    bool inside = w >= 1u && w <= wpr && j >= 0 && j < u_dims.y && k >= 0 && k < u_dims.z;
    padded[idx] = inside ? grid[(uint(k) * uint(u_dims.y) + uint(j)) * wpr + w - 1u] : 0u;
#endif
}
