// The distance from p to the triangle (0, ab, ac) in float: Ericson, Real-Time
// Collision Detection, Sec. 5.1.5 (the Voronoi regions of the vertices, edges
// and face), as attributes/closest.glsl does it in double.  sdf/band.comp uses
// it only to skip triangles that cannot be the nearest (with a slack far
// above its rounding); `precise` keeps compilers from contracting or
// reordering it, so the slack holds on every GPU.
float closest_distance_f(vec3 p, vec3 ab, vec3 ac) {
    precise float d1 = dot(ab, p), d2 = dot(ac, p);
    if (d1 <= 0.0 && d2 <= 0.0) return length(p);
    precise vec3 bp = p - ab;
    precise float d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) return length(bp);
    precise float vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return length(p - ab * (d1 / (d1 - d3)));
    precise vec3 cp = p - ac;
    precise float d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) return length(cp);
    precise float vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return length(p - ac * (d2 / (d2 - d6)));
    precise float va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0)
        return length(bp - (ac - ab) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))));
    precise float denom = 1.0 / (va + vb + vc);
    return length(p - ab * (vb * denom) - ac * (vc * denom));
}
