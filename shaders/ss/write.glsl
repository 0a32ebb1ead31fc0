// Register-buffered voxel writes (Sec. 3.2 "Voxel updates"): set bits are
// collected in four words held in registers and written with one atomicOr
// per word when its slot is needed again or at the end, instead of one
// atomic per voxel.  Needs common/bits.glsl and common/voxel_space.glsl.
//
// Written without loops on purpose: Mesa's llvmpipe allows each shader
// invocation about 65535 loop iterations in total (see glvox/methods/_gpu.py,
// LOOP_BUDGET), and every iteration of a slot loop would count.

//
// The voxel count comes for free: atomicOr returns the word before the write,
// so the bits this flush sets first are b & ~old; each invocation adds its
// count to stats[7] once at the end (exact: every bit is new to one flush).

layout(std430, binding = 3) buffer Grid { uint grid[]; };
layout(std430, binding = 4) buffer Stats { uint stats[]; };  // [7]: voxels set

uint w0, w1, w2, w3;   // word indices
uint b0, b1, b2, b3;   // pending bits (0: slot free)
uint victim;           // next slot to evict, round robin
uint n_new;            // voxels this invocation set first

void writes_begin() { b0 = b1 = b2 = b3 = 0u; victim = 0u; n_new = 0u; }

void flush_word(uint w, uint b) { if (b != 0u) n_new += uint(bitCount(b & ~atomicOr(grid[w], b))); }

void set_voxel(ivec3 v) {
    uint w = word_index(v);
    uint b = bit_of(uint(v.x));
    if (b0 != 0u && w0 == w) { b0 |= b; return; }
    if (b1 != 0u && w1 == w) { b1 |= b; return; }
    if (b2 != 0u && w2 == w) { b2 |= b; return; }
    if (b3 != 0u && w3 == w) { b3 |= b; return; }
    if (b0 == 0u) { w0 = w; b0 = b; return; }
    if (b1 == 0u) { w1 = w; b1 = b; return; }
    if (b2 == 0u) { w2 = w; b2 = b; return; }
    if (b3 == 0u) { w3 = w; b3 = b; return; }
    if (victim == 0u) { flush_word(w0, b0); w0 = w; b0 = b; }
    else if (victim == 1u) { flush_word(w1, b1); w1 = w; b1 = b; }
    else if (victim == 2u) { flush_word(w2, b2); w2 = w; b2 = b; }
    else { flush_word(w3, b3); w3 = w; b3 = b; }
    victim = (victim + 1u) & 3u;
}

void writes_end() {
    flush_word(w0, b0);
    flush_word(w1, b1);
    flush_word(w2, b2);
    flush_word(w3, b3);
    if (n_new != 0u) atomicAdd(stats[7], n_new);
}
