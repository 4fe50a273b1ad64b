#version 460
// MBOIT, second pass (additive blending): each fragment weighted by the transmittance in front of
// it, reconstructed from the pixel's four power moments (techniques.md section 6).
#include "fragment.glsl"

// The moment attachments of the first pass: vec4 (b0..b3) per pixel, then b4 per pixel.
layout(set = 0, binding = 2, std430) readonly buffer Moments { float moment_words[]; };

layout(location = 0) out vec4 accumulated;  // rgb a T, a T

// Transmittance at warped depth zf from b0 and the normalised moments b1..b4 (Muenstermann et al.
// 2018, Algorithm 3), with the bias toward (0, 0.375, 0, 0.375) that float32 storage needs.
float transmittance(float b0, vec4 b, float zf) {
  const float bias = frame.oit_params.x, beta = frame.oit_params.y;
  b = (1.0 - bias) * b + bias * vec4(0.0, 0.375, 0.0, 0.375);
  const float d11 = b.y - b.x * b.x;
  const float l21 = (b.z - b.x * b.y) / d11;
  const float d22 = (b.w - b.y * b.y) - l21 * (b.z - b.x * b.y);
  float c1 = zf - b.x;
  float c2 = zf * zf - b.y - l21 * c1;
  c1 /= d11;
  c2 /= d22;
  c1 -= l21 * c2;
  const float c0 = 1.0 - (b.x * c1 + b.y * c2);
  const float p = c1 / c2, q = c0 / c2;
  const float r = sqrt(max(p * p * 0.25 - q, 0.0));
  const float z1 = -0.5 * p - r, z2 = -0.5 * p + r;
  const float f0 = beta;
  const float f1 = z1 < zf ? 1.0 : 0.0;
  const float f2 = z2 < zf ? 1.0 : 0.0;
  const float f01 = (f1 - f0) / (z1 - zf);
  const float f12 = (f2 - f1) / (z2 - z1);
  const float f012 = (f12 - f01) / (z2 - zf);
  const float q2 = f012;
  const float q1 = f01 - f012 * (z1 + zf);
  const float q0 = f0 - zf * (f01 - f012 * z1);
  return clamp(exp(-b0 * (q0 + q1 * b.x + q2 * b.y)), 0.0, 1.0);
}

void main() {
  const uint pixel = pixel_index();
  const float b0 = moment_words[4u * pixel];
  if (b0 < 0.00100050033) discard;
  const vec4 c = shaded_fragment();
  if (c.a <= 0.0) discard;
  const uint count = frame.size.x * frame.size.y;
  const vec4 b = vec4(moment_words[4u * pixel + 1u], moment_words[4u * pixel + 2u],
                      moment_words[4u * pixel + 3u], moment_words[4u * count + pixel]) / b0;
  const float t = transmittance(b0, b, 2.0 * log_depth() - 1.0);
  accumulated = vec4(c.rgb * c.a * t, c.a * t);
}
