#version 450
// Zeroes the EIS_TARGETS integer render targets before a pass (glClear is
// undefined on integer color buffers, and moderngl has no glClearBuffer).
#define EIS_MASKS 0
#include "eisemann/masks.glsl"
void main() { eis_write_zeros(); }
