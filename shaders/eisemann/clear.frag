#version 450
// Zeroes the EIS_TARGETS integer render targets before a pass (glClear is
// undefined on integer color buffers, and moderngl has no glClearBuffer).
layout(location = 0) out uvec4 o_masks[EIS_TARGETS];
void main() {
    for (int t = 0; t < EIS_TARGETS; ++t) o_masks[t] = uvec4(0u);
}
