#version 330
// Two-light Lambert shading; faces along each axis get a slightly different
// tint so adjacent cube faces stay readable where they are coplanar.
// u_flat: the voxel's colour as it is, unlit (pictures read back by the tests).
in vec3 v_normal;
in vec3 v_color;
uniform vec3 u_light;
uniform bool u_flat;
out vec4 f_color;
void main() {
    if (u_flat) {
        f_color = vec4(v_color, 1.0);
        return;
    }
    vec3 n = normalize(v_normal);
    float key = max(dot(n, normalize(u_light)), 0.0);
    float fill = 0.35 * max(dot(n, normalize(vec3(-u_light.x, 0.4, -u_light.z))), 0.0);
    vec3 tint = 1.0 - 0.06 * abs(n);
    f_color = vec4(v_color * tint * (0.25 + 0.7 * key + fill), 1.0);
}
