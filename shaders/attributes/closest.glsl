// The closest point of a triangle to a point, in double (Ericson, Real-Time
// Collision Detection, Sec. 5.1.5: the Voronoi regions of the vertices, edges
// and face).  glvox.reference.attributes finds it by another construction
// (plane projection, else the nearest edge) in float64; the tests compare them.
// Returns the barycentric weights of a, b, c.
dvec3 closest_bary(dvec3 p, dvec3 a, dvec3 b, dvec3 c) {
    dvec3 ab = b - a, ac = c - a, ap = p - a;
    double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0.0lf && d2 <= 0.0lf) return dvec3(1.0lf, 0.0lf, 0.0lf);
    dvec3 bp = p - b;
    double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.0lf && d4 <= d3) return dvec3(0.0lf, 1.0lf, 0.0lf);
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0lf && d1 >= 0.0lf && d3 <= 0.0lf) {
        double v = d1 / (d1 - d3);
        return dvec3(1.0lf - v, v, 0.0lf);
    }
    dvec3 cp = p - c;
    double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.0lf && d5 <= d6) return dvec3(0.0lf, 0.0lf, 1.0lf);
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0lf && d2 >= 0.0lf && d6 <= 0.0lf) {
        double w = d2 / (d2 - d6);
        return dvec3(1.0lf - w, 0.0lf, w);
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0.0lf && (d4 - d3) >= 0.0lf && (d5 - d6) >= 0.0lf) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return dvec3(0.0lf, 1.0lf - w, w);
    }
    double denom = 1.0lf / (va + vb + vc);
    double v = vb * denom, w = vc * denom;
    return dvec3(1.0lf - v - w, v, w);
}

// Distance from p to the point of barycentrics q on (a, b, c).
double bary_distance(dvec3 p, dvec3 a, dvec3 b, dvec3 c, dvec3 q) {
    return length(p - (q.x * a + q.y * b + q.z * c));
}
