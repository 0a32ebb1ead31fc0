#version 450
// Self-test of glvox.gpu.dispatch.bind: buffers bound by block name.  The bindings are
// neither 0, 1, 2 nor in declaration order, so binding by position or by a swapped
// number writes into the wrong buffer.  A block only named in a comment, like
// `buffer Ghost { uint ghost[]; };`, is not declared.
layout(local_size_x = 64) in;
layout(std430, binding = 5) writeonly buffer Target { uint target[]; };
layout(std430, binding = 3) writeonly buffer Decoy { uint decoy[]; };
/* nor is one in a block comment: buffer Phantom { uint phantom[]; }; */
// Declared and never used: bind() skips it where the compiler dropped it.  The GLSL spec
// keeps every block of shared, std140 or std430 layout active; a packed one may go.
layout(packed, binding = 6) buffer Unused { uint unused[]; };
uniform uint u_count;
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    target[i] = 1000u + i;
    decoy[i] = 2000u + i;
}
