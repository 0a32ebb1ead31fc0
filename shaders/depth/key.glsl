// The depth test's key of a crossing (depth/raster.frag) or of a wireframe pixel
// (binvox/wire.frag), written as gl_FragDepth into a 32-bit float depth buffer, which
// stores it unchanged.  The z-buffers keep the nearest (LESS) or, with u_far, the
// farthest (LEQUAL on a reversed key) of a column's keys, and what the solids read from
// them is that crossing's slot: the first voxel whose center lies beyond it.  Depth
// peeling enumerates (key, triangle id) in increasing order.
//
// The key is a float built from integer bits: the code m = slot * 2^F + b (depth_code),
// b the crossing's place within its slot in steps of 2^-F voxel (F = u_key_frac_bits;
// the caller takes (u_depth_n + 1) * 2^F <= 2^29: glvox.methods.depth.raster.key_uniforms),
// and the key the float whose bits are KEY_FIRST + m (KEY_LAST - m with u_far).  Positive
// floats order as their bits do, so keys are monotone in the depth, equal keys have the
// same slot, and nothing is rounded but b, on any GL whose floating-point depth buffer
// holds the float written (as GL requires); the keys lie in [2^-126, 1), normal floats
// (a depth buffer may flush denormals).
//
// The depth rounded to float, the key before, has a step of the extent along the rays
// times up to 2^-24, and two depths closer than that across a slot's boundary k + 1/2
// shared a key, so that a z-buffer could keep the wrong slot: a fuzzed binvox-solid case,
// a crossing 1.8e-7 voxel past 4.5 and a wireframe pixel 5e-8 before it.  Within a slot
// the step 2^-F is below 2 (u_depth_n + 1) * 2^-29, 16 times finer than that.
uniform int u_depth_n;  // voxels along the rays
uniform int u_key_frac_bits;
uniform bool u_far;

const uint KEY_FIRST = 0x00800000u;  // the smallest normal float, 2^-126
const uint KEY_LAST = 0x3F7FFFFFu;   // the largest float below 1

// The crossing's code m = slot * 2^F + b at depth q (the key's integer, above): with
// x = q + 1/2 rounded once, as the reference rounds it, floor(x * 2^F) (exact: a power of
// two) clamped to [0, (u_depth_n + 1) * 2^F - 1], whose slot m >> F is floor(x) clamped to
// [0, u_depth_n]: the first voxel whose center lies beyond the crossing (voxel i flips iff
// i + 1/2 > q), u_depth_n meaning "beyond the grid".
// exact: the reference's slot in the high bits
uint depth_code(double q) {
    precise double x = (q + 0.5lf) * double(1u << uint(u_key_frac_bits));
    double top = double(uint(u_depth_n + 1) << uint(u_key_frac_bits)) - 1.0lf;
    return uint(clamp(floor(x), 0.0lf, top));
}

uint code_slot(uint m) { return m >> uint(u_key_frac_bits); }

// The key of code m (the float whose bits are KEY_FIRST + m, or KEY_LAST - m with u_far).
float depth_key(uint m) {
    return uintBitsToFloat(u_far ? KEY_LAST - m : KEY_FIRST + m);
}
