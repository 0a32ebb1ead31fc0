#version 450
// ss-solid-tiled, compaction of the sorted (tile, triangle) pairs into the
// list of active tiles (Sec. 4.2):
//   PHASE 0: flags[i] = 1 where a tile's run of pairs starts;
//   PHASE 1: (after an exclusive scan of the flags into slots) the active
//            tile list: tile key and first pair of each run;
//   PHASE 2: per active tile, its number of triangles into the statistics
//            (maximum, which sizes the passes of ss/tile_process.comp).
layout(local_size_x = 256) in;
#include "common/dispatch.glsl"
layout(std430, binding = 0) readonly buffer Keys { uint keys[]; };
layout(std430, binding = 1) buffer Flags { uint flags[]; };
layout(std430, binding = 2) readonly buffer Slots { uint slots[]; };
layout(std430, binding = 3) buffer Active { uint tiles[]; };  // (key, first pair) per active tile
layout(std430, binding = 4) buffer Stats { uint stats[]; };     // [0] active tiles, [1] max triangles
uniform uint u_pairs;
void main() {
    uint i = global_index_1d();
#if PHASE == 0
    if (i >= u_pairs) return;
    flags[i] = (i == 0u || keys[i] != keys[i - 1u]) ? 1u : 0u;
#elif PHASE == 1
    if (i >= u_pairs || flags[i] == 0u) return;
    tiles[2u * slots[i]] = keys[i];
    tiles[2u * slots[i] + 1u] = i;
#else
    uint n = stats[0];
    if (i >= n) return;
    uint end = i + 1u < n ? tiles[2u * i + 3u] : u_pairs;
    atomicMax(stats[1], end - tiles[2u * i + 1u]);
#endif
}
