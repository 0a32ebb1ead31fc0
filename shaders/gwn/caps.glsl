// gwn-solid's caps (glvox/methods/gwn/caps.py): a fan K over every boundary
// loop, appended to the mesh's triangles and its crossings counted apart
// (gwn/events.comp, planes of their own), so that C + C_K is the winding
// number of the closed M + K and w_M = C + C_K - w_K.  Where |w_K| stays
// below u_cap_limit (the threshold's distance to the nearest integer, less
// the tie tolerance) the integer C + C_K alone decides every voxel.  The Caps buffer: per loop (apex, r) of a ball holding its fan
// and (area, first triangle record, triangle count) (ints as float bits),
// then per fan triangle its vertex indices (uint bits).
layout(std430, binding = 11) readonly buffer Caps { vec4 caps[]; };
uniform int u_loops;        // loops: their records come first
uniform float u_cap_limit;  // turns
uniform vec4 u_caps_ball;   // a ball holding every fan (center, radius)
uniform float u_caps_area;  // the fans' total area

const int GWN_CAP_VEC4 = 2;

// closest_distance_f: the distance from a point to a triangle (Ericson), precise
#include "sdf/closest.glsl"

// The fan triangle of record t: its voxel-space vertices (vertex() of the includer).
void cap_triangle(int t, out vec3 a, out vec3 b, out vec3 c) {
    uvec4 f = floatBitsToUint(caps[t]);
    a = vertex(f.x);
    b = vertex(f.y);
    c = vertex(f.z);
}

// The solid angle of the triangle (a, b, c) seen from p (Van Oosterom and
// Strackee 1983), in (-2 pi, 2 pi]: continuous off the triangle.
float triangle_solid_angle(vec3 p, vec3 a, vec3 b, vec3 c) {
    vec3 u = a - p, v = b - p, w = c - p;
    float lu = length(u), lv = length(v), lw = length(w);
    return 2.0 * atan(dot(u, cross(v, w)), lu * lv * lw + dot(u, v) * lw + dot(u, w) * lv + dot(v, w) * lu);
}

// Distance from p to the segment (a, b).
float segment_distance(vec3 p, vec3 a, vec3 b) {
    vec3 ab = b - a;
    float t = clamp(dot(p - a, ab) / max(dot(ab, ab), 1e-30), 0.0, 1.0);
    return length(p - a - t * ab);
}

// Whether |w_K| stays below u_cap_limit at every point within hd of p0 (the
// caps then decide them all).  First all fans at once by their common ball,
// then per fan, in steradians, the least of:
// * its area over (|p0 - a| - r - hd)^2, the fan lying in the ball (a, r);
// * the sum over its triangles of min(A / d^2, 2 pi), d the triangle's
//   distance less hd (a triangle's solid angle is the integral of cos / r^2
//   over it);
// * where no triangle and no loop edge comes within hd: |Omega(p0)| plus hd
//   times a bound of |grad Omega| over the ball, the Biot-Savart integral
//   over the fan's boundary, its loop (the fan's inner edges cancel): at
//   most the sum over loop edges of min(l / g^2, 4 / g), g the edge's
//   distance less hd (as gwn/bricks.comp bounds the strips' gradient).
// Or, where that is less, the same with the solid angles at p0 of all the
// fans that keep clear of the ball summed before their absolute value.
// Distances are taken short and areas large for float32 rounding, and the
// exact value gets 2e-3 sr for its own.
bool caps_decide(vec3 p0, float hd) {
    float limit = u_cap_limit * 4.0 * GWN_PI * 0.999;
    // most bricks are far from every fan: one test for all of them
    float all = length(p0 - u_caps_ball.xyz) - u_caps_ball.w - hd;
    if (all > 0.0 && u_caps_area / (all * all) < limit) return true;
    // each: per fan the least of its bounds, summed.  signed_rest + |omega_all|:
    // the same but the solid angles of the fans clear of the ball summed with
    // their signs (fans of opposite sense close together, as a lid's rim inside
    // its pot's, cancel)
    float each = 0.0, signed_rest = 0.0, omega_all = 0.0;
    for (int l = 0; l < u_loops && (each < limit || signed_rest < limit); ++l) {
        vec4 ball = caps[GWN_CAP_VEC4 * l];
        vec4 fan = caps[GWN_CAP_VEC4 * l + 1];
        float d = length(p0 - ball.xyz) - ball.w - hd;
        if (d > 0.0 && each + fan.x / (d * d) < limit) {
            each += fan.x / (d * d);
            signed_rest += fan.x / (d * d);
            continue;
        }
        ivec4 range = floatBitsToInt(fan);
        float crude = 0.0, omega = 0.0, grad = 0.0;
        bool apart = true;  // no triangle or loop edge within hd of p0
        for (int t = range.y; t < range.y + range.z; ++t) {
            vec3 a, b, c;
            cap_triangle(t, a, b, c);
            float dt = closest_distance_f(p0 - a, b - a, c - a) * (1.0 - 1e-5) - hd - 1e-3;
            float area = 0.5005 * length(cross(b - a, c - a));
            crude += dt > 0.0 ? min(area / (dt * dt), 2.0 * GWN_PI) : 2.0 * GWN_PI;
            // (a, b) is the loop's edge: fan triangles are (w_{i+1}, w_i, apex)
            float g = segment_distance(p0, a, b) * (1.0 - 1e-5) - hd - 1e-3;
            apart = apart && dt > 0.0 && g > 0.0;
            if (apart) {
                omega += triangle_solid_angle(p0, a, b, c);
                grad += 1.001 * min(length(b - a) / (g * g), 4.0 / g);
            }
        }
        each += apart ? min(crude, abs(omega) + 2e-3 + grad * hd) : crude;
        signed_rest += apart ? 2e-3 + grad * hd : crude;
        omega_all += apart ? omega : 0.0;
    }
    return min(each, signed_rest + abs(omega_all)) < limit;
}
