// The column test of the depth-buffer passes (depth/raster.frag, and depth/raster.geom's
// cull), on the fixed point of depth/raster.geom (common/fixed.glsl).
#include "common/fixed.glsl"

// Does the triangle f (sgn: its orientation) cover the column center cf (units)?  A
// center on an edge counts for a top-left edge only, so a center on an edge shared by
// two triangles counts once.  w: the oriented edge functions there (edge i weighs
// vertex i + 2), each rounded once.
// exact: the reference's coverage test with the top-left rule, in integers
bool covers(ivec2 f[3], int sgn, ivec2 cf, out dvec3 w) {
    for (int i = 0; i < 3; ++i) {
        int s;
        w[i] = fixed_edge(f[i], f[(i + 1) % 3], cf, s) * double(sgn);
        s *= sgn;
        if (!(s > 0 || (s == 0 && fixed_top_left(f, i, sgn)))) return false;
    }
    return true;
}

