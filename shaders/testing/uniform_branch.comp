#version 450
// The uniform-update probe (glvox/gpu/behaviours.py): which branch a uniform
// selects, written to Out[0].  Two programs of it (VARIANT 0 and 1) take turns,
// each with values that change and values that stay set from its last use: a
// dispatch must see the values its program holds now (uniforms are program
// state, GL 4.5 Sec. 7.6), whatever another program was given in between.
layout(local_size_x = 1) in;
layout(std430, binding = 0) writeonly buffer Out { uint words[]; };
uniform bool u_flag;
uniform uint u_mode;
uniform uint u_value;

void main() {
    // stores inside the branches: a driver that specializes a program on the
    // uniforms its control flow reads (Mesa's inlined uniforms) does so here
    if (u_flag) {
        if (u_mode == 1u) words[0] = u_value;
        else words[0] = ~u_value;
    } else {
        if (u_mode == 1u) words[0] = u_value + 1u + uint(VARIANT);
        else words[0] = u_value ^ 0x5A5A5A5Au;
    }
}
