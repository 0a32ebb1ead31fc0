#version 330
// Mesh edges over the voxels (world positions relative to the grid's center).
in vec3 in_pos;
uniform mat4 u_mvp;
void main() {
    gl_Position = u_mvp * vec4(in_pos, 1.0);
    gl_Position.z -= 2e-4 * gl_Position.w;  // in front of the cube faces they lie on
}
