// Per-frame parameters shared by every rasterisation shader (std140; mirrored by FrameUniforms in
// lib/render/vulkan/raster_renderer.cpp), and the shading that must match the CPU ray tracer
// (lib/render/ray_tracer.cpp): transfer function interpolated in sRGB then linearised,
// Blinn-Phong with a headlight, straight (not premultiplied) colour.

const int kMaxTfPoints = 32;

layout(set = 0, binding = 0, std140) uniform FrameUniforms {
  mat4 view_projection;
  vec4 eye;          // xyz
  vec4 shading;      // ambient, diffuse, specular, shininess
  vec4 background;   // linear rgb
  vec4 ranges;       // tube attribute decode lo, hi; transfer-function range lo, hi
  uvec4 size;        // width, height, node capacity, 0
  uvec4 tf_counts;   // colour points, opacity points, early termination, 0
  vec4 termination;  // alpha at which compositing may stop
  vec4 view_dir;     // xyz: unit viewing direction (view-space depth = dot(p - eye, view_dir))
  vec4 depth_params;  // ln z_min, ln z_max of the data in view space; MLABDB tau_alpha, tau_o
  vec4 oit_params;    // MBOIT moment bias, overestimation beta; 0, 0
  uvec4 oit_counts;   // MLAB/MLABDB nodes per pixel k, WBOIT weight function, 0, 0
  vec4 moment_params; // MBOIT trigonometric phase scale, wrapping-zone ramp slope, offset; 0
  vec4 colours[kMaxTfPoints];    // x, sRGB r, g, b
  vec4 opacities[kMaxTfPoints];  // x, opacity
} frame;

float srgb_to_linear(float c) {
  return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

// Point i of the colour (x, r, g, b) or the opacity (x, a) table.
vec4 tf_point(bool colour, uint i) {
  return colour ? frame.colours[i] : frame.opacities[i];
}

// Piecewise linear through the table's points at t, clamped to the end points; returns the
// value columns (colour: rgb, opacity: a in .x).
vec3 tf_interpolate(bool colour, float t) {
  const uint n = colour ? frame.tf_counts.x : frame.tf_counts.y;
  if (t <= tf_point(colour, 0).x) return tf_point(colour, 0).yzw;
  if (t >= tf_point(colour, n - 1).x) return tf_point(colour, n - 1).yzw;
  for (uint i = 1; i < n; ++i) {
    const vec4 hi = tf_point(colour, i);
    if (t < hi.x) {
      const vec4 lo = tf_point(colour, i - 1);
      const float w = hi.x > lo.x ? (t - lo.x) / (hi.x - lo.x) : 0.0;
      return lo.yzw + w * (hi.yzw - lo.yzw);
    }
  }
  return tf_point(colour, n - 1).yzw;
}

vec4 transfer_function(float value) {
  const float span = frame.ranges.w - frame.ranges.z;
  const float t = clamp(span > 0.0 ? (value - frame.ranges.z) / span : 0.5, 0.0, 1.0);
  const vec3 srgb = tf_interpolate(true, t);
  const float a = tf_interpolate(false, t).x;
  return vec4(srgb_to_linear(srgb.r), srgb_to_linear(srgb.g), srgb_to_linear(srgb.b),
              clamp(a, 0.0, 1.0));
}

// Headlight: the light sits at the eye, so the half vector is the view vector.
vec3 shade(vec3 position, vec3 normal, vec3 colour) {
  const vec3 to_eye = normalize(frame.eye.xyz - position);
  vec3 n = normalize(normal);
  if (dot(n, to_eye) < 0.0) n = -n;  // interpolated normals can tip past the silhouette
  const float lambert = max(0.0, dot(n, to_eye));
  return (frame.shading.x + frame.shading.y * lambert) * colour +
         frame.shading.z * pow(lambert, frame.shading.w);
}
