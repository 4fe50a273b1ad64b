#version 460
// tiles, pass 3 over the tube mesh's triangles (tiles_composite.glsl): each pixel's ray against
// each front-facing triangle (Moller and Trumbore 1997), the normal and attribute interpolated
// as the CPU ray tracer interpolates them (lib/accel/embree_scene.cpp, surface()).
#include "tiles.glsl"
#include "tiles_triangles.glsl"
#include "shading.glsl"

// Fewer slots than capsules: the shared memory of the batch and the rounds stays within the
// 32 KiB of lavapipe.
const uint kBatch = 256, kSlots = 128;
// a: xyz, the key's depth bound; b: xyz, the farthest view depth; c: xyz, c's attribute.
shared vec4 batch_a[kBatch], batch_b[kBatch], batch_c[kBatch];
#ifndef TILES_LATE_SHADING
// The vertices' normals, x, y, z of a, b, c, then a's and b's attribute (floats: vec3 arrays take
// 16 bytes an element). Late shading reads them again.
shared float batch_normals[11][kBatch];
#endif

// Triangle s's corners (xyz, the attribute value in w) and their normals, read from the tube
// mesh.
void stored_triangle(uint s, out vec4 corner[3], out vec3 normal[3]) {
  for (int k = 0; k < 3; ++k) {
    const uint v = index_at(3u * s + uint(k));
    corner[k] = vertex_at(v);
    normal[k] = normal_at(v).xyz;
  }
}

void load_primitive(uint lane, uint s, float bound, float far) {
  vec4 corner[3];
  vec3 normal[3];
  stored_triangle(s, corner, normal);
  batch_a[lane] = vec4(corner[0].xyz, bound);
  batch_b[lane] = vec4(corner[1].xyz, far);
  batch_c[lane] = corner[2];
#ifndef TILES_LATE_SHADING
  batch_normals[9][lane] = corner[0].w;
  batch_normals[10][lane] = corner[1].w;
  for (int k = 0; k < 3; ++k) {
    batch_normals[k][lane] = normal[0][k];
    batch_normals[3 + k][lane] = normal[1][k];
    batch_normals[6 + k][lane] = normal[2][k];
  }
#endif
}

#ifndef TILES_LATE_SHADING
vec3 batch_normal(int vertex, uint i) {
  return vec3(batch_normals[3 * vertex][i], batch_normals[3 * vertex + 1][i],
              batch_normals[3 * vertex + 2][i]);
}
#endif

// The ray's front-face hit with the triangle a, b, c: t and the barycentric weights u, v of b
// and c.
bool triangle_hit(vec3 a, vec3 b, vec3 c, vec3 direction, out float t, out float u, out float v) {
  t = 0.0, u = 0.0, v = 0.0;
  const vec3 e1 = b - a, e2 = c - a;
  const vec3 p = cross(direction, e2);
  const float det = dot(e1, p);
  // det = -dot(direction, n) for the outward normal n = e1 x e2 (counter-clockwise from outside):
  // positive for a front face.
  if (det <= 0.0) return false;
  const vec3 s = view.eye - a;
  u = dot(s, p) / det;
  if (u < 0.0 || u > 1.0) return false;
  const vec3 q = cross(s, e1);
  v = dot(direction, q) / det;
  if (v < 0.0 || u + v > 1.0) return false;
  t = dot(e2, q) / det;
  return t > 0.0;
}

// What may_cross reads of batch entry i, and the depth bound.
const int kNearWords = 3;
void near_words(uint i, out vec4 words[kNearWords]) {
  words[0] = batch_a[i];
  words[1] = batch_b[i];
  words[2] = batch_c[i];
}
float depth_bound(uint i) { return batch_a[i].w; }

// The exact test is as cheap as any before it: pairs are the hits, and only those are shaded.
bool may_cross(vec4 words[kNearWords], vec3 direction) {
  float t, u, v;
  return triangle_hit(words[0].xyz, words[1].xyz, words[2].xyz, direction, t, u, v);
}

// The colour of the hit at t with barycentric weights u, v of corners b and c: the attribute and
// the normal interpolated as the CPU ray tracer interpolates them.
vec4 triangle_colour(vec3 direction, float t, float u, float v, vec3 values, vec3 normal[3]) {
  const float w = 1.0 - u - v;
  const float value = w * values.x + u * values.y + v * values.z;
  const vec3 n = w * normal[0] + u * normal[1] + v * normal[2];
  const vec4 base = transfer_function(value);
  return vec4(shade(view.eye + t * direction, n, base.rgb), base.a);
}

// Batch entry i's hit, shaded unless the window shades late.
bool first_hit(uint i, vec3 direction, out float t, out vec4 colour) {
  float u, v;
  colour = vec4(0.0);
  if (!triangle_hit(batch_a[i].xyz, batch_b[i].xyz, batch_c[i].xyz, direction, t, u, v))
    return false;
#ifndef TILES_LATE_SHADING
  const vec3 normal[3] = vec3[3](batch_normal(0, i), batch_normal(1, i), batch_normal(2, i));
  const vec3 values = vec3(batch_normals[9][i], batch_normals[10][i], batch_c[i].w);
  colour = triangle_colour(direction, t, u, v, values, normal);
#endif
  return true;
}

// The colour of a pending hit at t on triangle s, composited late: the same test on the same
// floats, read again from the tube mesh, gives the same hit (TILES_LATE_SHADING,
// tiles_composite.glsl). Should a compiler compute the test otherwise here (no test is marked
// precise), false and the colour of corner a: counted, not lost.
bool hit_colour(uint s, float t, vec3 direction, out vec4 colour) {
  vec4 corner[3];
  vec3 normal[3];
  stored_triangle(s, corner, normal);
  const vec3 values = vec3(corner[0].w, corner[1].w, corner[2].w);
  float t_hit, u, v;
  const bool found =
      triangle_hit(corner[0].xyz, corner[1].xyz, corner[2].xyz, direction, t_hit, u, v);
  if (!found) t_hit = t, u = 0.0, v = 0.0;
  colour = triangle_colour(direction, t_hit, u, v, values, normal);
  return found;
}

// A ray meets a shared edge of two triangles with probability zero: no seams.
float seam_of(uint i, vec3 direction) { return 0.0; }

#include "tiles_composite.glsl"
