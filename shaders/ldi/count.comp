#version 450
// The n_max pass of Leung & Wang 2013 (Sec. III-E): the samples of every ray by Eq. 5 over
// the whole ray, plus one leaving sample at the far face when T1 of the last cell is
// still inside (a solid cut by the grid's end; never on a closed mesh inside the grid).
// The maximum and the total are reduced on the GPU (atomics), so only n_max is read back.
// One invocation per ray; u_words iterations.
layout(local_size_x = 64) in;
#define LDI_READ_T2 1
#include "common/dispatch.glsl"
#include "ldi/column.glsl"

layout(std430, binding = 6) writeonly buffer Counts { uint counts[]; };
layout(std430, binding = 7) buffer Stats { uint stats[]; };  // [n_max, samples]

void main() {
    uint i = global_index_1d();
    uint n_rays = uint(u_grid_uv.x * u_grid_uv.y);
    if (i >= n_rays) return;
    ivec2 uv = ivec2(int(i % uint(u_grid_uv.x)), int(i / uint(u_grid_uv.x)));
    uint col = ldi_column(uv);
    uint n = 0u;
    uint e, l;
    for (int w = 0; w < u_words; ++w) {
        ldi_marks(col, w, e, l);
        int valid = u_cells - 32 * w;
        uint m = valid >= 32 ? 0xFFFFFFFFu : (1u << uint(valid)) - 1u;
        n += uint(bitCount(e & m) + bitCount(l & m));
    }
    if (ldi_t1_bit(col, u_cells - 1)) n += 1u;
    counts[col] = n;
    atomicMax(stats[0], n);
    atomicAdd(stats[1], n);
}
