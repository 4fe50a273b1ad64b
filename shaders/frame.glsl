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
  vec4 colours[kMaxTfPoints];    // x, sRGB r, g, b
  vec4 opacities[kMaxTfPoints];  // x, opacity
} frame;

float srgb_to_linear(float c) {
  return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

vec4 transfer_function(float value) {
  const float span = frame.ranges.w - frame.ranges.z;
  float t = span > 0.0 ? (value - frame.ranges.z) / span : 0.5;
  t = clamp(t, 0.0, 1.0);
  vec3 srgb = frame.colours[0].yzw;
  const uint nc = frame.tf_counts.x;
  if (t >= frame.colours[nc - 1].x) {
    srgb = frame.colours[nc - 1].yzw;
  } else if (t > frame.colours[0].x) {
    for (uint i = 1; i < nc; ++i)
      if (t < frame.colours[i].x) {
        const vec4 lo = frame.colours[i - 1], hi = frame.colours[i];
        const float w = hi.x > lo.x ? (t - lo.x) / (hi.x - lo.x) : 0.0;
        srgb = lo.yzw + w * (hi.yzw - lo.yzw);
        break;
      }
  }
  float a = frame.opacities[0].y;
  const uint no = frame.tf_counts.y;
  if (t >= frame.opacities[no - 1].x) {
    a = frame.opacities[no - 1].y;
  } else if (t > frame.opacities[0].x) {
    for (uint i = 1; i < no; ++i)
      if (t < frame.opacities[i].x) {
        const vec4 lo = frame.opacities[i - 1], hi = frame.opacities[i];
        const float w = hi.x > lo.x ? (t - lo.x) / (hi.x - lo.x) : 0.0;
        a = lo.y + w * (hi.y - lo.y);
        break;
      }
  }
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
