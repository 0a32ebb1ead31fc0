#version 450
// One pass of the LSD radix sort, step 2: stable scatter of each tile.
//
// Same tiles as radix_count.comp; `offsets` is the exclusive scan of its
// counts, so offsets[d * u_groups + g] is where the first key of digit d in
// tile g goes.  A key's output position is that plus its rank: the number of
// keys with the same digit before it in the tile.  Ranks come from counting,
// never from atomics, so the result is stable and the same on every run:
//
// * invocation t owns the ITEMS consecutive keys [first, first + ITEMS) of the
//   tile and counts its digits into column t of the shared matrix
//   s_cnt[row * WG_SIZE + t]; two digits share a row as 16-bit fields (digit
//   r in the low half, digit r + ROWS in the high half), so the matrix has
//   ROWS = RADIX / 2 rows;
// * an exclusive scan of the matrix flattened row-major (raking: each
//   invocation scans ROWS consecutive entries serially, then one work-group
//   scan of the segment sums) gives, per field, the number of keys of a
//   smaller digit of the same half plus the keys of the same digit owned by
//   earlier invocations; adding the tile's count of low-half digits to the
//   high-half fields makes that the key's position in the tile sorted by digit;
// * each invocation then walks its keys again in order, taking the position
//   from its cell and incrementing the cell.
//
// 16-bit fields need TILE <= 65535.  Shared memory: 4 * ROWS * WG_SIZE bytes
// for the matrix (16 KiB for 8-bit digits with 32 invocations), within GL's
// guaranteed minimum of 32 KiB.
// defaults: the sizes glvox.gpu_sort passes as defines
#ifndef WG_SIZE
#define WG_SIZE 32
#endif
#ifndef ITEMS
#define ITEMS 256
#endif
#ifndef DIGIT_BITS
#define DIGIT_BITS 8
#endif
#define RADIX (1u << DIGIT_BITS)
#define ROWS (RADIX / 2u)
#include "common.glsl"
layout(local_size_x = WG_SIZE) in;

layout(std430, binding = 0) readonly buffer KeysIn { uint keys_in[]; };
layout(std430, binding = 1) readonly buffer ValuesIn { uint values_in[]; };
layout(std430, binding = 2) writeonly buffer KeysOut { uint keys_out[]; };
layout(std430, binding = 3) writeonly buffer ValuesOut { uint values_out[]; };
layout(std430, binding = 4) readonly buffer Offsets { uint offsets[]; };

uniform uint u_n;
uniform uint u_shift;
uniform uint u_groups;

shared uint s_cnt[ROWS * uint(WG_SIZE)];
shared uint s_base[RADIX];

// The matrix cell of `digit` for invocation t, and the shift of its field.
uint cell(uint digit, uint t) { return (digit % ROWS) * uint(WG_SIZE) + t; }
uint field_shift(uint digit) { return (digit / ROWS) * 16u; }

void main() {
    uint g = group_index();
    if (g >= u_groups) return;
    uint t = gl_LocalInvocationIndex;
    for (uint r = 0u; r < ROWS; ++r) s_cnt[r * uint(WG_SIZE) + t] = 0u;
    memoryBarrierShared();
    barrier();

    uint first = (g * uint(WG_SIZE) + t) * uint(ITEMS);
    uint count = first < u_n ? min(uint(ITEMS), u_n - first) : 0u;
    // kept for the second walk: the keys are read from the buffer once
    uint keys[ITEMS];
    for (uint i = 0u; i < count; ++i) {
        keys[i] = keys_in[first + i];
        uint digit = (keys[i] >> u_shift) & (RADIX - 1u);
        s_cnt[cell(digit, t)] += 1u << field_shift(digit);  // column t is this invocation's own
    }
    memoryBarrierShared();
    barrier();

    uint seg = t * ROWS;
    uint sum = 0u;
    for (uint j = 0u; j < ROWS; ++j) sum += s_cnt[seg + j];
    uint packed_total;
    uint run = wg_exclusive_scan(sum, packed_total);
    for (uint j = 0u; j < ROWS; ++j) {
        uint c = s_cnt[seg + j];
        s_cnt[seg + j] = run;
        run += c;
    }
    uint low_total = packed_total & 0xFFFFu;
    memoryBarrierShared();
    barrier();

    // s_base[d] = global position of the tile's first digit-d key minus its
    // position in the tile (modular arithmetic: the sum below is exact)
    for (uint d = t; d < RADIX; d += uint(WG_SIZE)) {
        uint shift = field_shift(d);
        uint tile_start = ((s_cnt[cell(d, 0u)] >> shift) & 0xFFFFu) + (shift != 0u ? low_total : 0u);
        s_base[d] = offsets[d * u_groups + g] - tile_start;
    }
    memoryBarrierShared();
    barrier();

    for (uint i = 0u; i < count; ++i) {
        uint key = keys[i];
        uint digit = (key >> u_shift) & (RADIX - 1u);
        uint c = cell(digit, t);
        uint shift = field_shift(digit);
        uint prefix = s_cnt[c];
        s_cnt[c] = prefix + (1u << shift);
        uint pos = s_base[digit] + ((prefix >> shift) & 0xFFFFu) + (shift != 0u ? low_total : 0u);
        keys_out[pos] = key;
        values_out[pos] = values_in[first + i];
    }
}
