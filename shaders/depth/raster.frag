#version 450
// Passalis et al. 2006, Sec. 2-3: one z-buffer of a view.  A fragment is a crossing of
// the column's ray (its pixel center) with the triangle, decided as the reference decides
// it, in integers on the fixed point of depth/raster.geom (common/fixed.glsl); its crossing
// depth q is the barycentric combination of the vertices' depths with the exact edge
// functions as weights, in double, in voxel units.
//
// The depth test orders crossings by a key (depth/key.glsl), reversed with u_far, so that
// the test keeps the farthest crossing: the view from the opposite face of the bounding
// box; there it is LEQUAL, so of equal keys the last in primitive order wins, and a
// class's nearest and farthest crossings differ whenever it has two.
//
// Depth peeling (Sec. 3.3): the previous layer of the same facing class is held in a
// texture, and a fragment passes only when its (key, triangle id) is larger than the
// previous layer's.  The id breaks ties between crossings with equal keys: the depth test
// keeps the first of equal keys in primitive order, i.e. the smallest id, so the layers
// enumerate every crossing of a column exactly once, however close two of them are.
#include "depth/cover.glsl"
#include "depth/key.glsl"
flat in vec3 g_p0;
flat in vec3 g_p1;
flat in vec3 g_p2;
flat in ivec2 g_f0;
flat in ivec2 g_f1;
flat in ivec2 g_f2;
flat in int g_sgn;
flat in double g_inv_area2;
flat in uint g_id;
uniform int u_fix_bits;
uniform ivec2 u_target_size;  // also the geometry stage's: see main
uniform ivec2 u_tile_origin;
uniform bool u_peel;
uniform usampler2D u_prev;   // previous layer: (key bits, id, slot, valid)
// The layer: key bits, triangle id, the first voxel whose center lies beyond the crossing
// (reference: voxel i flips iff i + 1/2 > q, i.e. i >= floor(q + 1/2)), clamped to
// [0, u_depth_n] with u_depth_n meaning "beyond the grid", and w != 0 = a crossing is here:
// w = floor(q) + 2 with floor(q) clamped to [-1, u_depth_n], so w - 2 is the voxel holding
// the crossing when it lies in [0, u_depth_n) (binvox-solid's surface; 0 is never written).
layout(location = 0) out uvec4 o_layer;

// The crossing's depth: the vertices' depths weighted by w, clamped to the triangle's
// extent (outside it only by rounding).
// exact: one formula on exact weights
double crossing(dvec3 a, dvec3 b, dvec3 d, dvec3 w) {
    precise double q = a.z + (w.x * (d.z - a.z) + w.z * (b.z - a.z)) * g_inv_area2;
    return clamp(q, min(a.z, min(b.z, d.z)), max(a.z, max(b.z, d.z)));
}

void main() {
    // The clamp changes no pixel on a conforming GL (the target is the viewport).  It makes
    // the view's size a uniform of this stage too: softpipe drew nothing in a view when only
    // the geometry stage's uniforms changed from a view of another size
    // (tests/test_drivers.py).  A discard there instead cost llvmpipe up to 20%.
    ivec2 pix = min(ivec2(gl_FragCoord.xy), u_target_size - 1);
    ivec2 cf = fixed_center(pix + u_tile_origin, u_fix_bits);
    dvec3 a = dvec3(g_p0), b = dvec3(g_p1), d = dvec3(g_p2);
    dvec3 w;
    if (!covers(ivec2[3](g_f0, g_f1, g_f2), g_sgn, cf, w)) discard;
    double q = crossing(a, b, d, w);
    uint code = depth_code(q);
    uint slot = code_slot(code);
    float key = depth_key(code);
    if (u_peel) {
        uvec4 prev = texelFetch(u_prev, pix, 0);
        if (prev.w == 0u) discard;  // the previous layer was empty: so is this one
        float kp = uintBitsToFloat(prev.x);
        if (!(key > kp || (key == kp && g_id > prev.y))) discard;
    }
    gl_FragDepth = key;
    uint holder = uint(clamp(floor(q), -1.0lf, double(u_depth_n)) + 2.0lf);
    o_layer = uvec4(floatBitsToUint(key), g_id, slot, holder);
}
