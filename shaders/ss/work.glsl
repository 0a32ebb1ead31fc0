// How much work a triangle is, in the units its voxelization loop steps
// through: voxels for the simple variant and 1D boxes, voxel columns
// otherwise.  Work is split into chunks of SS_CHUNK units, one invocation
// per chunk, so that no invocation runs more than a bounded number of loop
// iterations (Mesa's llvmpipe silently stops an invocation after about 65535
// iterations in total; see LOOP_BUDGET in glvox/methods/_gpu.py).

ivec3 bbox_size(Tri T) { return T.hi - T.lo + 1; }

// The thin axis of a 2D box and the dominant axis of a 3D triangle.
int case_axis(Tri T, int type) {
    if (type == 2) return dominant_axis(T.n);
    return T.ext.x == 1 ? 0 : (T.ext.y == 1 ? 1 : 2);
}

// Zero area in float32, or a sliver (setup.glsl): no dominant axis to trust, so the
// voxels of the box get the full test (without the plane test for a sliver).
bool degenerate(Tri T) { return all(equal(T.n, vec3(0.0))) || T.no_plane; }

uint work_units(Tri T, int type) {
    ivec3 s = bbox_size(T);
    if (degenerate(T)) return uint(s.x) * uint(s.y) * uint(s.z);
#if SS_CRITERION == 1
    int w = dominant_axis(T.n);
    return uint(s[(w + 1) % 3]) * uint(s[(w + 2) % 3]);
#elif SS_VARIANT == 0
    return uint(s.x) * uint(s.y) * uint(s.z);
#else
    if (type == 0) return uint(s.x) * uint(s.y) * uint(s.z);
    int c = case_axis(T, type);
    return uint(s[(c + 1) % 3]) * uint(s[(c + 2) % 3]);
#endif
}

uint chunks_of(uint work) { return (work + uint(SS_CHUNK) - 1u) / uint(SS_CHUNK); }
