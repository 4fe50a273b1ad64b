// Per-frame parameters shared by every rasterisation shader (std140; mirrored by FrameUniforms in
// lib/render/vulkan/raster_state.hpp), and the shading (shading.glsl).

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

#include "shading.glsl"
