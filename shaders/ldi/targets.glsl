// The LDI_TARGETS render targets of a pass as images, for the compute passes that read
// them back into buffers (units 0 .. LDI_TARGETS - 1, format LDI_TARGET_FORMAT with
// LDI_TARGET_TYPE).  GLSL cannot index an array of image uniforms dynamically, hence
// the switch.
layout(LDI_TARGET_FORMAT, binding = 0) readonly uniform LDI_TARGET_TYPE u_target0;
#if LDI_TARGETS > 1
layout(LDI_TARGET_FORMAT, binding = 1) readonly uniform LDI_TARGET_TYPE u_target1;
#endif
#if LDI_TARGETS > 2
layout(LDI_TARGET_FORMAT, binding = 2) readonly uniform LDI_TARGET_TYPE u_target2;
#endif
#if LDI_TARGETS > 3
layout(LDI_TARGET_FORMAT, binding = 3) readonly uniform LDI_TARGET_TYPE u_target3;
#endif
#if LDI_TARGETS > 4
layout(LDI_TARGET_FORMAT, binding = 4) readonly uniform LDI_TARGET_TYPE u_target4;
#endif
#if LDI_TARGETS > 5
layout(LDI_TARGET_FORMAT, binding = 5) readonly uniform LDI_TARGET_TYPE u_target5;
#endif
#if LDI_TARGETS > 6
layout(LDI_TARGET_FORMAT, binding = 6) readonly uniform LDI_TARGET_TYPE u_target6;
#endif
#if LDI_TARGETS > 7
layout(LDI_TARGET_FORMAT, binding = 7) readonly uniform LDI_TARGET_TYPE u_target7;
#endif

LDI_TEXEL_TYPE ldi_target(int t, ivec2 p) {
    switch (t) {
#if LDI_TARGETS > 1
        case 1: return imageLoad(u_target1, p);
#endif
#if LDI_TARGETS > 2
        case 2: return imageLoad(u_target2, p);
#endif
#if LDI_TARGETS > 3
        case 3: return imageLoad(u_target3, p);
#endif
#if LDI_TARGETS > 4
        case 4: return imageLoad(u_target4, p);
#endif
#if LDI_TARGETS > 5
        case 5: return imageLoad(u_target5, p);
#endif
#if LDI_TARGETS > 6
        case 6: return imageLoad(u_target6, p);
#endif
#if LDI_TARGETS > 7
        case 7: return imageLoad(u_target7, p);
#endif
        default: return imageLoad(u_target0, p);
    }
}
