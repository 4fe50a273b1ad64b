#version 460
// MBOIT, first pass (additive blending): the absorbance q = -ln(1 - a) (at most 10) and its power
// moments q z^k, k = 1..4, over the warped log depth z in [-1, 1] (techniques.md section 6).
#include "fragment.glsl"

layout(location = 0) out vec4 moments_0123;  // b0, b1, b2, b3
layout(location = 1) out float moment_4;     // b4

void main() {
  const float a = transfer_function(value).a;
  if (1.0 - a > 0.9999999) discard;
  const float q = min(-log(1.0 - a), 10.0);
  const float z = 2.0 * log_depth() - 1.0;
  const float z2 = z * z;
  moments_0123 = vec4(q, q * z, q * z2, q * z2 * z);
  moment_4 = q * z2 * z2;
}
