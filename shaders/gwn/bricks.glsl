// gwn-solid's bricks: cubes of GWN_BRICK^3 voxels of the slab (aligned to the
// grid and to the slab's first slice u_slab.x; GWN_BRICK divides 4 GWN_SEGV,
// so a block of 4 voxels lies in one brick), a pair of vec4 each in Bricks,
// the record first (the second holds gwn/bricks.comp's sums between chunks):
//   x: F at the brick's center p0 (w: 0) or F- = F + T (w: 2), half solid
//      angles (as gwn/strip.glsl sums),
//   y: the error bound of x (turns),
//   z: G, a bound of |grad F| over the brick's box of voxel centers (turns
//      per voxel), so |F(p) - F(p0)| <= G |p - p0| there (F- alike),
//   w: 0: w(p) = C(p) + F(p); 2: w(p) = C(p) - T + F-(p), T the row's total
//      crossings; 1: no such bound holds (boundary strips reach the box
//      along +x and along -x); 3: the caps decide (gwn/caps.glsl): w(p) is
//      on the threshold's side of C(p), counted with the caps' crossings.
// gwn/bricks.comp writes them, gwn/rows.comp decides voxels with them.
// The second vec4 of the pair, once the last chunk has run: the first-order
// record of a brick with w 0 or 2, xyz the gradient of F (or F-, the same)
// at p0 (turns per voxel), w H, a bound of its second derivative over the box
// (turns per voxel^2); GWN_NO_H in w where there is none (it decides nothing).
const float GWN_NO_H = 1.0e30;

// The brick of voxel (i, j, k), k inside the slab, and its index in Bricks
// (bricks of the slab, x fastest, over the padded row of row_cells()).
ivec3 brick_of(int i, int j, int k) { return ivec3(i, j, k - u_slab.x) / GWN_BRICK; }

uint brick_index(ivec3 b) {
    uint nbx = (row_cells() + uint(GWN_BRICK) - 1u) / uint(GWN_BRICK);
    uint nby = (uint(u_dims.y) + uint(GWN_BRICK) - 1u) / uint(GWN_BRICK);
    return (uint(b.z) * nby + uint(b.y)) * nbx + uint(b.x);
}

// The brick's first voxel center (voxel space) and its center p0.
vec3 brick_low(ivec3 b) { return vec3(b * GWN_BRICK + ivec3(0, 0, u_slab.x)) + 0.5; }
vec3 brick_center(ivec3 b) { return brick_low(b) + 0.5 * float(GWN_BRICK - 1); }
