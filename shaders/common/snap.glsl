// The one world -> voxel transform of every GPU method, with the plane snap
// (glvox.gpu.transform.gpu_vertices_voxel repeats it in numpy, bit for bit).
//
// snap_to_planes is glvox.grid.snap_to_planes with the same operations in
// double: a voxel-space coordinate within SNAP_EPS of a multiple of 1/2 (a
// voxel face plane or a voxel center plane) is moved onto it before the
// float32 rounding, so geometry on those planes up to rounding lies exactly on
// them for every method and reference alike (README, "Ties").  SNAP_EPS is
// glvox.tolerances.SNAP_EPS, injected by the caller
// (glvox.gpu.transform.SNAP_DEFINES); a power of two, exact as a literal.
#ifndef SNAP_EPS
#error "SNAP_EPS is not defined: pass glvox.gpu.transform.SNAP_DEFINES to the program"
#endif

// exact: bit for bit glvox.grid.snap_to_planes
dvec3 snap_to_planes(dvec3 p) {
    precise dvec3 r = floor(2.0lf * p + 0.5lf) * 0.5lf;
    precise dvec3 gap = p - r;
    return mix(p, r, lessThanEqual(abs(gap), dvec3(SNAP_EPS)));
}

// A vertex uploaded as float32 relative to the mesh's anchor, in voxel space:
// (p - origin) / h in double (origin relative to the anchor, inv_h = 1 / h),
// snapped.  Double, not float32: the float32 upload is then the only rounding
// before the snap (2^-25 N voxel at most for a grid of N voxels fitted to the
// mesh), well inside SNAP_EPS.
// exact: bit for bit glvox.gpu.transform.gpu_vertices_voxel
dvec3 vertex_to_voxel(vec3 p, dvec3 origin, double inv_h) {
    precise dvec3 v = (dvec3(p) - origin) * inv_h;
    return snap_to_planes(v);
}
