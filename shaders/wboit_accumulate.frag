#version 460
// WBOIT (McGuire & Bavoil 2013), one additive pass: weighted premultiplied colour and opacity,
// and the absorbance -ln(1 - a) whose sum gives the revealage prod(1 - a) = exp(-sum) (additive
// instead of a multiplicative blend, so both targets share one blend state).
#include "fragment.glsl"

layout(location = 0) out vec4 accumulated;  // rgb a w, a w
layout(location = 1) out float absorbance;

// The weight functions: 0 the public code's (a + 0.01)^3 1e8 (1 - 0.95 z)^3 over NDC depth, 7-9
// the WBOIT paper's equations over view depth |z| (in the data's units).
float weight(float a) {
  const uint kind = frame.oit_counts.y;
  const float z = dot(world_position - frame.eye.xyz, frame.view_dir.xyz);
  if (kind == 7u)
    return a * clamp(10.0 / (1e-5 + pow(z / 5.0, 2.0) + pow(z / 200.0, 6.0)), 1e-2, 3e3);
  if (kind == 8u)
    return a * clamp(10.0 / (1e-5 + pow(z / 10.0, 3.0) + pow(z / 200.0, 6.0)), 1e-2, 3e3);
  if (kind == 9u) return a * clamp(0.03 / (1e-5 + pow(z / 200.0, 4.0)), 1e-2, 3e3);
  const float a3 = pow(8.0 * min(1.0, a) + 0.01, 3.0);
  const float b3 = pow(1.0 - 0.95 * gl_FragCoord.z, 3.0);
  return clamp(a3 * 1e8 * b3, 1e-2, 3e2);
}

void main() {
  const vec4 c = shaded_fragment();
  if (c.a <= 0.0) discard;
  const float w = weight(c.a);
  accumulated = vec4(c.rgb * c.a, c.a) * w;
  absorbance = -log(max(1.0 - c.a, 1e-30));
}
