#version 450
// Passalis et al. 2006, Sec. 2: every view renders the mesh in voxel space.  The
// transform runs in double (float32 would add up to ~1e-4 voxel of rounding at 1024^3,
// as much as the tie tolerance); one rounding to float32 remains, as in every glvox method.
uniform dvec3 u_origin_d;
uniform double u_inv_h_d;
in vec3 in_pos;  // world, relative to the mesh anchor
out vec3 v_vox;
void main() {
    v_vox = vec3((dvec3(in_pos) - u_origin_d) * u_inv_h_d);
}
