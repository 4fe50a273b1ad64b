#version 460
// Closest hit on a capsule (`--hits stepping`): the one nearest front crossing.

#include "rtx_common.glsl"
#include "shading.glsl"
#include "rtx_capsule_surface.glsl"

layout(location = 0) rayPayloadInEXT Payload payload;
hitAttributeEXT vec4 hit;  // outward normal xyz, position along the segment

void main() {
  payload.count = 1u;
  payload.t[0] = gl_HitTEXT;
  payload.chunk[0] = uint(gl_InstanceCustomIndexEXT);
  payload.primitive[0] = uint(gl_PrimitiveID);
  payload.colour[0] = capsule_surface(hit);
}
