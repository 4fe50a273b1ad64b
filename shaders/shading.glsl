// The shading that must match the CPU ray tracer (lib/render/ray_tracer.cpp): transfer function
// interpolated in sRGB then linearised, Blinn-Phong with a headlight, straight (not
// premultiplied) colour. Reads from the including shader's uniform block `frame`: colours,
// opacities, tf_counts.xy, ranges.zw (transfer-function range), shading, eye. An including shader
// may define TF_COUNTS to read the point counts (the loop bounds) from elsewhere (tiles.glsl).

#ifndef TF_COUNTS
#define TF_COUNTS frame.tf_counts
#endif

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
  const uint n = colour ? TF_COUNTS.x : TF_COUNTS.y;
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

// Headlight: the light sits at the eye, so the half vector is the view vector `to_eye` (unit).
vec3 shade_towards(vec3 to_eye, vec3 normal, vec3 colour) {
  vec3 n = normalize(normal);
  if (dot(n, to_eye) < 0.0) n = -n;  // interpolated normals can tip past the silhouette
  const float lambert = max(0.0, dot(n, to_eye));
  return (frame.shading.x + frame.shading.y * lambert) * colour +
         frame.shading.z * pow(lambert, frame.shading.w);
}

vec3 shade(vec3 position, vec3 normal, vec3 colour) {
  return shade_towards(normalize(frame.eye.xyz - position), normal, colour);
}
