#version 460
// MBOIT, second pass (additive blending): each fragment weighted by the transmittance in front of
// it, reconstructed from the pixel's moments (techniques.md section 6, moments.glsl).
#include "fragment.glsl"
#include "moments.glsl"

// Copies of the first pass's moment targets (layout in moments.glsl).
layout(set = 0, binding = 2, std430) readonly buffer Moments { float moment_words[]; };

layout(location = 0) out vec4 accumulated;  // rgb a T, a T

void main() {
  const uint pixel = pixel_index();
  const uint pixels = frame.size.x * frame.size.y;
  const float b0 = moment_words[moment_word(0u, pixel, pixels)];
  if (b0 < 0.00100050033) discard;
  const vec4 c = shaded_fragment();
  if (c.a <= 0.0) discard;
  float v[9];
  for (uint j = 0u; j < 9u; ++j)
    v[j] = j <= kMoments ? moment_words[moment_word(j, pixel, pixels)] : 0.0;
  const float t = moment_transmittance(v, 2.0 * log_depth() - 1.0);
  accumulated = vec4(c.rgb * c.a * t, c.a * t);
}
