#version 450
// Writes u_value to all 8 RGBA32UI targets (harness and logic-op self-test).
layout(location = 0) out uvec4 o0;
layout(location = 1) out uvec4 o1;
layout(location = 2) out uvec4 o2;
layout(location = 3) out uvec4 o3;
layout(location = 4) out uvec4 o4;
layout(location = 5) out uvec4 o5;
layout(location = 6) out uvec4 o6;
layout(location = 7) out uvec4 o7;
uniform uvec4 u_value;
void main() {
    uvec4 v = u_value ^ uvec4(uint(gl_FragCoord.x), uint(gl_FragCoord.y), 0u, 0u);
    o0 = v; o1 = v + 1u; o2 = v + 2u; o3 = v + 3u; o4 = v + 4u; o5 = v + 5u; o6 = v + 6u; o7 = v + 7u;
}
