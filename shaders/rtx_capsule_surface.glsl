// A hit on a capsule (reported by shaders/rtx_capsules.rint: front crossings only), for its
// closest-hit and any-hit shaders: shaded with the exact normal and the attribute interpolated
// along the segment, as the CPU tracer does for Embree's capsules. Needs rtx_common.glsl and
// shading.glsl.

vec4 capsule_surface(vec4 hit) {
  Chunk c = chunks[gl_InstanceCustomIndexEXT];
  const uint first = c.indices.v[gl_PrimitiveID] >> 2u;
  float value = 0.0;
  if (c.has_attribute != 0u) {
    const float a0 = c.positions.v[4u * first + 3u], a1 = c.positions.v[4u * first + 7u];
    value = a0 + hit.w * (a1 - a0);
  }
  const vec4 base = transfer_function(value);
  const vec3 x = gl_WorldRayOriginEXT + gl_HitTEXT * gl_WorldRayDirectionEXT;
  return vec4(shade(x, hit.xyz, base.rgb), base.a);
}
