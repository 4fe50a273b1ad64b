#version 460
// MLAB and MLABDB resolve: the k sorted nodes blended front to back over the background.
#include "frame.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(constant_id = 0) const uint kLayers = 8;

#include "pages.glsl"

float node_word(uint w) {
  return uintBitsToFloat(word_load(w));
}
layout(set = 0, binding = 4, std430) writeonly buffer Output { vec4 pixels[]; };

void main() {
  const uvec2 p = gl_GlobalInvocationID.xy;
  if (p.x >= frame.size.x || p.y >= frame.size.y) return;
  const uint pixel = p.y * frame.size.x + p.x;
  const uint n = frame.size.x * frame.size.y * kLayers;
  vec3 colour = vec3(0.0);
  float transmittance = 1.0;
  for (uint i = 0u; i < kLayers; ++i) {
    const uint at = pixel * kLayers + i;
    if (isinf(node_word(at))) continue;  // empty (MLABDB's front bucket may be)
    colour += transmittance * vec3(node_word(n + 3u * at), node_word(n + 3u * at + 1u),
                                   node_word(n + 3u * at + 2u));
    transmittance *= node_word(4u * n + at);
  }
  pixels[pixel] = vec4(colour + transmittance * frame.background.rgb, 1.0 - transmittance);
}
