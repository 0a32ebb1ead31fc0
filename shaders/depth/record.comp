#version 450
// Record one z-buffer of a view (Passalis et al. 2006, Sec. 2, step 2 on the GPU): the
// crossing it holds at each pixel flips the parity of the voxels beyond it, so this marks
// the first of them with an XOR bit; depth.scan then turns the marks into the parity of
// crossings before each voxel center, which is "between a pair of z-buffers" of the paper.
//
// It also reads the stencil count of the pass when asked (STENCIL_MODE, one program each,
// so that each declares only the buffers it writes): 1, its maximum (how many peeling
// passes the view needs, Sec. 3.3); 2, per column, whether more crossings than the
// double-layer buffers hold were counted (Sec. 3.2's unclassifiable columns).
layout(local_size_x = 8, local_size_y = 8) in;
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
#include "view.glsl"
uniform ivec2 u_tile_origin;
uniform ivec2 u_view_size;     // (n_u, n_v): columns of the whole view
uniform usampler2D u_layer;    // (key bits, triangle id, first voxel beyond, valid)
uniform usampler2D u_dedupe;   // another layer of the same class, or unused
uniform bool u_use_dedupe;     // a crossing already recorded from u_dedupe is not flipped twice
uniform usampler2D u_stencil;  // the stencil buffer of the pass (crossings counted)
layout(std430, binding = 0) buffer Flips { uint flips[]; };
#if STENCIL_MODE == 1
layout(std430, binding = 1) buffer Stats { uint stats[]; };
#elif STENCIL_MODE == 2
layout(std430, binding = 2) writeonly buffer Crowded { uint crowded[]; };  // per column of the view
#endif

void main() {
    ivec2 pix = ivec2(gl_GlobalInvocationID.xy);
    ivec2 col = pix + u_tile_origin;
    if (any(greaterThanEqual(pix, textureSize(u_layer, 0))) || any(greaterThanEqual(col, u_view_size))) {
        return;
    }
#if STENCIL_MODE == 1
    atomicMax(stats[0], texelFetch(u_stencil, pix, 0).r);
#elif STENCIL_MODE == 2
    crowded[col.y * u_view_size.x + col.x] = texelFetch(u_stencil, pix, 0).r > CLASSIFIABLE_COUNT ? 1u : 0u;
#endif
    uvec4 layer = texelFetch(u_layer, pix, 0);
    if (layer.w == 0u || layer.z >= uint(u_dims[u_axis])) return;
    if (u_use_dedupe) {
        uvec4 other = texelFetch(u_dedupe, pix, 0);
        if (other.w != 0u && other.y == layer.y) return;
    }
    ivec3 v = from_view(ivec3(col, int(layer.z)));
    atomicXor(flips[word_index(v)], bit_of(uint(v.x)));
}
