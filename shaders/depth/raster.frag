#version 450
// Passalis et al. 2006, Sec. 2-3: one z-buffer of a view.  A fragment is a crossing of
// the column's ray (its pixel center) with the triangle, decided as the reference decides
// it; its crossing depth q is computed from the triangle's plane in double, in voxel units.
//
// The depth test orders crossings by a key: (q - u_key_lo) * u_key_scale rounded to float,
// monotone in q and inside (0, 1) for the whole mesh (reversed with u_far, so that the test
// keeps the farthest crossing: the view from the opposite face of the bounding box; there
// it is LEQUAL, so of equal keys the last in primitive order wins, and a class's nearest and
// farthest crossings differ whenever it has two).  The key is written as gl_FragDepth into
// a 32-bit float depth buffer, which stores it unchanged.
//
// Depth peeling (Sec. 3.3): the previous layer of the same facing class is held in a
// texture, and a fragment passes only when its (key, triangle id) is larger than the
// previous layer's.  The id breaks ties between crossings with equal keys: the depth test
// keeps the first of equal keys in primitive order, i.e. the smallest id, so the layers
// enumerate every crossing of a column exactly once, however close two of them are.
flat in vec3 g_p0;
flat in vec3 g_p1;
flat in vec3 g_p2;
flat in double g_na;
flat in uint g_id;
uniform ivec2 u_tile_origin;
uniform int u_depth_n;       // voxels along the rays
uniform double u_key_lo;
uniform double u_key_scale;
uniform bool u_far;
uniform bool u_peel;
uniform usampler2D u_prev;   // previous layer: (key bits, id, slot, valid)
// The layer: key bits, triangle id, the first voxel whose center lies beyond the crossing
// (reference: voxel i flips iff i + 1/2 > q, i.e. i >= floor(q + 1/2)), clamped to
// [0, u_depth_n] with u_depth_n meaning "beyond the grid", and w != 0 = a crossing is here:
// w = floor(q) + 2 with floor(q) clamped to [-1, u_depth_n], so w - 2 is the voxel holding
// the crossing when it lies in [0, u_depth_n) (binvox-solid's surface; 0 is never written).
layout(location = 0) out uvec4 o_layer;

// Edge function of p -> q at c, evaluated from the lexicographically smaller end point and
// negated when the edge runs the other way, so the two triangles of a shared edge get
// exactly opposite values (as glvox.reference.solid does).
// exact: opposite values for the two triangles of an edge (the reference's)
double edge_function(dvec2 p, dvec2 q, dvec2 c) {
    bool swap = p.x > q.x || (p.x == q.x && p.y > q.y);
    dvec2 s = swap ? q : p;
    dvec2 t = swap ? p : q;
    precise double f = (t.x - s.x) * (c.y - s.y) - (t.y - s.y) * (c.x - s.x);
    return swap ? -f : f;
}

// Center c belongs to the projected triangle on the inner side of edge p -> q, with the
// top-left rule for centers exactly on it (sgn orients the triangle counter-clockwise).
// exact: the reference's coverage test with the top-left rule
bool owns(dvec2 p, dvec2 q, dvec2 c, double sgn) {
    precise double f = edge_function(p, q, c) * sgn;
    precise dvec2 e = q - p;
    precise double neu = -e.y * sgn;
    precise double nev = e.x * sgn;
    bool top_left = neu > 0.0 || (neu == 0.0 && nev < 0.0);
    return f > 0.0 || (f == 0.0 && top_left);
}

// exact: the crossing, in the reference's order; clamped to the triangle's extent
// (the exact crossing lies within it; this only removes rounding)
double crossing(dvec3 a, dvec3 b, dvec3 d, dvec2 c) {
    precise dvec3 e0 = b - a, e1 = d - a;
    precise dvec3 n = dvec3(e0.y * e1.z - e0.z * e1.y, e0.z * e1.x - e0.x * e1.z, e0.x * e1.y - e0.y * e1.x);
    precise double q = a.z + (n.x * (a.x - c.x) + n.y * (a.y - c.y)) / g_na;
    return clamp(q, min(a.z, min(b.z, d.z)), max(a.z, max(b.z, d.z)));
}

void main() {
    ivec2 pix = ivec2(gl_FragCoord.xy);
    dvec2 c = dvec2(pix + u_tile_origin) + 0.5;
    dvec3 a = dvec3(g_p0), b = dvec3(g_p1), d = dvec3(g_p2);
    double sgn = g_na > 0.0 ? 1.0 : -1.0;
    if (!(owns(a.xy, b.xy, c, sgn) && owns(b.xy, d.xy, c, sgn) && owns(d.xy, a.xy, c, sgn))) {
        discard;
    }
    double q = crossing(a, b, d, c);
    precise double kd = (q - u_key_lo) * u_key_scale;
    float key = float(kd);
    if (u_far) key = 1.0 - key;
    if (u_peel) {
        uvec4 prev = texelFetch(u_prev, pix, 0);
        if (prev.w == 0u) discard;  // the previous layer was empty: so is this one
        float kp = uintBitsToFloat(prev.x);
        if (!(key > kp || (key == kp && g_id > prev.y))) discard;
    }
    precise double first = floor(q + 0.5);
    uint slot = first >= double(u_depth_n) ? uint(u_depth_n) : uint(max(first, 0.0lf));
    gl_FragDepth = key;
    uint holder = uint(clamp(floor(q), -1.0lf, double(u_depth_n)) + 2.0lf);
    o_layer = uvec4(floatBitsToUint(key), g_id, slot, holder);
}
