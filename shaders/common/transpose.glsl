// 32 x 32 bit matrix transpose by recursive block swaps (16 x 16, then 8 x 8,
// ... 1 x 1 blocks): afterwards bit b of a[c] is the former bit c of a[b].
// Words of a packed grid along one axis become words along another (the
// eisemann targets into the grid, vote-solid's y and z parities into x rows).
// The uvec4 form transposes four matrices at once, one per component.

void transpose32(inout uint a[32]) {
    uint m = 0x0000FFFFu;
    for (int j = 16; j != 0; j >>= 1, m ^= (m << j)) {
        for (int k = 0; k < 32; k = ((k | j) + 1) & ~j) {
            uint d = ((a[k] >> j) ^ a[k | j]) & m;
            a[k | j] ^= d;
            a[k] ^= d << j;
        }
    }
}

void transpose32(inout uvec4 a[32]) {
    uint m = 0x0000FFFFu;
    for (int j = 16; j != 0; j >>= 1, m ^= (m << j)) {
        for (int k = 0; k < 32; k = ((k | j) + 1) & ~j) {
            uvec4 d = ((a[k] >> j) ^ a[k | j]) & m;
            a[k | j] ^= d;
            a[k] ^= d << j;
        }
    }
}
