// Bit tricks on 32-bit words (GLSL shifts by >= 32 are undefined: guard them).

// The single bit of position i (0..31) in its word.
uint bit_of(uint i) { return 1u << (i & 31u); }

// Ones in bits lo..31; zero when lo >= 32.
uint mask_from(uint lo) { return lo >= 32u ? 0u : (0xFFFFFFFFu << lo); }

// Ones in bits 0..hi (inclusive); all ones when hi >= 31.
uint mask_upto(uint hi) { return hi >= 31u ? 0xFFFFFFFFu : ((1u << (hi + 1u)) - 1u); }

// Ones in bits lo..hi (inclusive); zero when lo > hi.
uint mask_range(uint lo, uint hi) { return lo > hi ? 0u : (mask_from(lo) & mask_upto(hi)); }

// Set bits strictly below position i (i in 0..32).
int count_below(uint word, uint i) { return i >= 32u ? bitCount(word) : bitCount(word & ((1u << i) - 1u)); }
