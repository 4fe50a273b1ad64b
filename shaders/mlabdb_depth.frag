#version 460
// MLABDB, first pass: per pixel the nearest log depth of a fragment with opacity above tau_alpha
// (where the back bucket starts) and of one at least tau_o (behind which nothing is seen).
// Non-negative floats order like their bits, so atomicMin on the bits finds the minimum.
#include "fragment.glsl"

layout(set = 0, binding = 1, std430) buffer PixelState { uint pixel_state[]; };

void main() {
  const float a = transfer_function(value).a;
  if (a <= frame.depth_params.z) return;
  const uint count = frame.size.x * frame.size.y;
  const uint pixel = pixel_index();
  const uint d = floatBitsToUint(log_depth());
  atomicMin(pixel_state[count + pixel], d);
  if (a >= frame.depth_params.w) atomicMin(pixel_state[2u * count + pixel], d);
}
