#version 460
// Closest hit on the triangle tube mesh (`--hits stepping`): the one nearest hit, front or back.

#include "rtx_common.glsl"
#include "shading.glsl"
#include "rtx_triangle_surface.glsl"

layout(location = 0) rayPayloadInEXT Payload payload;
hitAttributeEXT vec2 barycentrics;

void main() {
  vec4 colour;
  const bool front = triangle_surface(barycentrics, colour);
  payload.count = 1u;
  payload.t[0] = gl_HitTEXT;
  payload.chunk[0] = uint(gl_InstanceCustomIndexEXT) | (front ? 0u : kBackHit);
  payload.primitive[0] = uint(gl_PrimitiveID);
  payload.colour[0] = colour;
}
