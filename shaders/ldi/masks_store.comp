#version 450
// The render targets of one Phase-1 pass and tile (Leung & Wang 2013 Sec. III-E: the XOR
// or OR masks of 128 LDI_TARGETS cells per pixel) -> the mask buffer, one ray's words
// consecutive (ldi/column.glsl).  One invocation per pixel of the tile, 4 LDI_TARGETS words
// (at most 32): each word of the buffer is written by exactly one invocation of one
// (tile, pass).  Bits past LOD-C are cleared: the XOR masks run to the end of the pass.
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
#include "ldi/cells.glsl"
#include "ldi/pixels.glsl"
#include "ldi/targets.glsl"

layout(std430, binding = 2) writeonly buffer Masks { uint masks[]; };

uniform ivec2 u_tile_lo;
uniform ivec2 u_tile_size;
uniform int u_slice_lo;  // first cell of the pass (a multiple of 128)
uniform int u_words;     // words per ray
uniform uint u_invocations;  // pixels of the tile

void main() {
    uint i = global_index_1d();
    if (i >= u_invocations) return;
    ivec2 p = ivec2(int(i % uint(u_tile_size.x)), int(i / uint(u_tile_size.x)));
    uint base = ldi_column(p + u_tile_lo) * uint(u_words);
    int w0 = u_slice_lo / 32;
    for (int t = 0; t < LDI_TARGETS; ++t) {
        uvec4 v = ldi_target(t, p);
        for (int c = 0; c < 4; ++c) {
            int w = w0 + 4 * t + c;
            if (w >= u_words) return;
            int valid = u_cells - 32 * w;  // cells of this word inside the grid
            uint word = valid < 32 ? v[c] & ((1u << uint(valid)) - 1u) : v[c];
            masks[base + uint(w)] = word;
        }
    }
}
