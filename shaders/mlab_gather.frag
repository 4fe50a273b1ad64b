#version 460
// MLAB (`mlab`) and MLABDB's second pass (`mlabdb`, kBuckets = 1): insert the fragment into its
// pixel's nodes under a per-pixel spin lock (devices without fragment shader interlock).
#include "mlab_insert.glsl"

void main() {
  const vec4 c = shaded_fragment();
  if (c.a <= 0.0) return;
  const uint pixel = pixel_index();
  // The critical section sits inside the loop, so lanes of one subgroup that wait on each other
  // cannot deadlock: the lane holding the lock finishes in the same iteration.
  bool done = false;
  while (!done) {
    if (atomicCompSwap(pixel_state[pixel], 0u, 1u) == 0u) {
      mlab_fragment(pixel, c);
      memoryBarrierBuffer();
      atomicExchange(pixel_state[pixel], 0u);
      done = true;
    }
  }
}
