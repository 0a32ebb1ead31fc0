#version 450
// Passalis et al. 2006, Sec. 2: every view renders the mesh in voxel space, through
// the one world -> voxel transform of every method (double, plane snap:
// common/snap.glsl); one rounding to float32 remains, as in every glvox method.
#include "common/snap.glsl"
uniform dvec3 u_origin_d;
uniform double u_inv_h_d;
in vec3 in_pos;  // world, relative to the mesh anchor
out vec3 v_vox;
void main() {
    v_vox = vec3(vertex_to_voxel(in_pos, u_origin_d, u_inv_h_d));
}
