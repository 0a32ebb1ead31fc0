#version 450
// gwn-solid, pass 2: every row of the slab to its prefix sums, C at every
// voxel (gwn/events.comp wrote each crossing at its first voxel).
//
// With boundary edges (EDGES 1) the row keeps C for gwn/field.comp.  A mesh
// whose half-edges all cancel has F = 0 and w = C exactly (closed,
// consistently oriented meshes, also nested, overlapping or inside-out
// ones), so this pass finishes the job (EDGES 0): bit i of the row's word is
// set when C >= u_threshold, set voxels are counted, and with WINDING 1 the
// cells keep w = C as float.  Bits past nx stay zero.
#include "common/voxel_space.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
#include "gwn/layout.glsl"
layout(std430, binding = 3) buffer Cells { ivec4 cells[]; };
layout(std430, binding = 7) buffer Bits { uint bits[]; };
layout(std430, binding = 8) buffer Count { uint voxel_count; };
uniform float u_threshold;
// the rows visited: j0 .. j0 + nj - 1, k0 .. k0 + nk - 1 (inside the slab);
// rows without crossings keep C = 0 (cleared cells; their bits stay clear
// unless 0 >= u_threshold, when the caller passes every row)
uniform ivec4 u_rows;   // j0, nj, k0, nk

void main() {
    uint row = global_index_1d();
    if (row >= uint(u_rows.y * u_rows.w)) return;
    int j = u_rows.x + int(row % uint(u_rows.y)), k = u_rows.z + int(row / uint(u_rows.y));
    uint base = row_base(j, k) / 4u;
    int run = 0;
#if !EDGES
    uint word = 0u, count = 0u;
    uint wbase = (uint(k) * uint(u_dims.y) + uint(j)) * words_per_row();
#endif
    for (uint q = 0u; q < row_cells() / 4u; ++q) {
        ivec4 c = cells[base + q];
        c.x += run;
        c.y += c.x;
        c.z += c.y;
        c.w += c.z;
        run = c.w;
#if EDGES
        cells[base + q] = c;
#else
        vec4 w = vec4(c);
        uint x = 4u * q;
        uvec4 in4 = uvec4(greaterThanEqual(w, vec4(u_threshold)))
                    * uvec4(lessThan(uvec4(x) + uvec4(0u, 1u, 2u, 3u), uvec4(u_dims.x)));
        word |= (in4.x | in4.y << 1u | in4.z << 2u | in4.w << 3u) << (x & 31u);
#if WINDING
        cells[base + q] = floatBitsToInt(w);
#endif
        if ((q & 7u) == 7u) {
            bits[wbase + q / 8u] = word;
            count += uint(bitCount(word));
            word = 0u;
        }
#endif
    }
#if !EDGES
    if (count != 0u) atomicAdd(voxel_count, count);
#endif
}
