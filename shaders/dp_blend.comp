#version 460
// Depth peeling: blends the layer just peeled under the pixels composited so far (front to back)
// and records its depth for the next layer. kFinish instead adds the background.
#include "frame.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(constant_id = 0) const uint kFinish = 0;

layout(set = 0, binding = 1, std430) buffer Peeled { float peeled[]; };
// The layer's colour attachment (vec4 per pixel) followed by its depth attachment.
layout(set = 0, binding = 2, std430) readonly buffer Layer { float layer[]; };
layout(set = 0, binding = 4, std430) buffer Output { vec4 pixels[]; };

void main() {
  const uvec2 p = gl_GlobalInvocationID.xy;
  if (p.x >= frame.size.x || p.y >= frame.size.y) return;
  const uint pixel = p.y * frame.size.x + p.x;
  vec4 acc = pixels[pixel];  // premultiplied rgb, A
  if (kFinish != 0u) {
    pixels[pixel] = vec4(acc.rgb + (1.0 - acc.a) * frame.background.rgb, acc.a);
    return;
  }
  const uint count = frame.size.x * frame.size.y;
  const float depth = layer[4u * count + pixel];
  if (depth > 1.0) return;  // nothing left in this pixel
  const vec4 c = vec4(layer[4u * pixel], layer[4u * pixel + 1u], layer[4u * pixel + 2u],
                      layer[4u * pixel + 3u]);
  acc.rgb += (1.0 - acc.a) * c.a * c.rgb;
  acc.a += (1.0 - acc.a) * c.a;
  pixels[pixel] = acc;
  peeled[pixel] = depth;
}
