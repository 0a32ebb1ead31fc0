#version 330
// Lit voxel cubes, one instance per (exposed) voxel.  Coordinates are
// relative to the grid's center so float32 keeps them precise.
in vec3 in_pos;       // unit cube corner offset, [-0.5, 0.5]^3
in vec3 in_normal;
in vec3 in_voxel;     // voxel index (i, j, k)
in vec3 in_color;     // the voxel's own RGB in [0, 1]
uniform mat4 u_mvp;
uniform vec3 u_origin;  // grid origin minus the grid's center
uniform float u_h;
out vec3 v_normal;
out vec3 v_color;
void main() {
    vec3 p = u_origin + (in_voxel + 0.5 + in_pos) * u_h;
    v_normal = in_normal;
    v_color = in_color;
    gl_Position = u_mvp * vec4(p, 1.0);
}
