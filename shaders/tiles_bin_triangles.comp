#version 460
// tiles, pass 1 over the tube mesh's triangles: each triangle's screen bounds binned
// (tiles_keys.glsl) with its nearest vertex depth. Back faces are culled here already, and a
// triangle whose bounds hold a few pixel centres only where one of them lies inside it.
#include "tiles.glsl"
#include "tiles_triangles.glsl"
// Before tiles_keys.glsl, which reads gl_WorkGroupSize.
layout(local_size_x = 256) in;
#include "tiles_keys.glsl"

// Whether a pixel centre of the triangle's bounds [lo, hi] lies inside it on the screen, grown by
// a sixteenth of a pixel as its bounds are (screen_bounds), for the float error of the projection
// and of the composite's ray-triangle test; true for bounds of more pixels than binning.x,
// untested. A pixel's ray meets a triangle in front of the eye where its centre lies inside the
// triangle's projection, so a triangle none of whose pixel centres lies there has no hit: tube
// meshes are mostly such triangles, smaller than a pixel.
bool covers_a_tested_pixel(uint s, vec2 lo, vec2 hi) {
  ivec2 p0, extent;
  const int pixels = tested_pixels(lo, hi, p0, extent);
  if (pixels < 0) return true;
  vec3 a, b, c;
  triangle_corners(s, a, b, c);
  const vec2 corner[3] = vec2[3](project(a).xy, project(b).xy, project(c).xy);
  const vec2 ab = corner[1] - corner[0], ac = corner[2] - corner[0];
  const float area = ab.x * ac.y - ab.y * ac.x;  // twice the signed area
  // Degenerate on the screen, or not finite: kept (the composite decides).
  if (!(abs(area) > 0.0) || isinf(area)) return true;
  const float orientation = sign(area);
  bool covered = false;
  for (int k = 0; k < kTestedPixels; ++k) {
    if (k >= pixels) break;
    const vec2 centre = vec2(tested_pixel(p0, extent, k)) + 0.5;
    bool inside = true;
    for (int e = 0; e < 3; ++e) {
      const vec2 from = corner[e], edge = corner[(e + 1) % 3] - from, to = centre - from;
      // The centre's signed distance from the edge's line, positive inwards.
      const float distance = orientation * (edge.x * to.y - edge.y * to.x) / length(edge);
      inside = inside && distance >= -0.0625;
    }
    covered = covered || inside;
  }
  return covered;
}

void main() {
  load_frame_view();
  const uint s = flat_workgroup() * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
  vec2 lo = vec2(0.0), hi = vec2(-1.0);
  float z_near = 0.0, z_far = 0.0;
  // Every invocation takes part in emit_keys (it counts per workgroup).
  bool visible = s < view.size.w && screen_bounds(s, lo, hi, z_near, z_far);
  if (visible) visible = covers_a_tested_pixel(s, lo, hi);
  emit_keys(s, visible, lo, hi, z_near);
}
