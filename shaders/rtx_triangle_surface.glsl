// A hit on the triangle tube mesh, for its closest-hit and any-hit shaders: back hits (the
// geometric normal, counter-clockwise from outside, facing away from the eye) are reported as
// such; front hits are shaded with the interpolated normal and attribute, as the CPU reference
// does (EmbreeScene::surface). Needs rtx_common.glsl and shading.glsl.

vec3 position(Chunk c, uint v) {
  return vec3(c.positions.v[3u * v], c.positions.v[3u * v + 1u], c.positions.v[3u * v + 2u]);
}

// tubes/tube_mesh.cpp decode_octahedral
vec3 decode_octahedral(uint packed) {
  const float u = max(float(int(packed << 16) >> 16) / 32767.0, -1.0);
  const float v = max(float(int(packed) >> 16) / 32767.0, -1.0);
  vec3 n = vec3(u, v, 1.0 - abs(u) - abs(v));
  if (n.z < 0.0) {
    n.x = (1.0 - abs(v)) * (u >= 0.0 ? 1.0 : -1.0);
    n.y = (1.0 - abs(u)) * (v >= 0.0 ? 1.0 : -1.0);
  }
  return normalize(n);
}

vec3 vertex_normal(Chunk c, uint v) {
  if (c.normal_encoding == 1u) return decode_octahedral(c.normals_oct.v[v]);
  return vec3(c.normals.v[3u * v], c.normals.v[3u * v + 1u], c.normals.v[3u * v + 2u]);
}

float vertex_attribute(Chunk c, uint v) {
  const uint word = c.attributes.v[v >> 1u];
  const uint unorm = (v & 1u) != 0u ? word >> 16u : word & 0xFFFFu;
  return frame.ranges.x + (frame.ranges.y - frame.ranges.x) * (float(unorm) / 65535.0);
}

// The current hit: false for a back hit, else true with its shaded colour and opacity.
bool triangle_surface(vec2 barycentrics, out vec4 colour) {
  colour = vec4(0.0);
  Chunk c = chunks[gl_InstanceCustomIndexEXT];
  const uint i0 = c.indices.v[3u * uint(gl_PrimitiveID)];
  const uint i1 = c.indices.v[3u * uint(gl_PrimitiveID) + 1u];
  const uint i2 = c.indices.v[3u * uint(gl_PrimitiveID) + 2u];
  const vec3 p0 = position(c, i0), p1 = position(c, i1), p2 = position(c, i2);
  if (dot(cross(p1 - p0, p2 - p0), gl_WorldRayDirectionEXT) > 0.0) return false;
  const vec3 w = vec3(1.0 - barycentrics.x - barycentrics.y, barycentrics.x, barycentrics.y);
  vec3 n = w.x * vertex_normal(c, i0) + w.y * vertex_normal(c, i1) + w.z * vertex_normal(c, i2);
  if (dot(n, n) == 0.0) n = cross(p1 - p0, p2 - p0);
  float value = 0.0;
  if (c.has_attribute != 0u)
    value = w.x * vertex_attribute(c, i0) + w.y * vertex_attribute(c, i1) +
            w.z * vertex_attribute(c, i2);
  const vec4 base = transfer_function(value);
  const vec3 x = gl_WorldRayOriginEXT + gl_HitTEXT * gl_WorldRayDirectionEXT;
  colour = vec4(shade(x, n, base.rgb), base.a);
  return true;
}
