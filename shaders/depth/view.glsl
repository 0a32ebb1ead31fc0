// One orthographic view of Passalis et al. 2006 (Sec. 2): the rays run along voxel
// axis u_axis; view coordinates are (u, v, a) = (axis + 1, axis + 2, axis) mod 3, a cyclic
// permutation of (x, y, z), so handedness and the normal's components permute alike.
// Pixel (u, v) of the view is the voxel column whose center is (u + 1/2, v + 1/2).

uniform int u_axis;

ivec3 view_axes() { return ivec3((u_axis + 1) % 3, (u_axis + 2) % 3, u_axis); }

vec3 to_view(vec3 p) {
    ivec3 ax = view_axes();
    return vec3(p[ax.x], p[ax.y], p[ax.z]);
}

// Voxel index of column (c.x, c.y) at slice c.z along the view axis.
ivec3 from_view(ivec3 c) {
    ivec3 ax = view_axes();
    ivec3 v;
    v[ax.x] = c.x;
    v[ax.y] = c.y;
    v[ax.z] = c.z;
    return v;
}
