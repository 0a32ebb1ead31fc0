// The 2D winding numbers of gwn-solid's boundary chain (gwn/field.comp,
// gwn/bricks.comp): crossings of a half-line in the (y, z) plane, decided by
// the exact edge function of the crossings (gwn/strip.glsl's gwn_edge) on
// their fixed-point (y, z).  Include after the Edges block and vertex() (and,
// for chain_winding, the Nodes and Links blocks).

// One edge's part of the winding number of a closed polygon's (y, z)
// projection around c (counterclockwise positive, y right, z up: crossings of
// the half-line from c towards +y, half-open in z), by the exact edge
// function of the crossings; `tie` when c lies on the projected edge.
int edge_winding(vec2 a_, vec2 b_, vec2 c_, inout bool tie) {
    ivec2 a = solid_fixed(a_), b = solid_fixed(b_), c = solid_fixed(c_);
    if ((a.y <= c.y) != (b.y <= c.y)) {
        double f = gwn_edge(a, b, c);
        if (f == 0.0lf) tie = true;
        if (a.y <= c.y) return f > 0.0lf ? 1 : 0;
        return f < 0.0lf ? -1 : 0;
    }
    if (a.y == c.y && b.y == c.y && min(a.x, b.x) <= c.x && c.x <= max(a.x, b.x)) tie = true;
    return 0;
}

// The winding number of node n's closed polygons (its edges, a contiguous
// range, and its chord) projected on (y, z), around the row center c.
int node_winding(ivec4 lk, ivec4 chord, vec2 c, inout bool tie) {
    int wn = 0;
    for (int e = lk.x; e < lk.x + lk.y; ++e) {
        uvec2 ed = edges[e];
        wn += edge_winding(vertex(ed.x).yz, vertex(ed.y).yz, c, tie);
    }
    if (chord.x >= 0) wn += edge_winding(vertex(uint(chord.x)).yz, vertex(uint(chord.y)).yz, c, tie);
    return wn;
}

#ifdef GWN_CHAIN_WINDING
// The winding number of the whole boundary chain's (y, z) projection around
// c, by the tree from its root: a node whose disk misses c adds minus its
// chord's part (its closed polygons wind 0 times around c), a leaf under c
// its edges' parts.  T, a row's total signed crossings, is minus this.
int chain_winding(vec2 c, inout bool tie) {
    int wn = 0;
    int stack[64];  // as deep as the walks of gwn/field.comp (TREE_STACK)
    int sp = 0;
    stack[sp++] = 0;
    while (sp > 0) {
        int n = stack[--sp];
        vec4 cr = nodes[GWN_NODE_VEC4 * n];
        ivec4 lk = links[2 * n];
        ivec4 chord = links[2 * n + 1];
        vec2 d = cr.yz - c;
        if (dot(d, d) > cr.w * cr.w) {
            if (chord.x >= 0) wn -= edge_winding(vertex(uint(chord.x)).yz, vertex(uint(chord.y)).yz, c, tie);
        } else if (lk.z < 0) {
            for (int e = lk.x; e < lk.x + lk.y; ++e) {
                uvec2 ed = edges[e];
                wn += edge_winding(vertex(ed.x).yz, vertex(ed.y).yz, c, tie);
            }
        } else {
            stack[sp++] = lk.w;
            stack[sp++] = lk.z;
        }
    }
    return wn;
}
#endif
