// Shared pieces of the scan and radix sort kernels (shaders/sort/).
//
// The including .comp defines WG_SIZE (invocations per work group, a power of
// two) before including this file.  Work groups are numbered linearly over a
// 2D dispatch (x first, then y), because one dispatch dimension is limited
// to GL_MAX_COMPUTE_WORK_GROUP_COUNT (65535 on llvmpipe) groups.
//
// Loops are short on purpose: an invocation runs a few hundred iterations
// (ITEMS, the raking segments), far below the 65535 after which llvmpipe's
// loop limiter silently stops an invocation's loops.

uint group_index() {
    return gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
}

// Raking segment of wg_exclusive_scan: about sqrt(WG_SIZE), so that both
// serial steps below stay short.
const uint WG_SEG = uint(WG_SIZE) >= 1024u ? 32u : uint(WG_SIZE) >= 256u ? 16u
                  : uint(WG_SIZE) >= 64u ? 8u : uint(WG_SIZE) >= 16u ? 4u : 1u;
const uint WG_PARTS = (uint(WG_SIZE) + WG_SEG - 1u) / WG_SEG;

shared uint s_wg_scan[WG_PARTS * WG_SEG];
shared uint s_wg_parts[WG_PARTS + 1u];

// Exclusive prefix sum of v over the work group's invocations, in invocation
// order; `total` receives the sum of all.  Every invocation must call it
// (it contains barriers).  Raking, with a constant four barriers whatever
// WG_SIZE (llvmpipe runs each barrier as a switch between the coroutines of
// all SIMD chunks of the group, so few barriers matter more there than idle
// invocations): WG_PARTS invocations each scan WG_SEG values serially, one
// invocation scans the WG_PARTS segment sums, and the segments add their
// offsets.  The values may be packed (several counters in bit fields of one
// uint) as long as no field overflows into the next.
uint wg_exclusive_scan(uint v, out uint total) {
    uint t = gl_LocalInvocationIndex;
    s_wg_scan[t] = v;
    for (uint i = uint(WG_SIZE) + t; i < WG_PARTS * WG_SEG; i += uint(WG_SIZE)) s_wg_scan[i] = 0u;
    memoryBarrierShared();
    barrier();
    if (t < WG_PARTS) {
        uint run = 0u;
        for (uint j = t * WG_SEG; j < (t + 1u) * WG_SEG; ++j) {
            uint x = s_wg_scan[j];
            s_wg_scan[j] = run;
            run += x;
        }
        s_wg_parts[t] = run;
    }
    memoryBarrierShared();
    barrier();
    if (t == 0u) {
        uint run = 0u;
        for (uint p = 0u; p < WG_PARTS; ++p) {
            uint x = s_wg_parts[p];
            s_wg_parts[p] = run;
            run += x;
        }
        s_wg_parts[WG_PARTS] = run;
    }
    memoryBarrierShared();
    barrier();
    uint prefix = s_wg_scan[t] + s_wg_parts[t / WG_SEG];
    total = s_wg_parts[WG_PARTS];
    // the shared arrays may be reused by the next call once everyone has read them
    memoryBarrierShared();
    barrier();
    return prefix;
}
