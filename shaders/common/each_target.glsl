// EACH_TARGET(M) expands to M(0) M(1) ... M(TARGETS_N - 1): a loop over a fragment
// shader's render targets, spelled out (TARGETS_N: 1..8, defined by the includer).
//
// Why not a loop: GLSL has no portable unroll hint, and Mesa's llvmpipe (22.3) leaves
// `for (int t = 0; t < N; ++t) o[t] = ...` rolled, turning the output array indexed by
// the counter into a scalar store per lane and channel.  Measured on the
// Eisemann-Decoret render (bunny, 512^3, 4 targets): 117 ms with the loop, 61-70 ms
// spelled out.  A constant index is what every compiler handles best.
#if TARGETS_N == 1
#define EACH_TARGET(M) M(0)
#elif TARGETS_N == 2
#define EACH_TARGET(M) M(0) M(1)
#elif TARGETS_N == 3
#define EACH_TARGET(M) M(0) M(1) M(2)
#elif TARGETS_N == 4
#define EACH_TARGET(M) M(0) M(1) M(2) M(3)
#elif TARGETS_N == 5
#define EACH_TARGET(M) M(0) M(1) M(2) M(3) M(4)
#elif TARGETS_N == 6
#define EACH_TARGET(M) M(0) M(1) M(2) M(3) M(4) M(5)
#elif TARGETS_N == 7
#define EACH_TARGET(M) M(0) M(1) M(2) M(3) M(4) M(5) M(6)
#elif TARGETS_N == 8
#define EACH_TARGET(M) M(0) M(1) M(2) M(3) M(4) M(5) M(6) M(7)
#else
#error "TARGETS_N must be 1..8"
#endif
