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
//
// With BRICKS 1 (boundary edges, no field asked for) it also decides every
// voxel of the segments u_segs whose |C + F0 - threshold| exceeds its brick's
// bound err + G |p - p0| + u_margin (gwn/bricks.comp says why that holds;
// in bricks of the -x split C - T + F0, after the row, T the row's total
// crossings from the boundary chain):
// a block of 4 voxels decided whole gets its bits here; the others keep C in
// their cells, and Masks gets every segment's mask of such blocks (indexed as
// gwn/field.comp numbers segments), which gwn/todo.comp lists for
// gwn/field.comp.  After the row, the blocks left in bricks with a first-order
// record (gwn/bricks.glsl) get a second chance: F(p0) + grad . (p - p0) within
// err + H |p - p0|^2 / 2 (brick_near).
//
// CAPS 1 (with BRICKS and PLANES): CapEvents holds the crossings of the caps
// (gwn/caps.glsl) alone, in planes like Events; their row sums C_K added to
// C give C_{M+K}, which decides every voxel of a brick the caps decide
// (record w 3).  Elsewhere C alone goes on as above.  A row's words up to
// the first with a brick the caps leave (every word, in most rows) go in a
// loop of their own, as a closed mesh's row does, without the block loop's
// per-word set-up (llvmpipe: rows 0.7 of the time on the bunny at 512^3).
//
// PLANES 1: the crossings come as gwn/events.comp's bit planes (two for the
// +1 counts, two for the -1 ones; the second of each only read in rows
// flagged with a carry: gwn/layout.glsl), not as an int per voxel; the
// Cells then only receive C where a later pass reads it.  Closed meshes
// (EDGES 0, no WINDING) go word by word: a word without crossings has one C
// throughout, a word with some is cut at them.
#include "common/bits.glsl"
#include "common/voxel_space.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
#include "gwn/layout.glsl"
layout(std430, binding = 3) buffer Cells { ivec4 cells[]; };
#if PLANES
// gwn/events.comp's counts of the +1 and the -1 crossings of each voxel (0..3),
// in bit planes (gwn/layout.glsl): plane 0 of both as a uvec2 per word of the
// slab's bit grid, then plane 1 the same way
layout(std430, binding = 0) readonly buffer Events { uvec2 events[]; };

// The crossing counts of voxels shift .. shift + 3 of a word whose planes are e.
ivec4 block_deltas(uvec4 e, uint shift) {
    uvec4 sh = uvec4(shift) + uvec4(0u, 1u, 2u, 3u);
    return ivec4((uvec4(e.x) >> sh) & 1u) + 2 * ivec4((uvec4(e.y) >> sh) & 1u)
           - ivec4((uvec4(e.z) >> sh) & 1u) - 2 * ivec4((uvec4(e.w) >> sh) & 1u);
}

// The crossing count of voxel i (0..31) of that word.
int voxel_delta(uvec4 e, uint i) {
    ivec4 b = ivec4((e >> i) & 1u);
    return b.x + 2 * b.y - b.z - 2 * b.w;
}

// The planes of grid word `word` of the slab (gwn/layout.glsl) as one uvec4:
// +1 plane 0, +1 plane 1, -1 plane 0, -1 plane 1; plane 1 is read only in a
// row flagged in Carried, else it holds nothing.  A macro, for Events and
// CapEvents alike.
#define GWN_PLANES(buf, word, carried) \
    gwn_planes(buf[word], (carried) ? buf[plane_words() + (word)] : uvec2(0u))
uvec4 gwn_planes(uvec2 p0, uvec2 p1) { return uvec4(p0.x, p1.x, p0.y, p1.y); }

// gwn/events.comp's flags: row r of the slab has a bit in the mesh's plane 1
// where carried[r] != 0, in the caps' where carried[slab_rows() + r] != 0
layout(std430, binding = 12) readonly buffer Carried { uint carried[]; };
#endif
layout(std430, binding = 7) buffer Bits { uint bits[]; };
layout(std430, binding = 8) buffer Count {
    uint voxel_count; uint refine_count; uint todo_count; uint todo_total;
    uint split_blocks;  // blocks decided by the -x split (run.stats)
    uint overflow;      // gwn/events.comp's
    uint first_order_blocks;  // blocks decided by a first-order record (run.stats)
};
uniform float u_threshold;
#if BRICKS
#include "gwn/strip.glsl"
#include "gwn/bricks.glsl"
layout(std430, binding = 4) readonly buffer Bricks { vec4 bricks[]; };
layout(std430, binding = 2) buffer Masks { uint masks[]; };  // per segment: its blocks left
layout(std430, binding = 1) readonly buffer VoxVerts { float vox[]; };
layout(std430, binding = 5) readonly buffer Edges { uvec2 edges[]; };
layout(std430, binding = 6) readonly buffer Nodes { vec4 nodes[]; };
layout(std430, binding = 9) readonly buffer Links { ivec4 links[]; };
vec3 vertex(uint i) { return vec3(vox[3u * i], vox[3u * i + 1u], vox[3u * i + 2u]); }
#define GWN_CHAIN_WINDING 1
#include "gwn/winding2d.glsl"
uniform float u_margin;
uniform ivec2 u_segs;   // segments s0 .. s0 + ns - 1: the rest is outside (w < threshold)
#if CAPS
// gwn/events.comp's planes of the caps' crossings alone, laid out as Events
layout(std430, binding = 10) readonly buffer CapEvents { uvec2 cap_events[]; };
// gwn/bricks.comp's bit per brick the caps decide
layout(std430, binding = 11) readonly buffer CapBits { uint cap_bits[]; };
#endif
#endif
#if BRICKS
// Whether w(p) may lie within the bound of u_threshold at the 4 voxels
// p = p0 + (dx, dyz) of a brick whose record is rec (w 0 or 2) and first-order
// record rec1 (gwn/bricks.glsl), where w is the zeroth-order value (C, or
// C - T, plus F at p0); where the first order decides a voxel the zeroth does
// not, w becomes the first-order value (the two are on the same side of the
// threshold where both decide) and `first` is set.  Zeroth order:
// |w(p) - w| <= err + G |p - p0|.  First order: |w(p) - w - grad . (p - p0)|
// <= err + H |p - p0|^2 / 2, plus 1e-3 G |p - p0| for the float32 rounding of
// the gradient's sum (a few ulp of each edge's term, each at most that edge's
// share of G); a brick without a gradient has H = GWN_NO_H: nothing decided.
bvec4 brick_near(inout vec4 w, vec4 rec, vec4 rec1, vec4 dx, vec2 dyz, float dyz2, out bool first) {
    vec4 d2 = dx * dx + dyz2;
    vec4 dist = sqrt(d2);
    bvec4 near0 = lessThanEqual(abs(w - u_threshold), rec.y + rec.z * dist + u_margin);
    vec4 w1 = w + rec1.x * dx + dot(rec1.yz, dyz);
    bvec4 near1 = lessThanEqual(abs(w1 - u_threshold), rec.y + 1e-3 * rec.z * dist + 0.5 * rec1.w * d2 + u_margin);
    first = any(near0);
    w = mix(w, w1, near0);
    return bvec4(uvec4(near0) * uvec4(near1));
}
#endif

// the rows visited: j0 .. j0 + nj - 1, k0 .. k0 + nk - 1 (inside the slab);
// rows without crossings keep C = 0 (cleared cells; their bits stay clear
// unless 0 >= u_threshold, when the caller passes every row)
uniform ivec4 u_rows;   // j0, nj, k0, nk

#if CAPS
// Word sw (of u_segs) of row `row`, all of whose bricks the caps decide: C + C_K
// crossing by crossing, as a closed mesh's row goes, its bits stored and counted,
// its segment left with no blocks (Masks); `run` and `run_caps`, the row sums,
// carried across it.
void counted_word(int sw, uint row, uint ev_row, uint wbase, bool row_carried, bool cap_carried,
                  inout int run, inout int run_caps, inout uint count) {
    uvec4 e = GWN_PLANES(events, ev_row + uint(sw), row_carried);
    uvec4 f = GWN_PLANES(cap_events, ev_row + uint(sw), cap_carried);
    uint any = e.x | e.y | e.z | e.w | f.x | f.y | f.z | f.w;
    uint word = 0u, from = 0u;
    while (any != 0u) {
        uint i = uint(findLSB(any));
        any &= any - 1u;
        if (i > from && float(run + run_caps) >= u_threshold) word |= mask_range(from, i - 1u);
        run += voxel_delta(e, i);
        run_caps += voxel_delta(f, i);
        from = i;
    }
    if (float(run + run_caps) >= u_threshold) word |= mask_from(from);
    if (uint(sw) + 1u == words_per_row()) word &= mask_upto(uint(u_dims.x) - 1u - 32u * uint(sw));
    if (word != 0u) {
        bits[wbase + uint(sw)] = word;
        count += uint(bitCount(word));
    }
    masks[uint(sw - u_segs.x) * uint(u_rows.y * u_rows.w) + row] = 0u;
}
#endif

void main() {
    uint row = global_index_1d();
    if (row >= uint(u_rows.y * u_rows.w)) return;
    int j = u_rows.x + int(row % uint(u_rows.y)), k = u_rows.z + int(row / uint(u_rows.y));
    uint base = row_base(j, k) / 4u;
    int run = 0;
#if !EDGES || BRICKS
    uint word = 0u, count = 0u;
    uint wbase = bits_row(j, k);
#endif
#if BRICKS
    uint todo_mask = 0u;
    // the row's first brick: its index and center; x moves along the row
    ivec3 b0 = brick_of(0, j, k);
    uint brick_row = brick_index(b0);
    vec3 center = brick_center(b0);
    vec2 dyz = vec2(j, k) + 0.5 - center.yz;
    float dyz2 = dot(dyz, dyz);
    vec4 rec;
    bool later = false, left_any = false;
#if CAPS
    int run_caps = 0;  // the row sums of the caps' crossings
    uvec4 cev;
#endif
#endif
#if PLANES
    uint ev_row = row_base(j, k) / 32u;  // the row's first word
    uvec4 ev;
    // without CARRY_FLAGS (small grids) every row reads its second planes
    bool row_carried = CARRY_FLAGS == 0 || carried[slab_row(j, k)] != 0u;
#if CAPS
    bool cap_carried = CARRY_FLAGS == 0 || carried[slab_rows() + slab_row(j, k)] != 0u;
#endif
#endif
#if PLANES && !EDGES && !WINDING
    uint wpr = words_per_row();
    for (uint w = 0u; w < wpr; ++w) {
        ev = GWN_PLANES(events, ev_row + w, row_carried);
        uint any = ev.x | ev.y | ev.z | ev.w;
        // voxels from .. i - 1 have C = run; voxel i adds its own crossings
        uint from = 0u;
        while (any != 0u) {
            uint i = uint(findLSB(any));
            any &= any - 1u;
            if (i > from && float(run) >= u_threshold) word |= mask_range(from, i - 1u);
            run += voxel_delta(ev, i);
            from = i;
        }
        if (float(run) >= u_threshold) word |= mask_from(from);
        if (w + 1u == wpr) word &= mask_upto(uint(u_dims.x) - 1u - 32u * w);  // bits past nx stay zero
        if (word != 0u) {
            bits[wbase + w] = word;
            count += uint(bitCount(word));
            word = 0u;
        }
    }
#else
    uint q8_first = 0u;  // the first word the loop below takes
#if CAPS
    // The words of u_segs before the first with a brick the caps leave need no
    // block of their own: C + C_K, word by word as a closed mesh's row, their
    // segments left with no blocks (Masks); a row whose bricks the caps all
    // decide ends there.  Before u_segs no crossing lies (the mesh's and the
    // fans' x range), so the loop below takes up the row where these end.
    {
        const uint per_word = uint(32 / GWN_BRICK);
        uint b0 = brick_row + per_word * uint(u_segs.x), b1 = brick_row + per_word * uint(u_segs.x + u_segs.y);
        uint left = b1;  // the first brick the caps do not decide
        for (uint cw = b0 / 32u; cw * 32u < b1; ++cw) {
            uint need = mask_range(max(b0, cw * 32u) - cw * 32u, min(b1 - 1u, cw * 32u + 31u) - cw * 32u);
            uint missing = need & ~cap_bits[cw];
            if (missing != 0u) {
                left = cw * 32u + uint(findLSB(missing));
                break;
            }
        }
        int lean_end = u_segs.x + int((left - b0) / per_word);
        for (int sw = u_segs.x; sw < lean_end; ++sw)
            counted_word(sw, row, ev_row, wbase, row_carried, cap_carried, run, run_caps, count);
        if (lean_end >= u_segs.x + u_segs.y) {
            if (count != 0u) atomicAdd(voxel_count, count);
            return;
        }
        q8_first = 8u * uint(lean_end);
    }
#endif
    // word by word (lanes of one SIMD batch stay on the same word), then its
    // 8 blocks of 4 voxels
    for (uint q8 = q8_first; q8 < row_cells() / 4u; q8 += 8u) {
        uint q_end = q8 + 8u;  // the blocks left to the loop below
#if CAPS
        // a word whose bricks the caps all decide goes whole, crossing by
        // crossing, as a closed mesh's row does (and skips the block loop:
        // llvmpipe runs a branch no lane takes, but leaves a loop no lane enters)
        {
            uint q = q8;
            int sw = int(q / 8u);
            // the word's 32 / GWN_BRICK bricks, whose bits share a word of CapBits
            // (a row of bricks is 4 words_per_row() of them)
            const uint per_word = uint(32 / GWN_BRICK);
            uint bi = brick_row + per_word * uint(sw);
            bool whole = sw >= u_segs.x && sw < u_segs.x + u_segs.y
                         && ((cap_bits[bi / 32u] >> (bi & 31u)) & ((1u << per_word) - 1u)) == (1u << per_word) - 1u;
            if (whole) {
                counted_word(sw, row, ev_row, wbase, row_carried, cap_carried, run, run_caps, count);
                q_end = q8;
            }
        }
#endif
        for (uint q = q8; q < q_end; ++q) {
#if PLANES
            if ((q & 7u) == 0u) ev = GWN_PLANES(events, ev_row + q / 8u, row_carried);
            ivec4 c = block_deltas(ev, (q & 7u) * 4u);
#else
            ivec4 c = cells[base + q];
#endif
            c.x += run;
            c.y += c.x;
            c.z += c.y;
            c.w += c.z;
            run = c.w;
#if CAPS
            if ((q & 7u) == 0u) cev = GWN_PLANES(cap_events, ev_row + q / 8u, cap_carried);
            ivec4 ck = block_deltas(cev, (q & 7u) * 4u);
            ck.x += run_caps;
            ck.y += ck.x;
            ck.z += ck.y;
            ck.w += ck.z;
            run_caps = ck.w;
#endif
#if BRICKS
            int seg = int(q / 8u);
            if (seg >= u_segs.x && seg < u_segs.x + u_segs.y) {
                // the brick of voxel 4 q (GWN_BRICK / 4 blocks per brick along the row)
                uint bx = q / uint(GWN_BRICK / 4);
                if (q % uint(GWN_BRICK / 4) == 0u) rec = bricks[2u * (brick_row + bx)];
#if CAPS
                // a brick the caps decide (record w 3): |w - C_{M+K}| stays under the
                // threshold's distance to the integers, so w is on C_{M+K}'s side of it
                bool by_caps = rec.w == 3.0;
                ivec4 closed = c + ck;
#else
                const bool by_caps = false;
                ivec4 closed = c;
#endif
                if (by_caps) {
                    uint x = 4u * q;
                    uvec4 in4 = uvec4(greaterThanEqual(vec4(closed), vec4(u_threshold)))
                                * uvec4(lessThan(uvec4(x) + uvec4(0u, 1u, 2u, 3u), uvec4(u_dims.x)));
                    word |= (in4.x | in4.y << 1u | in4.z << 2u | in4.w << 3u) << (x & 31u);
                } else {
                    vec4 dx = vec4(float(4u * q) + 0.5 - center.x) + vec4(0.0, 1.0, 2.0, 3.0) - float(bx * uint(GWN_BRICK));
                    vec4 dist = sqrt(dx * dx + dyz2);
                    vec4 w = vec4(c) + rec.x * (0.5 / GWN_PI);
                    bvec4 near = lessThanEqual(abs(w - u_threshold), rec.y + rec.z * dist + u_margin);
                    if (rec.w != 0.0 || any(near)) {
                        // undecided, or -x split: decided after the row, when T is known
                        todo_mask |= 1u << (q & 7u);
                        cells[base + q] = c;
                        later = later || (GWN_SPLIT != 0 && rec.w == 2.0);
                    } else {
                        uint x = 4u * q;
                        uvec4 in4 = uvec4(greaterThanEqual(w, vec4(u_threshold)))
                                    * uvec4(lessThan(uvec4(x) + uvec4(0u, 1u, 2u, 3u), uvec4(u_dims.x)));
                        word |= (in4.x | in4.y << 1u | in4.z << 2u | in4.w << 3u) << (x & 31u);
                    }
                }
            }
            if ((q & 7u) == 7u) {
                if (word != 0u) {
                    bits[wbase + q / 8u] = word;
                    count += uint(bitCount(word));
                    word = 0u;
                }
                if (seg >= u_segs.x && seg < u_segs.x + u_segs.y) {
                    masks[uint(seg - u_segs.x) * uint(u_rows.y * u_rows.w) + row] = todo_mask;
                    left_any = left_any || todo_mask != 0u;
                    todo_mask = 0u;
                }
            }
#elif EDGES
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
    }
#endif
#if BRICKS
    // The blocks left above, after the row: those of -x split bricks, w = (C - T)
    // + F-, T = the row's total crossings (T from the boundary chain: the row sums
    // miss crossings past the grid; a row through a projected boundary edge or
    // vertex leaves them undecided.  chain_winding walks the whole tree in one
    // invocation: GWN_SPLIT is 0, and those blocks go to the walk, when the tree
    // is over the loop budget), and those of both splits by their bricks'
    // first-order records (brick_near).  Here and not in the loop above, which
    // every block of the row goes through: there the first order's sums made
    // the pass 15-30% slower on llvmpipe where they decide nothing.
    bool tie = false;
    int total = later ? -chain_winding(vec2(j, k) + 0.5, tie) : 0;
    uint split = 0u, first_order = 0u;
    if (left_any) {
        for (int seg = u_segs.x; seg < u_segs.x + u_segs.y; ++seg) {
            uint at = uint(seg - u_segs.x) * uint(u_rows.y * u_rows.w) + row;
            uint left = masks[at], add = 0u;
            for (uint i = 0u; i < 8u; ++i) {
                uint q = uint(seg) * 8u + i;
                if ((left & (1u << i)) == 0u) continue;
                uint bx = q / uint(GWN_BRICK / 4);
                vec4 r = bricks[2u * (brick_row + bx)];
                bool minus_split = r.w == 2.0 && later && !tie;
                if (r.w != 0.0 && !minus_split) continue;
                vec4 dx = vec4(float(4u * q) + 0.5 - center.x) + vec4(0.0, 1.0, 2.0, 3.0) - float(bx * uint(GWN_BRICK));
                vec4 w = vec4(cells[base + q] - (minus_split ? total : 0)) + r.x * (0.5 / GWN_PI);
                bool by_first = false;
                if (any(brick_near(w, r, bricks[2u * (brick_row + bx) + 1u], dx, dyz, dyz2, by_first))) continue;
                uint x = 4u * q;
                uvec4 in4 = uvec4(greaterThanEqual(w, vec4(u_threshold)))
                            * uvec4(lessThan(uvec4(x) + uvec4(0u, 1u, 2u, 3u), uvec4(u_dims.x)));
                add |= (in4.x | in4.y << 1u | in4.z << 2u | in4.w << 3u) << (x & 31u);
                left &= ~(1u << i);
                if (by_first) ++first_order;
                else ++split;
            }
            if (add != 0u) {
                bits[wbase + uint(seg)] |= add;
                count += uint(bitCount(add));
            }
            masks[at] = left;
        }
        if (split != 0u) atomicAdd(split_blocks, split);
        if (first_order != 0u) atomicAdd(first_order_blocks, first_order);
    }
#endif
#if !EDGES || BRICKS
    if (count != 0u) atomicAdd(voxel_count, count);
#endif
}
