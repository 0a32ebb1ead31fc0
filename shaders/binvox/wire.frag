#version 450
// binvox-solid, binvox -aw: a pixel of the wireframe (wire.geom's proxy) and the line's
// depth there, decided in double exactly as glvox.reference.binvox.wire_hits decides it:
// along the major axis the pixel center c = i + 1/2 lies in [s, e) of the end points, and
// across it the pixel holds the line at c, p = s + t (e - s) with t = (c - s) / (e - s)
// (interpolated from the end point with the smaller major coordinate, so both directions
// of a shared edge give the same pixels).  The output is depth/raster.frag's layer, keyed
// the same way (depth/key.glsl), so that the z-buffer keeps the nearest (farthest) of
// lines and crossings.
#include "depth/key.glsl"
flat in vec3 g_s;
flat in vec3 g_e;
flat in int g_major;
flat in uint g_id;
uniform ivec2 u_tile_origin;
layout(location = 0) out uvec4 o_layer;

void main() {
    ivec2 pix = ivec2(gl_FragCoord.xy);
    ivec2 col = pix + u_tile_origin;
    int major = g_major, minor = 1 - g_major;
    dvec3 s = dvec3(g_s), e = dvec3(g_e);
    precise double c = double(col[major]) + 0.5;
    if (!(s[major] <= c && c < e[major])) discard;
    precise double t = (c - s[major]) / (e[major] - s[major]);
    precise double pm = s[minor] + t * (e[minor] - s[minor]);
    if (floor(pm) != double(col[minor])) discard;
    precise double q = s.z + t * (e.z - s.z);
    uint code = depth_code(q);
    uint slot = code_slot(code);
    float key = depth_key(code);
    gl_FragDepth = key;
    uint holder = uint(clamp(floor(q), -1.0lf, double(u_depth_n)) + 2.0lf);
    o_layer = uvec4(floatBitsToUint(key), g_id, slot, holder);
}
