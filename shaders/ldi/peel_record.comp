#version 450
// Depth-peeling LDI: record one peeled layer (depth/raster.frag's RGBA32UI layer: key bits,
// triangle id, first voxel beyond, valid) as the layer's depth in voxel units.  The depth is
// recomputed from the triangle id exactly as depth/raster.frag computes it (the same snapped
// float32 voxel-space vertices as depth/raster.vert, (u, v) in its fixed point, the depths
// weighted by the exact edge functions at the pixel center, clamped to the triangle's
// extent), then clamped to the grid [0, n_axis] and rounded to float32.  Peeling orders
// crossings by (float32 key, triangle id); crossings whose keys tie can come out of depth
// order by less than a key step, so each ray keeps the running maximum: the samples are
// sorted.
layout(local_size_x = 8, local_size_y = 8) in;
#include "depth/view.glsl"
#include "ldi/pixels.glsl"
#include "common/snap.glsl"
#include "common/fixed.glsl"

uniform usampler2D u_layer;
uniform ivec2 u_tile_origin;
uniform int u_layer_index;
uniform int u_chunk_lo;
uniform int u_chunk_layers;
uniform int u_depth_n;
uniform dvec3 u_origin_d;
uniform double u_inv_h_d;
uniform int u_fix_bits;  // depth/raster.geom's F for this view
layout(std430, binding = 0) readonly buffer Verts { float verts[]; };  // world, relative to the anchor
layout(std430, binding = 1) readonly buffer Faces { uint faces[]; };
layout(std430, binding = 2) writeonly buffer Depths { float depths[]; };  // this chunk
layout(std430, binding = 3) buffer Last { float last[]; };               // per ray
layout(std430, binding = 6) buffer Counts { uint counts[]; };

vec3 vertex(uint vi) {
    vec3 p = vec3(verts[3u * vi], verts[3u * vi + 1u], verts[3u * vi + 2u]);
    return to_view(vec3(vertex_to_voxel(p, u_origin_d, u_inv_h_d)));
}

// depth/raster.frag's crossing at the column center cf (units of 2^-F), in its order: the
// weights are the oriented edge functions of the vertices' (u, v) in the fixed point,
// the divisor twice the projected area, each rounded once (as depth/raster.geom).
// exact: depth/raster.frag's crossing
double peel_crossing(vec3 a, vec3 b, vec3 d, ivec2 cf) {
    ivec2 f[3] = ivec2[3](fixed_point(a.xy, u_fix_bits), fixed_point(b.xy, u_fix_bits), fixed_point(d.xy, u_fix_bits));
    int sgn, s;
    double area2 = abs(fixed_det(f[1].x - f[0].x, f[2].y - f[0].y, f[1].y - f[0].y, f[2].x - f[0].x, sgn));
    double inv_area2 = 1.0lf / area2;
    dvec3 w;
    for (int i = 0; i < 3; ++i) w[i] = fixed_edge(f[i], f[(i + 1) % 3], cf, s) * double(sgn);
    dvec3 p = dvec3(a.z, b.z, d.z);
    precise double q = p.x + (w.x * (p.z - p.x) + w.z * (p.y - p.x)) * inv_area2;
    return clamp(q, min(p.x, min(p.y, p.z)), max(p.x, max(p.y, p.z)));
}

void main() {
    ivec2 pix = ivec2(gl_GlobalInvocationID.xy);
    ivec2 uv = pix + u_tile_origin;
    if (any(greaterThanEqual(pix, textureSize(u_layer, 0))) || any(greaterThanEqual(uv, u_grid_uv))) return;
    uvec4 layer = texelFetch(u_layer, pix, 0);
    if (layer.w == 0u) return;
    uint t = layer.y;
    vec3 a = vertex(faces[3u * t]);
    vec3 b = vertex(faces[3u * t + 1u]);
    vec3 d = vertex(faces[3u * t + 2u]);
    double q = clamp(peel_crossing(a, b, d, fixed_center(uv, u_fix_bits)), 0.0, double(u_depth_n));
    uint col = ldi_column(uv);
    float v = u_layer_index == 0 ? float(q) : max(float(q), last[col]);
    last[col] = v;
    depths[col * uint(u_chunk_layers) + uint(u_layer_index - u_chunk_lo)] = v;
    counts[col] = uint(u_layer_index + 1);
}
