#version 450
// Active level-1 nodes, extraction (Sec. 5.1): one invocation per 32-bit
// word of the Morton-indexed bit array (a 4 x 4 x 2 block of nodes).
//   EXTRACT_WRITE 0: counts[w] = set bits of word w (then scanned);
//   EXTRACT_WRITE 1: the Morton codes of the word's set bits, in bit order
//   (= Morton order), from offsets[w] on: ActNodes_1 comes out sorted.
layout(local_size_x = 256) in;
#include "common/dispatch.glsl"
layout(std430, binding = 8) readonly buffer L1Bits { uint l1bits[]; };
#if EXTRACT_WRITE
layout(std430, binding = 5) readonly buffer Offsets { uint offsets[]; };
layout(std430, binding = 9) writeonly buffer Act { uint act[]; };
#else
layout(std430, binding = 5) writeonly buffer Counts { uint counts[]; };
#endif
uniform uint u_words;
void main() {
    uint w = global_index_1d();
    if (w >= u_words) return;
    uint bits = l1bits[w];
#if EXTRACT_WRITE
    uint at = offsets[w];
    for (int i = 0; i < 32 && bits != 0u; ++i) {
        int b = findLSB(bits);
        act[at++] = (w << 5) | uint(b);
        bits &= bits - 1u;
    }
#else
    counts[w] = uint(bitCount(bits));
#endif
}
