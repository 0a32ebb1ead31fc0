#version 450
// Depth-peeling LDI: record one peeled layer (depth/raster.frag's RGBA32UI layer: key bits,
// triangle id, first voxel beyond, valid) as the layer's depth in voxel units.  The depth is
// recomputed from the triangle id in double exactly as depth/raster.frag computes it (the
// same snapped float32 voxel-space vertices as depth/raster.vert, the plane at the pixel center,
// clamped to the triangle's extent), then clamped to the grid [0, n_axis] and rounded to
// float32.  Peeling orders crossings by (float32 key, triangle id); crossings whose keys
// tie can come out of depth order by less than a key step, so each ray keeps the running
// maximum: the samples are sorted.
layout(local_size_x = 8, local_size_y = 8) in;
#include "depth/view.glsl"
#include "ldi/pixels.glsl"
#include "common/snap.glsl"

uniform usampler2D u_layer;
uniform ivec2 u_tile_origin;
uniform int u_layer_index;
uniform int u_chunk_lo;
uniform int u_chunk_layers;
uniform int u_depth_n;
uniform dvec3 u_origin_d;
uniform double u_inv_h_d;
layout(std430, binding = 0) readonly buffer Verts { float verts[]; };  // world, relative to the anchor
layout(std430, binding = 1) readonly buffer Faces { uint faces[]; };
layout(std430, binding = 2) writeonly buffer Depths { float depths[]; };  // this chunk
layout(std430, binding = 3) buffer Last { float last[]; };               // per ray
layout(std430, binding = 6) buffer Counts { uint counts[]; };

vec3 vertex(uint vi) {
    vec3 p = vec3(verts[3u * vi], verts[3u * vi + 1u], verts[3u * vi + 2u]);
    return to_view(vec3(vertex_to_voxel(p, u_origin_d, u_inv_h_d)));
}

// exact: depth/raster.frag's crossing, in its order (cross() written out)
double peel_crossing(dvec3 a, dvec3 b, dvec3 d, dvec2 c) {
    precise dvec3 e0 = b - a, e1 = d - a;
    precise dvec3 n = dvec3(e0.y * e1.z - e0.z * e1.y, e0.z * e1.x - e0.x * e1.z, e0.x * e1.y - e0.y * e1.x);
    precise double q = a.z + (n.x * (a.x - c.x) + n.y * (a.y - c.y)) / n.z;
    return clamp(q, min(a.z, min(b.z, d.z)), max(a.z, max(b.z, d.z)));
}

void main() {
    ivec2 pix = ivec2(gl_GlobalInvocationID.xy);
    ivec2 uv = pix + u_tile_origin;
    if (any(greaterThanEqual(pix, textureSize(u_layer, 0))) || any(greaterThanEqual(uv, u_grid_uv))) return;
    uvec4 layer = texelFetch(u_layer, pix, 0);
    if (layer.w == 0u) return;
    uint t = layer.y;
    dvec3 a = dvec3(vertex(faces[3u * t]));
    dvec3 b = dvec3(vertex(faces[3u * t + 1u]));
    dvec3 d = dvec3(vertex(faces[3u * t + 2u]));
    dvec2 c = dvec2(uv) + 0.5;
    double q = clamp(peel_crossing(a, b, d, c), 0.0, double(u_depth_n));
    uint col = ldi_column(uv);
    float v = u_layer_index == 0 ? float(q) : max(float(q), last[col]);
    last[col] = v;
    depths[col * uint(u_chunk_layers) + uint(u_layer_index - u_chunk_lo)] = v;
    counts[col] = uint(u_layer_index + 1);
}
