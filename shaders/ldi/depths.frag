#version 450
// Leung & Wang 2013 Alg. 2 (DepthSampleRetrieval), one pass: LDI_LAYERS = 4 LDI_TARGETS
// layers [u_layer_lo, u_layer_lo + LDI_LAYERS) of every ray, blended with MAX.
//
// A fragment in cell z is classified by T1 and T2 (Sec. III-B): entering voxel (EV,
// T1(z) = 1, T1(z-1) = 0), leaving voxel (LV, 0 and 1), entering-leaving voxel (ELV, both 0
// and T2(z) = 1); leaving-entering voxels (LEV, both 1) are taken as solid and their
// fragments dropped, as are those of cells with no sample.  Its layer p is the number of
// samples in front of its cell (fast bit checking, Eq. 5).  An EV keeps its nearest
// fragment, an LV its farthest, an ELV both: with normalized depth d in [0, 1], the nearest
// is the MAX of 1 - d (Eq. 6: entering samples sit at even layers here, counting from 0),
// the farthest the MAX of d.  Values are rounded up to float32, so after decoding the
// entering sample is at most and the leaving sample at least the computed crossing.
//
// The mesh drawn is the true one moved by at most m voxel per coordinate: u_motion for
// the float32 upload (glvox.methods.ldi.leung_wang_passes.mesh_motion) plus the largest
// move of the plane snap among the triangle's vertices (common/transform.comp).
// Every true vertex lies in the box of that half-side around its drawn one, so the true
// triangle lies in the drawn one plus that box, and the true crossing of a ray the drawn
// triangle covers lies within  m_a + m (|n_u| + |n_v|) / |n_a|  of the drawn crossing
// (m_a = m in cells along the ray; n of the drawn triangle in this frame), within the
// drawn triangle's extent along the ray grown by m_a, and within m_a of the extent of
// the drawn triangle's points whose projection lies within m of the center (on a steep
// triangle, where the first bound exceeds a cell: eis_section).  The samples are moved outwards by
// that much (entering earlier, leaving later), so the LDI encloses the true mesh's
// intervals on every ray whose coverage the motion cannot change (Leung & Wang's claim is
// per ray), not only the snapped mesh's; on a steep triangle a snap of 2^-11 voxel across
// the ray moves the crossing by far more.  The cell z stays the drawn crossing's, as in T1
// and T2.
#include "eisemann/column.glsl"
#include "ldi/column.glsl"

uniform ivec2 u_tile_lo;
uniform int u_layer_lo;
uniform double u_motion;           // voxels per coordinate: the float32 upload's rounding
layout(std430, binding = 6) readonly buffer Motion { float motion[]; };  // the snap's, per vertex
uniform double u_cells_per_voxel;  // LOD-C / n_axis

flat in uint v_tri;

layout(location = 0) out vec4 o_depths[LDI_TARGETS];
#define TARGETS_N LDI_TARGETS
#include "common/each_target.glsl"

void main() {
    dvec3 p0, p1, p2;
    eis_triangle(v_tri, p0, p1, p2);
    dvec3 n = eis_normal(p0, p1, p2);
    ivec2 pix = ivec2(gl_FragCoord.xy) + u_tile_lo;
    dvec2 c = dvec2(pix) + 0.5;
    dvec3 w;
    if (!eis_covers_at(p0, p1, p2, c, w)) discard;
    double qc = ldi_cell_depth(eis_crossing(p0, p1, p2, w));
    int z = ldi_cell(qc);
    uint col = ldi_column(pix);
    bool here = ldi_t1_bit(col, z);
    bool before = ldi_t1_bit(col, z - 1);
    bool ev = here && !before;
    bool lv = !here && before;
    bool elv = !here && !before && ldi_t2_bit(col, z);
    if (!(ev || lv || elv)) discard;
    int s0 = ldi_layers_ahead(col, z) - u_layer_lo;
    int s1 = elv ? s0 + 1 : -1;
    bool first_here = s0 >= 0 && s0 < LDI_LAYERS;
    bool second_here = s1 >= 0 && s1 < LDI_LAYERS;
    if (!(first_here || second_here)) discard;
    double m = u_motion + double(max(motion[eis_faces[3u * v_tri]],
                                     max(motion[eis_faces[3u * v_tri + 1u]], motion[eis_faces[3u * v_tri + 2u]])));
    double ma = m * u_cells_per_voxel;
    // 2^-30 cell: far above the double rounding of the crossing and of the bound itself
    // |n_a| from the exact edge functions (in units of 2^-2F voxel^2): never 0 where covered
    double unit = eis_unit();
    double n_a = (w.x + w.y + w.z) * unit * unit;
    double widen = ma + m * (abs(n.x) + abs(n.y)) / n_a + 1.0 / 1073741824.0;
    double zlo = ldi_cell_depth(min(p0.z, min(p1.z, p2.z))) - ma;
    double zhi = ldi_cell_depth(max(p0.z, max(p1.z, p2.z))) + ma;
    if (widen > 1.0) {
        // a steep triangle: the true crossing is also within m_a of the drawn triangle's
        // points whose projection lies within m of the center, in the slab of half-width
        // m sqrt(2) across its longest edge (the box's reach along any direction)
        dvec2 s = eis_section(p0, p1, p2, c, m * 1.4142135623730951 + 1.0 / 1073741824.0);
        zlo = max(zlo, ldi_cell_depth(s.x) - ma - 1.0 / 1073741824.0);
        zhi = min(zhi, ldi_cell_depth(s.y) + ma + 1.0 / 1073741824.0);
    }
    double d_near = clamp(max(qc - widen, zlo) / double(u_cells), 0.0, 1.0);
    double d_far = clamp(min(qc + widen, zhi) / double(u_cells), 0.0, 1.0);
    float near_key = ldi_round_up(1.0 - d_near);  // entering: the MAX of 1 - d is the nearest
    float far_key = ldi_round_up(d_far);          // leaving: the MAX of d is the farthest
    // layer s0 (if first_here) gets the first key, s1 (if second_here) the far key, the
    // others 0; per target by constant index (common/each_target.glsl)
    ivec4 first_at = ivec4(first_here ? s0 : -1), second_at = ivec4(second_here ? s1 : -1);
    float first_key = lv ? far_key : near_key;
#define LDI_DEPTHS_OUT(t) { \
        ivec4 layer = ivec4(4 * t) + ivec4(0, 1, 2, 3); \
        o_depths[t] = mix(mix(vec4(0.0), vec4(first_key), equal(layer, first_at)), vec4(far_key), \
                          equal(layer, second_at)); }
    EACH_TARGET(LDI_DEPTHS_OUT)
}
