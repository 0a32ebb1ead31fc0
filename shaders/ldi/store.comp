#version 450
// The depth targets of one Phase-2 pass and tile -> the LDI's depth buffer (chunk), in
// voxel units along the axis: layer L even holds an entering sample stored as 1 - d,
// odd a leaving one stored as d (ldi/depths.frag; d = depth / n_axis).  Decoded in double
// and rounded outwards to float32 (entering down, leaving up), so the stored solid
// encloses the computed one.  Layers past the ray's count are NaN; the far-face sample of
// a ray still inside at the grid's end (ldi/count.comp) is n_axis.
// One invocation per pixel of the tile, LDI_LAYERS (at most 32) layers.
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
#include "ldi/column.glsl"
#include "ldi/targets.glsl"

layout(std430, binding = 6) readonly buffer Counts { uint counts[]; };
layout(std430, binding = 2) writeonly buffer Depths { float depths[]; };  // this chunk

uniform ivec2 u_tile_lo;
uniform ivec2 u_tile_size;
uniform int u_layer_lo;      // first layer of the pass
uniform int u_n_max;
uniform int u_chunk_lo;      // first layer held by the chunk
uniform int u_chunk_layers;  // layers per ray in the chunk
uniform int u_depth_n;       // n_axis: voxels along the rays
uniform uint u_invocations;  // pixels of the tile

void main() {
    uint i = global_index_1d();
    if (i >= u_invocations) return;
    ivec2 p = ivec2(int(i % uint(u_tile_size.x)), int(i / uint(u_tile_size.x)));
    uint col = ldi_column(p + u_tile_lo);
    int count = int(counts[col]);
    bool closed = ldi_t1_bit(col, u_cells - 1);
    double n_a = double(u_depth_n);
    uint base = col * uint(u_chunk_layers) - uint(u_chunk_lo);
    vec4 texel = vec4(0.0);
    for (int slot = 0; slot < LDI_LAYERS; ++slot) {
        int layer = u_layer_lo + slot;
        if (layer >= u_n_max) return;
        if ((slot & 3) == 0) texel = ldi_target(slot >> 2, p);
        float value;
        if (layer >= count) {
            value = uintBitsToFloat(0x7FC00000u);  // NaN
        } else if (layer == count - 1 && closed) {
            value = float(u_depth_n);
        } else {
            double f = double(texel[slot & 3]);
            value = (layer & 1) == 0 ? ldi_round_down(clamp(1.0 - f, 0.0, 1.0) * n_a)
                                     : ldi_round_up(clamp(f, 0.0, 1.0) * n_a);
        }
        depths[base + uint(layer)] = value;
    }
}
