#version 460
// Closest hit on a capsule: shaded with the exact normal and the attribute interpolated along
// the segment, as the CPU tracer does for Embree's capsules.

#include "rtx_common.glsl"
#include "shading.glsl"

layout(location = 0) rayPayloadInEXT Payload payload;
hitAttributeEXT vec4 hit;

void main() {
  Chunk c = chunks[gl_InstanceCustomIndexEXT];
  const uint first = c.indices.v[gl_PrimitiveID] >> 2u;
  float value = 0.0;
  if (c.has_attribute != 0u) {
    const float a0 = c.positions.v[4u * first + 3u], a1 = c.positions.v[4u * first + 7u];
    value = a0 + hit.w * (a1 - a0);
  }
  const vec4 base = transfer_function(value);
  const vec3 x = gl_WorldRayOriginEXT + gl_HitTEXT * gl_WorldRayDirectionEXT;
  payload.t = gl_HitTEXT;
  payload.colour = vec4(shade(x, hit.xyz, base.rgb), base.a);
  payload.kind = kFrontHit;
}
