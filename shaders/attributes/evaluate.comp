#version 450
// The attributes of every set voxel from its source triangle (attributes/pair.glsl
// found it), evaluated at the triangle's closest point to the voxel center:
// colour (face colour, vertex colours interpolated, or the texture sampled at
// the interpolated UV) and normal (the face's, or the interpolated vertex
// normals).  One invocation per grid word, at most 32 voxels each.
//   u_first: the first pass: every voxel's normal and the colour of every voxel
//   whose triangle samples no texture or texture u_tex_index; the next passes:
//   only the colour of voxels whose triangle samples texture u_tex_index (bound to
//   u_tex), one pass per further texture.  u_tex_index -1: no texture.
#include "attributes/closest.glsl"
layout(local_size_x = 64) in;
#include "common/dispatch.glsl"
layout(std430, binding = 1) readonly buffer VoxVerts { float vox[]; };
layout(std430, binding = 2) readonly buffer Faces { uint faces[]; };
layout(std430, binding = 11) readonly buffer BestTri { uint best_tri[]; };
layout(std430, binding = 12) readonly buffer SlotVoxel { uvec2 slot_voxel[]; };  // (i | j << 16, k)
// per face: colour source (glvox.visuals.COLOR_*), texture index, unused, face RGBA8
layout(std430, binding = 7) readonly buffer FaceInfo { uvec4 face_info[]; };
layout(std430, binding = 13) readonly buffer CornerUV { float corner_uv[]; };       // 6 per face
layout(std430, binding = 14) readonly buffer CornerColor { uint corner_color[]; };  // 3 RGBA8 per face
layout(std430, binding = 15) readonly buffer Normals { float normals[]; };  // face normal, then 3 corners: 12 per face
layout(std430, binding = 5) buffer OutColor { uint out_color[]; };
layout(std430, binding = 6) writeonly buffer OutNormal { float out_normal[]; };
uniform sampler2D u_tex;
uniform int u_tex_index;
uniform bool u_first;
uniform vec4 u_factor;
uniform uint u_slots;
uniform bool u_color;
uniform bool u_normal;
uniform bool u_vertex_normals;

const uint NONE = 0xFFFFFFFFu;

dvec3 vertex(uint i) { return dvec3(vox[3u * i], vox[3u * i + 1u], vox[3u * i + 2u]); }

vec3 normal_at(uint t, vec3 q) {
    uint o = 12u * t;
    if (!u_vertex_normals) return vec3(normals[o], normals[o + 1u], normals[o + 2u]);
    vec3 n = vec3(0.0);
    for (uint c = 0u; c < 3u; ++c)
        n += q[c] * vec3(normals[o + 3u + 3u * c], normals[o + 4u + 3u * c], normals[o + 5u + 3u * c]);
    float len = length(n);
    return len > 0.0 ? n / len : vec3(0.0);
}

uint color_at(uint t, vec3 q, uvec4 info) {
    if (info.x == 1u) return info.w;
    if (info.x == 2u) {
        vec4 c = q.x * unpackUnorm4x8(corner_color[3u * t]) + q.y * unpackUnorm4x8(corner_color[3u * t + 1u])
               + q.z * unpackUnorm4x8(corner_color[3u * t + 2u]);
        return packUnorm4x8(c);
    }
    if (info.x == 3u) {
        uint o = 6u * t;
        vec2 uv = q.x * vec2(corner_uv[o], corner_uv[o + 1u]) + q.y * vec2(corner_uv[o + 2u], corner_uv[o + 3u])
                + q.z * vec2(corner_uv[o + 4u], corner_uv[o + 5u]);
        return packUnorm4x8(textureLod(u_tex, uv, 0.0) * u_factor);
    }
    return 0u;
}

void main() {
    uint slot = global_index_1d();
    if (slot >= u_slots) return;
    uint t = best_tri[slot];
    uvec4 info = t == NONE ? uvec4(0u) : face_info[t];
    bool textured = info.x == 3u;
    bool this_texture = textured && int(info.y) == u_tex_index;
    if (!u_first && !this_texture) return;
    vec3 q = vec3(0.0);
    if (t != NONE) {
        uvec2 sv = slot_voxel[slot];
        dvec3 p = dvec3(ivec3(int(sv.x & 0xFFFFu), int(sv.x >> 16), int(sv.y))) + 0.5lf;
        q = vec3(closest_bary(p, vertex(faces[3u * t]), vertex(faces[3u * t + 1u]), vertex(faces[3u * t + 2u])));
    }
    if (u_color && (this_texture || (u_first && !textured))) out_color[slot] = t == NONE ? 0u : color_at(t, q, info);
    if (u_normal && u_first) {
        vec3 n = t == NONE ? vec3(0.0) : normal_at(t, q);
        out_normal[3u * slot] = n.x;
        out_normal[3u * slot + 1u] = n.y;
        out_normal[3u * slot + 2u] = n.z;
    }
}
