// Work split into chunks (glvox/methods/ss_octree.py): pass 1 writes the
// chunk count of every item, an exclusive scan turns the counts into
// offsets, and the next pass runs one invocation per chunk, finding its item
// by binary search in the offsets (at most 32 steps).  Unlike one dispatch
// dimension per chunk index, no invocation idles on items with fewer chunks,
// and no item is limited in its number of chunks.  Chunks bound the loop
// iterations of an invocation (LOOP_BUDGET in glvox/methods/_gpu.py).

layout(std430, binding = 6) readonly buffer ChunkOffsets { uint chunk_offsets[]; };
layout(std430, binding = 7) readonly buffer ChunkTotal { uint chunk_total[]; };

// Item of global chunk g (< chunk_total[0]): the last item whose offset is <= g.
uint chunk_item(uint g, uint items) {
    uint lo = 0u, hi = items;  // offsets[lo] <= g < offsets[hi] (offsets[items] = total)
    for (int step = 0; step < 32 && hi - lo > 1u; ++step) {
        uint mid = (lo + hi) >> 1;
        if (chunk_offsets[mid] <= g) lo = mid; else hi = mid;
    }
    return lo;
}
