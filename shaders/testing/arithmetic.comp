#version 450
// What this compiler does to the arithmetic that glvox's exact shaders rest on
// (glvox.gl.arithmetic, run by `glvox selftest`).  For each probe i the host
// gives (a, b, c, d) with c = -fl(a * b) and d = 1, so that
//   a * b + c    is 0 when computed with two roundings (what `precise` demands:
//                GLSL 4.50 Sec. 4.9 forbids fusing it into one fma), and the
//                rounding error of a * b when fused;
//   a * b - c*d  the same, in the form of a cross product's component
//                (ss/setup.glsl): -fl(a * b) * 1 is exact;
//   fma(a, b, c) the positive control: one rounding where the hardware has an
//                fma, so the probe can tell fused from unfused at all;
// and the same in double.  Without `precise`, Sec. 4.7.1 lets a compiler fuse
// (reported, not a failure).  Also: a / b (GLSL allows 2.5 ulp), and whether
// float32 denormals survive a product (u_tiny * u_tiny).
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Floats { vec4 fin[]; };
layout(std430, binding = 1) readonly buffer Doubles { dvec4 din[]; };
layout(std430, binding = 2) writeonly buffer FloatOut { vec4 fout[]; };   // precise, plain, fma, cross
layout(std430, binding = 3) writeonly buffer DoubleOut { dvec4 dout[]; };
layout(std430, binding = 4) writeonly buffer Extra { vec2 extra[]; };    // a / b, u_tiny * u_tiny
uniform uint u_count;
uniform float u_tiny;

// exact: the helper convention of common/edge.glsl (a precise local, returned)
float helper_cross(float a, float b, float c, float d) {
    precise float r = a * b - c * d;
    return r;
}

// exact: as above, in double
double helper_cross_d(double a, double b, double c, double d) {
    precise double r = a * b - c * d;
    return r;
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    vec4 f = fin[i];
    precise float kept = f.x * f.y + f.z;
    float plain = f.x * f.y + f.z;
    precise float fused = fma(f.x, f.y, f.z);
    fout[i] = vec4(kept, plain, fused, helper_cross(f.x, f.y, -f.z, f.w));
    dvec4 g = din[i];
    precise double dkept = g.x * g.y + g.z;
    double dplain = g.x * g.y + g.z;
    precise double dfused = fma(g.x, g.y, g.z);
    dout[i] = dvec4(dkept, dplain, dfused, helper_cross_d(g.x, g.y, -g.z, g.w));
    precise float tiny = u_tiny * u_tiny;
    extra[i] = vec2(f.x / f.y, tiny);
}
