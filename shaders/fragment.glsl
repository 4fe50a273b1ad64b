// What every tube fragment shader starts from: the interpolated vertex outputs, the shaded
// straight colour and opacity, the pixel index into per-pixel buffers, and the normalised
// logarithmic view depth that MLABDB's buckets and MBOIT's moments are taken over
// (techniques.md sections 5 and 6).
#include "frame.glsl"

layout(location = 0) in vec3 world_position;
layout(location = 1) in vec3 world_normal;
layout(location = 2) in float value;

// Straight rgb (shaded) and opacity from the transfer function.
vec4 shaded_fragment() {
  const vec4 c = transfer_function(value);
  return vec4(shade(world_position, world_normal, c.rgb), c.a);
}

uint pixel_index() {
  return uint(gl_FragCoord.y) * frame.size.x + uint(gl_FragCoord.x);
}

// (ln z_view - ln z_min) / (ln z_max - ln z_min), clamped to [0, 1].
float log_depth() {
  const float z = max(dot(world_position - frame.eye.xyz, frame.view_dir.xyz), 1e-20);
  const float span = frame.depth_params.y - frame.depth_params.x;
  return clamp((log(z) - frame.depth_params.x) / span, 0.0, 1.0);
}
