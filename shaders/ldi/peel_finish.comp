#version 450
// Depth-peeling LDI: NaN past each ray's count, and a ray with an odd count (an open mesh:
// the parity solid runs to the grid's end) closed by a sample at the far face n_axis.
// One invocation per (ray, layer of the chunk).
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
#include "ldi/pixels.glsl"

layout(std430, binding = 2) buffer Depths { float depths[]; };  // this chunk
layout(std430, binding = 6) readonly buffer Counts { uint counts[]; };

uniform int u_chunk_lo;
uniform int u_chunk_layers;
uniform int u_layers;  // layers of the result (with room for the closing sample)
uniform int u_depth_n;
uniform uint u_invocations;

void main() {
    uint i = global_index_1d();
    if (i >= u_invocations) return;
    uint col = i / uint(u_chunk_layers);
    int layer = u_chunk_lo + int(i % uint(u_chunk_layers));
    if (layer >= u_layers) return;
    int count = int(counts[col]);
    if (layer < count) return;
    depths[i] = (layer == count && (count & 1) == 1) ? float(u_depth_n) : uintBitsToFloat(0x7FC00000u);
}
