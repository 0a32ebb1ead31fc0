#version 450
// Depth-peeling LDI (the exact baseline): the largest stencil count of the first pass of a
// tile, i.e. the most crossings on one of its rays (saturating at 255), so the host knows
// how many peeling passes to run (Passalis et al. 2006 Sec. 3.3, as passalis-peel does).
layout(local_size_x = 8, local_size_y = 8) in;
uniform usampler2D u_stencil;
layout(std430, binding = 7) buffer Stats { uint stats[]; };
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, textureSize(u_stencil, 0)))) return;
    atomicMax(stats[0], texelFetch(u_stencil, p, 0).r);
}
