// A row segment of gwn/field.comp and gwn/refine.comp: 4 GWN_SEGV voxels of
// row (j, k) from x0 on, numbered row by row over the evaluated part of the
// slab (u_rows, u_segs), and how its results are written.
const int SEG = 4 * GWN_SEGV;

struct Segment {
    int j, k, seg;
    vec2 c;          // row center (y, z)
    float x0, x1;    // first voxel's low face, last voxel center inside the grid
    uint cell;       // first cell (gwn/layout.glsl)
};

// Neighbouring invocations take neighbouring rows of the same x range: they
// run side by side in one SIMD batch of llvmpipe (or one warp), and walk the
// tree alike (a node near one row is near the next), where segments of one
// row diverge.
bool segment_of(uint id, out Segment S) {
    uint nr = uint(u_rows.y * u_rows.w);
    uint row = id % nr;
    if (id / nr >= uint(u_segs.y)) return false;
    S.seg = u_segs.x + int(id / nr);
    S.j = u_rows.x + int(row % uint(u_rows.y));
    S.k = u_rows.z + int(row / uint(u_rows.y));
    S.c = vec2(S.j, S.k) + 0.5;
    S.x0 = float(S.seg * SEG);
    S.x1 = min(S.x0 + float(SEG) - 0.5, float(u_dims.x) - 0.5);
    S.cell = row_base(S.j, S.k) + uint(S.seg * SEG);
    return true;
}

vec3 vertex(uint i) { return vec3(vox[3u * i], vox[3u * i + 1u], vox[3u * i + 2u]); }

// Bits (w >= u_threshold), their count and, with WINDING 1, w in the cells,
// for the blocks of 4 voxels in `blocks` (bit i: voxels 4 i .. 4 i + 3).
// gwn/field.comp and gwn/refine.comp may each finish some blocks of one
// word: the bits go in with atomicOr.
void finish_segment(Segment S, vec4 w[GWN_SEGV], uint blocks) {
    uint word = 0u;
    for (int i = 0; i < GWN_SEGV; ++i) {
        if ((blocks & (1u << i)) == 0u) continue;
        uint x = uint(S.seg * SEG + 4 * i);
        uvec4 in4 = uvec4(greaterThanEqual(w[i], vec4(u_threshold)))
                    * uvec4(lessThan(uvec4(x) + uvec4(0u, 1u, 2u, 3u), uvec4(u_dims.x)));
        word |= (in4.x | in4.y << 1u | in4.z << 2u | in4.w << 3u) << (x & 31u);
#if WINDING
        cells[S.cell / 4u + uint(i)] = floatBitsToInt(w[i]);
#endif
    }
    if (word != 0u) {
        atomicOr(bits[bits_row(S.j, S.k) + uint(S.seg * SEG) / 32u], word);
        atomicAdd(voxel_count, uint(bitCount(word)));
    }
}
