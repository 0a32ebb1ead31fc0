#version 450
// binvox-solid, binvox -aw: the wireframe of one view (the rays along u_axis), drawn into
// the carving z-buffers next to the triangles (depth/raster.*).  Every edge of every
// triangle (those parallel to the rays included: they are the thin parts -aw is for)
// becomes a proxy quad around the line, half a pixel longer at each end and 1.25 pixels
// to each side across its major axis; wire.frag decides which pixels the line owns.
// The line's pixels lie within 1/2 pixel of it across the major axis, so the proxy holds
// them with a margin far above GL's vertex snapping (1/256 pixel on llvmpipe).
//
// An edge shared by several triangles is one line (the same end points, so the same
// pixels and depths): only one of them draws it, the first in primitive order into the
// nearest z-buffer (LESS keeps the first of equal keys) and the last into the farthest
// (LEQUAL keeps the last), so the z-buffer holds exactly what drawing every copy left
// (u_owners: glvox.methods.binvox.solid.wire_owners).
layout(triangles) in;
layout(triangle_strip, max_vertices = 12) out;
#include "depth/view.glsl"
in vec3 v_vox[];
uniform ivec2 u_tile_origin;
uniform ivec2 u_target_size;
uniform bool u_far;
// per triangle (texel id % width, id / width): bit k set where it draws its edge k (vertex
// k -> k + 1), bits 0-2 into the nearest z-buffer, 3-5 into the farthest
uniform usampler2D u_owners;
flat out vec3 g_s;     // the end point with the smaller major coordinate (view space)
flat out vec3 g_e;     // the other
flat out int g_major;  // 0: u, 1: v
flat out uint g_id;

void emit(dvec2 p, vec3 s, vec3 e, int major) {
    g_s = s;
    g_e = e;
    g_major = major;
    g_id = uint(gl_PrimitiveIDIn);
    gl_Position = vec4(vec2(2.0 * p / dvec2(u_target_size) - 1.0), 0.0, 1.0);
    EmitVertex();
}

void main() {
    vec3 p[3] = vec3[3](to_view(v_vox[0]), to_view(v_vox[1]), to_view(v_vox[2]));
    dvec2 off = dvec2(u_tile_origin);
    int width = textureSize(u_owners, 0).x;
    uint own = texelFetch(u_owners, ivec2(gl_PrimitiveIDIn % width, gl_PrimitiveIDIn / width), 0).r
               >> (u_far ? 3u : 0u);
    for (int k = 0; k < 3; ++k) {
        if ((own & (1u << uint(k))) == 0u) continue;
        vec3 a = p[k], b = p[(k + 1) % 3];
        // differences of float32 values: exact in double, as in the reference
        double du = double(b.x) - double(a.x), dv = double(b.y) - double(a.y);
        int major = abs(du) >= abs(dv) ? 0 : 1;
        bool fwd = major == 0 ? a.x <= b.x : a.y <= b.y;
        vec3 s = fwd ? a : b, e = fwd ? b : a;
        dvec2 ds = dvec2(s.xy) - off, de = dvec2(e.xy) - off;
        if (ds[major] == de[major]) continue;  // parallel to the rays: no pixel
        dvec2 along = (de - ds) / (de[major] - ds[major]);  // 1 along the major axis
        dvec2 across = major == 0 ? dvec2(0.0, 1.25) : dvec2(1.25, 0.0);
        dvec2 s0 = ds - 0.5 * along, e0 = de + 0.5 * along;
        emit(s0 - across, s, e, major);
        emit(e0 - across, s, e, major);
        emit(s0 + across, s, e, major);
        emit(e0 + across, s, e, major);
        EndPrimitive();
    }
}
