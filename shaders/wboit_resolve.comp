#version 460
// WBOIT resolve: the weighted average colour, covering 1 - revealage of the background.
#include "frame.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// The accumulation (vec4 per pixel), then the summed absorbance (per pixel).
layout(set = 0, binding = 2, std430) readonly buffer Targets { float words[]; };
layout(set = 0, binding = 4, std430) writeonly buffer Output { vec4 pixels[]; };

void main() {
  const uvec2 p = gl_GlobalInvocationID.xy;
  if (p.x >= frame.size.x || p.y >= frame.size.y) return;
  const uint pixel = p.y * frame.size.x + p.x;
  const uint count = frame.size.x * frame.size.y;
  const vec4 acc = vec4(words[4u * pixel], words[4u * pixel + 1u], words[4u * pixel + 2u],
                        words[4u * pixel + 3u]);
  const float alpha = 1.0 - exp(-words[4u * count + pixel]);
  const vec3 colour = acc.rgb / max(acc.a, 1e-5);
  pixels[pixel] = vec4(alpha * colour + (1.0 - alpha) * frame.background.rgb, alpha);
}
