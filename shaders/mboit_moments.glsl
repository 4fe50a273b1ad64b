// MBOIT, first pass (additive blending): the absorbance q = -ln(1 - a) (at most 10) and its
// moments over the warped log depth z in [-1, 1] (techniques.md section 6; moments.glsl says
// which targets hold which moments). mboit_moments.frag writes two targets (4 moments),
// mboit_moments_wide.frag three (6 or 8).
#include "fragment.glsl"
#include "moments.glsl"

layout(location = 0) out vec4 moments_0123;  // b0, b1, b2, b3
layout(location = 1) out float moment_last;  // b_n
#ifdef WIDE_MOMENTS
layout(location = 2) out vec4 moments_4567;  // b4 .. b_{n-1}
#endif

void main() {
  const float a = transfer_function(value).a;
  if (1.0 - a > 0.9999999) discard;
  float v[9];
  fragment_moments(min(-log(1.0 - a), 10.0), 2.0 * log_depth() - 1.0, v);
  moments_0123 = vec4(v[0], v[1], v[2], v[3]);
  moment_last = v[kMoments];
#ifdef WIDE_MOMENTS
  moments_4567 = vec4(v[4], v[5], kMoments > 6u ? v[6] : 0.0, kMoments > 6u ? v[7] : 0.0);
#endif
}
