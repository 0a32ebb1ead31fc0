// The flat invocation index of a 1D job dispatched by glvox.methods._gpu.dispatch_1d,
// which splits more than GL_MAX_COMPUTE_WORK_GROUP_COUNT groups along y.
// Include it after the local_size layout: gl_WorkGroupSize exists only then.
uint global_index_1d() {
    return gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x;
}
