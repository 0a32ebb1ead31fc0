#version 450
// binvox-solid: record one z-buffer of a view (shaders/depth/raster.*) into packed grids.
//   u_record 0 / 1 (carving): the nearest (0) or farthest (1) crossing of the column, the
//     z-buffers binvox reads from the two faces along the axis.  It marks with an XOR bit
//     the first voxel kept (slot - u_dilate) and the first voxel carved again beyond the
//     farthest crossing (slot + u_dilate); binvox keeps k with round(zb) <= k < round(zf),
//     i.e. the centers between the two crossings, one more voxel at each end when dilated.
//     A column whose two marks coincide (one crossing seen from both faces) keeps nothing
//     (dilated: the two voxels around it).
//   u_record 2 (parity voting; every peeled layer): the crossing flips the parity of the
//     centers beyond it (mark at slot), the column's total parity (flip of its word in
//     Total), and sets the voxel holding it in Surface (raster.frag's w - 2).
// STENCIL_MODE 1 (a program of its own, the only one that declares Stats) also takes the
// tile's largest stencil count into stats[0].
layout(local_size_x = 8, local_size_y = 8) in;
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
#include "depth/view.glsl"
uniform ivec2 u_tile_origin;
uniform ivec2 u_view_size;     // (n_u, n_v): columns of the whole view
uniform usampler2D u_layer;    // (key bits, triangle id, first voxel beyond, floor(q) + 2)
uniform usampler2D u_stencil;  // the stencil buffer of the pass (crossings counted)
uniform int u_record;          // 0: nearest (carving), 1: farthest (carving), 2: vote
uniform int u_dilate;          // 0, or 1 for dilated carving
layout(std430, binding = 0) buffer Flips { uint flips[]; };
#if STENCIL_MODE == 1
layout(std430, binding = 1) buffer Stats { uint stats[]; };
#endif
layout(std430, binding = 2) buffer Total { uint total[]; };     // per column of the view
layout(std430, binding = 3) buffer Surface { uint surface[]; };

void main() {
    ivec2 pix = ivec2(gl_GlobalInvocationID.xy);
    ivec2 col = pix + u_tile_origin;
    if (any(greaterThanEqual(pix, textureSize(u_layer, 0))) || any(greaterThanEqual(col, u_view_size))) {
        return;
    }
#if STENCIL_MODE == 1
    atomicMax(stats[0], texelFetch(u_stencil, pix, 0).r);
#endif
    uvec4 layer = texelFetch(u_layer, pix, 0);
    if (layer.w == 0u) return;
    int n = u_dims[u_axis];
    int slot = int(layer.z);
    if (u_record == 0) slot = max(slot - u_dilate, 0);
    if (u_record == 1) slot = slot + u_dilate;
    if (slot < n) {
        ivec3 v = from_view(ivec3(col, slot));
        atomicXor(flips[word_index(v)], bit_of(uint(v.x)));
    }
    if (u_record == 2) {
        // atomic: the layers of a column are recorded by successive dispatches with no
        // barrier between them, and a plain read-modify-write need not see the last one's
        atomicXor(total[col.y * u_view_size.x + col.x], 1u);
        int holder = int(layer.w) - 2;
        if (holder >= 0 && holder < n) {
            ivec3 v = from_view(ivec3(col, holder));
            atomicOr(surface[word_index(v)], bit_of(uint(v.x)));
        }
    }
}
