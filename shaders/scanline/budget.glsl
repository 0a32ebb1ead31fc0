// Loop budget and line jobs of the scanline voxelizer (see glvox/methods/scanline.py).
//
// Mesa's llvmpipe silently ends every loop of a SIMD batch (8 lanes at 256
// bits) once the batch has run 65535 loop iterations in total
// (LOOP_BUDGET in glvox/methods/_gpu.py).  One invocation per triangle can
// exceed that for large triangles, so every invocation charges itself for
// the loop iterations it may cause and stops before its share u_budget is
// spent:
//   - a loop iteration is charged 1 + the number of loop statements nested
//     in it (each nested loop runs at least one SIMD iteration, its entry,
//     even where no lane is active, because gallivm runs both sides of a
//     branch under masks);
//   - a line is a job charged up front with its step count + 1 (its last,
//     failing test); an SLV line also with MARK_BOX_COST per step and per end
//     point box (lines.glsl: the corner loop of a box, up to 1 + 7).
// The sum of the charges of the lanes of a batch bounds the iterations the
// batch runs, so u_budget = (65535 - margin) / lanes keeps every batch safe.
// Jobs are drawn whole or not at all, so a stopped invocation leaves a valid
// subset; the host redraws its triangle in the overflow passes:
//   PASS 0  draw every job; an invocation that runs out of budget appends its
//           triangle to out_words[2 + i] (count in out_words[0]);
//   PASS 1  (one invocation per overflowed triangle) draw nothing; write the
//           selection charge, the total job cost and the largest job cost;
//   PASS 2  (one invocation per part of a triangle) draw the jobs whose
//           running cost starts in [lo, hi); an invocation that still runs
//           out of budget counts itself in out_words[0];
//   PASS 3  (ILV's small-triangle table, voxelize.comp) draw every job into
//           the invocation's 4 x 4 x 4 block; out of budget counts the entry bad.

uint g_ticks = 0u;     // iterations charged so far
bool g_abort = false;  // out of budget: stop, draw nothing more
uint g_cost = 0u;      // PASS 1, 2: cost of the jobs met so far
uint g_maxjob = 0u;    // PASS 1: largest job cost
uint g_lo = 0u;        // PASS 2: this part's share of the running cost
uint g_hi = 0u;

// Charge w iterations; false (and stop) when the budget would be exceeded.
bool tick(uint w) {
    if (g_abort) return false;
    g_ticks += w;
    if (g_ticks > u_budget) {
        g_abort = true;
        return false;
    }
    return true;
}

// A line of `cost` loop iterations: true when this invocation draws it now.
bool job(uint cost) {
    if (g_abort) return false;
#if PASS == 0 || PASS == 3
    return tick(cost);
#else
    uint start = g_cost;
    g_cost += cost;
    g_maxjob = max(g_maxjob, cost);
#if PASS == 1
    return false;
#else
    return start >= g_lo && start < g_hi && tick(cost);
#endif
#endif
}

#if PASS == 3
// Building the small-triangle table (voxelize.comp): marks go to this
// invocation's block, bit x + 4 y + 16 z for voxel SMALL_BASE + (x, y, z).
const ivec3 SMALL_BASE = ivec3(4);
uvec2 g_small = uvec2(0u);
bool g_small_bad = false;

void mark(ivec3 v) {
    ivec3 d = v - SMALL_BASE;
    if (all(greaterThanEqual(d, ivec3(0))) && all(lessThan(d, ivec3(4)))) {
        uint bit = uint(d.x + 4 * d.y + 16 * d.z);
        if (bit < 32u) g_small.x |= 1u << bit;
        else g_small.y |= 1u << (bit - 32u);
    } else {
        g_small_bad = true;  // cannot happen: ILV paths stay in the triangle's lattice box
    }
}
#else
void mark(ivec3 v) {
    if (in_grid(v)) atomicOr(grid[word_index(v)], bit_of(uint(v.x)));
}
#endif
