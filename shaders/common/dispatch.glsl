// The flat invocation index of a 1D job dispatched by glvox.methods._gpu.dispatch_1d,
// which splits more than GL_MAX_COMPUTE_WORK_GROUP_COUNT groups along y.
// Include it after the local_size layout: gl_WorkGroupSize exists only then.
uint global_index_1d() {
    return gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x;
}

// The indirect dispatch of n invocations in groups of local_size, as
// glvox.gpu.dispatch.dispatch_1d lays out a direct one: more than max_groups
// groups are split along y (global_index_1d numbers them back).  (x, y, 1).
uvec3 dispatch_args_1d(uint n, uint local_size, uint max_groups) {
    uint groups = (n + local_size - 1u) / local_size;
    uint x = min(groups, max_groups);
    return uvec3(x, x == 0u ? 0u : (groups + x - 1u) / x, 1u);
}
