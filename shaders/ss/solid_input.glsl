// The voxel-space triangles of the solid passes (common/transform.comp's output
// and the mesh's faces), set up for ss/solid.glsl.
layout(std430, binding = 1) readonly buffer VoxVerts { float vox[]; };
layout(std430, binding = 2) readonly buffer Faces { uint faces[]; };

vec3 vox_vertex(uint i) { return vec3(vox[3u * i], vox[3u * i + 1u], vox[3u * i + 2u]); }

bool load_solid_triangle(uint t, out SolidTri T) {
    return solid_setup(vox_vertex(faces[3u * t]), vox_vertex(faces[3u * t + 1u]),
                       vox_vertex(faces[3u * t + 2u]), T);
}

// The columns of T this pass visits: its covered-center box, and with VOX_SLAB
// (common/voxel_space.glsl) only the rows k of the slab the grid buffer holds.
ivec4 pass_columns(SolidTri T) {
    ivec4 c = solid_columns(T, u_dims);
#ifdef VOX_SLAB
    c.y = max(c.y, u_slab.x);
    c.w = min(c.w, u_slab.x + u_slab.y - 1);
#endif
    return c;
}

// Work of triangle T in units of SOLID_UNIT x SOLID_UNIT columns (1: columns
// for ss-solid, 4: tiles for ss-solid-tiled): the units of its covered-center
// range, as (first unit, units per row, total units); total 0 when it
// covers no column center of the grid.
uvec4 solid_units(SolidTri T) {
    ivec4 c = pass_columns(T);
    if (c.x > c.z || c.y > c.w) return uvec4(0u);
    ivec4 u = c / SOLID_UNIT;
    uint nu = uint(u.z - u.x + 1), nv = uint(u.w - u.y + 1);
    return uvec4(uint(u.x), uint(u.y), nu, nu * nv);
}
