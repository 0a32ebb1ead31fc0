// Voxel columns along the render axis and the triangles crossing them
// (Eisemann & Decoret 2008, as described in Leung & Wang 2013 Sec. III-A and
// Schwarz & Seidel 2010 Sec. 2), shared by the vertex and fragment stages.
//
// Needs EIS_AXIS (0, 1, 2: the render axis a).  The pixel grid is the plane
// (u, v) = ((a + 1) % 3, (a + 2) % 3), the same plane and orientation as the
// CPU reference (glvox/reference/solid.py), so pixel (i, j) is the voxel column
// whose center is at (i + 0.5, j + 0.5) in voxel units: pixel centers are
// column centers.
//
// Precision.  Vertices arrive in voxel space as doubles (common/transform.comp with VOX_DOUBLE),
// computed from the float32 upload relative to the mesh's anchor: the mesh the
// GPU sees is the true one moved by at most 2^-24 * N/2 voxel (3e-5 voxel at
// N = 1024), below TIE_EPS (1e-4).  Everything below is evaluated in double, so
// its own rounding (~1e-13 voxel) only matters for centers closer than that to
// the surface.  The coverage test and the crossing are the reference's formulas
// (edge functions from the lexicographically smaller end point, negated when
// the edge runs the other way, so two triangles sharing an edge get exactly
// opposite values; top-left fill rule for centers on an edge).  Hence the GPU
// computes the exact parity solid of a mesh moved by less than TIE_EPS, and a
// voxel it classifies differently from the float64 reference has its center
// within TIE_EPS of the surface: a tie (glvox.reference.solid_ties).

layout(std430, binding = 0) readonly buffer EisVox { double eis_vox[]; };  // voxel space, xyz per vertex
layout(std430, binding = 1) readonly buffer EisFaces { uint eis_faces[]; };

const int EIS_U = (EIS_AXIS + 1) % 3;
const int EIS_V = (EIS_AXIS + 2) % 3;

// Vertex vi as (u, v, a).
dvec3 eis_vertex(uint vi) {
    uint b = 3u * vi;
    return dvec3(eis_vox[b + uint(EIS_U)], eis_vox[b + uint(EIS_V)], eis_vox[b + uint(EIS_AXIS)]);
}

void eis_triangle(uint t, out dvec3 p0, out dvec3 p1, out dvec3 p2) {
    p0 = eis_vertex(eis_faces[3u * t]);
    p1 = eis_vertex(eis_faces[3u * t + 1u]);
    p2 = eis_vertex(eis_faces[3u * t + 2u]);
}

// The triangle's normal (cross(p1 - p0, p2 - p0)) in (u, v, a) order.
// exact: as the reference's normal
dvec3 eis_normal(dvec3 p0, dvec3 p1, dvec3 p2) {
    precise dvec3 e0 = p1 - p0;
    precise dvec3 e1 = p2 - p0;
    precise dvec3 n = dvec3(e0.y * e1.z - e0.z * e1.y, e0.z * e1.x - e0.x * e1.z, e0.x * e1.y - e0.y * e1.x);
    return n;
}

// Edge function of p -> q at c, evaluated from the lexicographically smaller
// end point (see the precision note above); `precise` keeps the compiler from
// contracting it differently in two places.
// exact: opposite values for the two triangles of an edge
double eis_edge(dvec2 p, dvec2 q, dvec2 c) {
    bool swap = p.x > q.x || (p.x == q.x && p.y > q.y);
    dvec2 a = swap ? q : p;
    dvec2 b = swap ? p : q;
    precise double f = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    return swap ? -f : f;
}

// The projected triangle's orientation: +1 counter-clockwise (the normal's a
// component positive), else -1.
double eis_orientation(double n_a) { return n_a > 0.0 ? 1.0 : -1.0; }

// Edge i (p[i] -> p[i + 1]) of the projected triangle p at c, oriented by sgn
// so that the inside is positive.
// exact: eis_edge's value times +-1
double eis_edge_at(dvec2 p[3], int i, double sgn, dvec2 c) {
    precise double f = eis_edge(p[i], p[(i + 1) % 3], c) * sgn;
    return f;
}

// Does edge i own the centers exactly on it?  Only a left edge (inward normal
// n_u > 0) or a top edge (n_u == 0, n_v < 0) does.
// exact: a difference, negations and products by +-1
bool eis_top_left(dvec2 p[3], int i, double sgn) {
    precise dvec2 e = p[(i + 1) % 3] - p[i];
    precise double nu = -e.y * sgn;
    precise double nv = e.x * sgn;
    return nu > 0.0 || (nu == 0.0 && nv < 0.0);
}

// Is the column center c inside the projected triangle?  A center on an edge
// counts only for a top-left edge: each center on a shared edge counts exactly
// once.  (testing/tie_probe.glsl reads the same edge values and flags.)
// exact: the reference's coverage test
bool eis_covers(dvec3 p0, dvec3 p1, dvec3 p2, double n_a, dvec2 c) {
    double sgn = eis_orientation(n_a);
    dvec2 p[3] = dvec2[3](p0.xy, p1.xy, p2.xy);
    for (int i = 0; i < 3; ++i) {
        double f = eis_edge_at(p, i, sgn, c);
        if (!(f > 0.0 || (f == 0.0 && eis_top_left(p, i, sgn)))) return false;
    }
    return true;
}

// Where the column through c crosses the triangle's plane, along a (voxel
// units), clamped to the triangle's extent along a as the reference does
// (it only removes rounding on nearly edge-on triangles).
// exact: the reference's crossing formula, in its order
double eis_crossing(dvec3 p0, dvec3 p1, dvec3 p2, dvec3 n, dvec2 c) {
    precise double q = p0.z + (n.x * (p0.x - c.x) + n.y * (p0.y - c.y)) / n.z;
    return clamp(q, min(min(p0.z, p1.z), p2.z), max(max(p0.z, p1.z), p2.z));
}

// A double voxel coordinate as an int, clamped first so that far-away geometry
// cannot overflow the conversion (callers only compare with grid indices).
int eis_to_int(double x) { return int(clamp(x, -2.0, 1073741824.0)); }

// First slice a crossing at q flips: voxel k flips iff its center k + 0.5 > q.
// exact: one rounding-free addition
int eis_first_flipped(double q) {
    precise double f = floor(q + 0.5);
    return eis_to_int(f);
}

// The slice holding the crossing point (the voxel whose [k, k+1] contains q;
// a crossing on the face k belongs to slice k).  On the grid's far face (q = n,
// n slices) it belongs to the last slice, the one voxel inside the grid that the
// face touches: geometry on the grid's boundary planes is voxelized like geometry
// inside, so a face there (the default fit puts the bounding box on them) keeps
// its wall.
int eis_slice_of(double q, int n) { return q == double(n) ? n - 1 : eis_to_int(floor(q)); }
