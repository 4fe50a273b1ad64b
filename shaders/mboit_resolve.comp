#version 460
// MBOIT resolve: the total opacity is exact, 1 - exp(-b0); the colour is the transmittance-
// weighted mean of the fragments' colours, blended over the background.
#include "frame.glsl"
#include "moments.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// The moment targets' copies (b0 first), then the second pass's accumulation (vec4 per pixel).
layout(set = 0, binding = 2, std430) readonly buffer Targets { float words[]; };
layout(set = 0, binding = 4, std430) writeonly buffer Output { vec4 pixels[]; };

void main() {
  const uvec2 p = gl_GlobalInvocationID.xy;
  if (p.x >= frame.size.x || p.y >= frame.size.y) return;
  const uint pixel = p.y * frame.size.x + p.x;
  const uint count = frame.size.x * frame.size.y;
  const float b0 = words[4u * pixel];
  const uint at = moment_floats(count) + 4u * pixel;
  const vec4 acc = vec4(words[at], words[at + 1u], words[at + 2u], words[at + 3u]);
  const float alpha = 1.0 - exp(-b0);
  const vec3 colour = acc.a > 0.0 ? acc.rgb / acc.a : vec3(0.0);
  pixels[pixel] = vec4(alpha * colour + (1.0 - alpha) * frame.background.rgb, alpha);
}
